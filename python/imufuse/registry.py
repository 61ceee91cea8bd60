"""The filter matrix: every filter configuration the suites run.

Every filter of imufuse.catalogue is in it: a filter without an extra case
below runs with its catalogue defaults (dt = 0.01, or 0.002 for fixed point).
The lists here hold only the extra configurations worth testing (every option
of every class, published defaults, edge gains).

The test suite, the benchmarks, the MCU measurement (bench/mcu) and the generated
tables of the sanitizer and fuzzing drivers (tests/hostile_c/hostile_table.py) import it by
name: ``from imufuse.registry import FLOAT_CASES``. The helpers that return pytest
parameters import pytest when called (pytest is a test requirement, not the package's).
"""
import functools
import inspect
from dataclasses import dataclass, field

import numpy as np

import imufuse_c

from . import catalogue, reference

DTYPES = ("float32", "float64")


@dataclass(frozen=True)
class Case:
    name: str                       # class name in imufuse_c and imufuse.reference
    params: dict = field(default_factory=dict)   # constructor keywords (dt included)
    label: str = ""                 # distinguishes several configurations of one class

    @property
    def id(self):
        return f"{self.name}-{self.label}" if self.label else self.name

    @property
    def kind(self):
        return catalogue.entry(self.name).kind

    def make(self, backend, dtype):
        return catalogue.entry(self.name).make(backend, **self.params, dtype=dtype)

    @property
    def profiles(self):
        """The fixed-point profiles the class is built in ("32" and "8" for every class today)."""
        return getattr(reference, self.name).profiles

    def make_fixed(self, backend, profile):
        return catalogue.entry(self.name).make(backend, **self.params, profile=profile)


CASES_1D = [
    # chapter 2
    Case("Complementary1D", dict(dt=0.01, alpha=0.98)),
    Case("Complementary1D", dict(dt=1 / 60, T=10 / 60), "seed003"),
    Case("Kalman1D", dict(dt=0.01, k0=0.02)),
    Case("Mahony1D", dict(dt=0.01, kp=2.0)),
    # chapter 3
    Case("Kalman1DBias", dict(dt=0.01, k0=0.02, k1=-0.5)),
    Case("Kalman1DBias", dict(dt=0.01, k0=0.02, k1=0.5, bias_sign=+1), "plus"),
    Case("Mahony1DBias", dict(dt=0.01, kp=2.0, ki=0.3)),
    Case("Mahony1DBias", dict(dt=0.01, kp=2.003, ki=0.3, integrate_first=True), "eq3_9"),
    Case("Complementary1DBias", dict(dt=0.01, kp=2.0, ki=0.3)),
    Case("Complementary1DBias", dict(dt=0.002, omega0=1.5, xi=2.0), "omega0_xi"),
]

# ---- quaternion filters: csrc/mahony.c, csrc/madgwick.c ---------------------
CASES_QUATERNION = [
    # article 4.1 / appendix: Mahony in quaternion form (kp = twoKp/2, ki = twoKi/2).
    # Every option of every class, both precisions: invsqrt exact/fast, ki = 0 / > 0,
    # delta_s full/simplified; "published" = the x-io defaults at 512 Hz.
    Case("MahonyIMU", dict(dt=0.005, kp=1.0, ki=0.3), "ki"),
    Case("MahonyIMU", dict(dt=1 / 512, kp=0.5, ki=0.0, invsqrt="fast"), "published"),
    Case("MahonyAHRS", dict(dt=0.005, kp=1.0, ki=0.3)),
    Case("MahonyAHRS", dict(dt=1 / 512, kp=0.5, ki=0.0, invsqrt="fast"), "published"),
    Case("MahonyAHRS", dict(dt=0.01, kp=2.0, ki=0.5, invsqrt="fast"), "fast_ki"),
    # chapter 5 / appendix: Madgwick's gradient descent
    Case("MadgwickIMU", dict(dt=0.01, beta=0.1)),
    Case("MadgwickIMU", dict(dt=0.01, beta=0.1, delta_s="simplified"), "simplified"),
    Case("MadgwickIMU", dict(dt=1 / 512, beta=0.1, invsqrt="fast"), "published"),
    Case("MadgwickIMU", dict(dt=0.005, beta=0.3, delta_s="simplified", invsqrt="fast"),
         "simplified_fast"),
    Case("MadgwickAHRS", dict(dt=0.01, beta=0.1)),
    Case("MadgwickAHRS", dict(dt=1 / 512, beta=0.1, invsqrt="fast"), "published"),
    # Nair (2016): the accelerometer-magnitude gate (gyro only outside lo..hi g)
    Case("MahonyIMU", dict(dt=0.005, kp=1.0, ki=0.3, acc_gate=(0.6, 1.4)), "gate"),
    Case("MahonyAHRS", dict(dt=0.005, kp=1.0, ki=0.3, acc_gate=(0.9, 1.1), acc_1g=9.81,
                            invsqrt="fast"), "gate_ms2"),
    Case("MadgwickIMU", dict(dt=0.005, beta=0.1, acc_gate=(0.6, 1.4)), "gate"),
    Case("MadgwickIMU", dict(dt=0.005, beta=0.1, delta_s="simplified", acc_gate=(0.0, 1.05)),
         "gate_simplified"),
    Case("MadgwickAHRS", dict(dt=0.005, beta=0.1, acc_gate=(0.6, 1.4), invsqrt="fast"),
         "gate"),
]

# ---- gravity-vector and DCM filters: csrc/multiwii.c, kk.c, mahony2d.c, dcm.c
CASES_GRAVITY = [
    # appendix: MultiWii 2.2 (firmware defaults) and variants of every option
    Case("MultiWii", dict(dt=1 / 400)),
    Case("MultiWii", dict(dt=0.005, cmpf=100.0, acc_lpf_shift=0, window=0.3), "nolpf"),
    Case("MultiWii", dict(dt=0.0025, cmpf=600, acc_lpf_shift=3, acc_1g=512.0), "acc512"),
    Case("MultiWii", dict(dt=0.01, cmpf=0.0, acc_lpf_shift=16, acc_1g=9.80665, window=1.0),
         "wide"),
    # appendix: KK, Eq. 4.5 with a P controller
    Case("KK", dict(dt=0.005, kp=0.01)),
    Case("KK", dict(dt=0.002, kp=1.0), "kp1"),
    # 4.2: Eq. 4.4 and Eq. 4.3
    Case("Mahony2D", dict(dt=0.005, kp=2.0, ki=0.5)),
    Case("Mahony2D", dict(dt=0.005, kp=2.0, ki=0.5, error="exact"), "exact"),
    Case("Mahony2D", dict(dt=0.01, kp=5.0, ki=0.0, error="exact"), "exact_p"),
    # 4.1 / 4.3: DCM with P&B re-orthogonalisation
    Case("DCM", dict(dt=0.005, kp=2.0, ki=0.5)),
    Case("DCM", dict(dt=0.01, kp=0.5, ki=0.0), "p"),
]

# ---- the recommended AHRS: csrc/robust.c (its defaults run as every class's below)
CASES_ROBUST = [
    Case("RobustAHRS", dict(dt=0.01), "defaults"),
    # B6 off: the configuration for an 8-bit MCU (docs/firmware.md), the stored offset only
    Case("RobustAHRS", dict(dt=0.01, mag_learn=False), "nolearn"),
]

EXTRA_FLOAT_CASES = [*CASES_1D, *CASES_QUATERNION, *CASES_GRAVITY, *CASES_ROBUST]


def _with_defaults(extra, entries, dt, case=None):
    """The extra cases plus one default case for every entry without one (dt
    None: a filter constructed without a sample interval)."""
    have = {c.name for c in extra}
    step = {} if dt is None else dict(dt=dt)
    return [*extra, *((case or Case)(e.name, dict(**step, **e.defaults), "defaults")
                      for e in entries if e.name not in have)]


FLOAT_CASES = _with_defaults(EXTRA_FLOAT_CASES, catalogue.FLOAT, 0.01)


def _param(*values, id):
    """One pytest parameter (pytest imported here: only the suites call these helpers)."""
    import pytest
    return pytest.param(*values, id=id)


def float_cases(kind=None):
    cases = [c for c in FLOAT_CASES if kind is None or c.kind == kind]
    return [_param(c, id=c.id) for c in cases]


def float_matrix():
    """(case, dtype) pairs for every float filter configuration."""
    return [_param(c, dt, id=f"{c.id}-{dt}") for c in FLOAT_CASES for dt in DTYPES]


def case_params(cases):
    """pytest parameters of ``cases``, one per configuration (with each_dtype)."""
    return [_param(c, id=c.id) for c in cases]


def each(name, values):
    """A decorator: the test of (..., name, ...) run for every value of ``name`` in one test
    item (the same checks as one item per value, one test ID); a failure names the value."""
    def decorate(test):
        sig = inspect.signature(test)

        @functools.wraps(test)
        def run(*args, **kwargs):
            for v in values:
                try:
                    test(*args, **{name: v}, **kwargs)
                except AssertionError as e:
                    raise AssertionError(f"[{name}={v!r}] {e}") from e
        run.__signature__ = sig.replace(parameters=[p for n, p in sig.parameters.items()
                                                    if n != name])
        return run
    return decorate


#: float32 and float64 in one test item
each_dtype = each("dtype", DTYPES)
#: the compiled filter and its twin in one test item
each_backend = each("backend", ("c", "ref"))


def as_dtype(arrays, dtype):
    return tuple(np.asarray(a, dtype=dtype) for a in arrays)


# ---- fixed point (csrc/fixed): run() takes int16 counts, state is int32 -------
PROFILES = ("32", "8")
EXTRA_FIXED_CASES = [
    Case("Complementary1DQ", dict(dt=0.002, alpha=0.995, gyr_scale=1e-3, angle_scale=1e-4)),
    Case("Mahony1DBiasQ", dict(dt=0.002, kp=2.0, ki=0.2, gyr_scale=1e-3, angle_scale=1e-4)),
    Case("Mahony1DBiasQ", dict(dt=0.002, kp=2.0004, ki=0.2, integrate_first=True,
                               gyr_scale=1e-3, angle_scale=1e-4), "eq3_9"),
    Case("KKQ", dict(dt=0.002, kp=0.002, gyr_scale=1.0642e-3)),
    Case("KKQ", dict(dt=0.005, kp=1.0, gyr_scale=1.0642e-3), "kp1"),
    Case("MultiWiiQ", dict(dt=1 / 400, gyr_scale=1.0642e-3, acc_1g=4096)),
    Case("MultiWiiQ", dict(dt=0.005, cmpf=100.0, acc_lpf_shift=0, window=0.3,
                           gyr_scale=1.0642e-3, acc_1g=512), "nolpf"),
    Case("MultiWiiQ", dict(dt=0.01, cmpf=0.0, acc_lpf_shift=15, window=1.0,
                           gyr_scale=6.1e-5, acc_1g=16384), "extreme"),
    Case("MahonyIMUQ", dict(dt=1 / 512, kp=1.0, ki=0.05, gyr_scale=1.0642e-3)),
    Case("MadgwickIMUQ", dict(dt=1 / 512, beta=0.1, gyr_scale=1.0642e-3)),
    Case("RobustIMUQ", dict(dt=1 / 512, gyr_scale=1.0642e-3), "defaults"),
    Case("RobustAHRSQ", dict(dt=1 / 512, gyr_scale=1.0642e-3), "defaults"),
    # every option off or on against the defaults (the IMU's blocks are the same code in
    # both classes): the output latency, a constant process noise (rate_ref 0), no bias in
    # motion (tau_bias 0), a short rest; B4 with short horizons (hold, new field,
    # reference), no dip test, a narrow norm test
    Case("RobustAHRSQ", dict(dt=1 / 512, latency=0.004, rate_ref=0.0, tau_bias=0.0,
                             rest_time=0.2, mag_hold=0.02, mag_new_time=0.3, tau_mag_ref=0.5,
                             tau_mag=1.0, mag_dip=90.0, mag_norm=0.02, gyr_scale=1.0642e-3),
         "options"),
    # B6 on: the magnetometer offset learnt while turning (its defaults otherwise)
    Case("RobustAHRSQ", dict(dt=1 / 512, mag_learn=True, gyr_scale=1.0642e-3), "learn"),
]


FIXED_CASES = _with_defaults(EXTRA_FIXED_CASES, catalogue.FIXED, 0.002)


def fixed_matrix():
    """(case, profile) pairs for every fixed-point filter configuration."""
    return [_param(c, p, id=f"{c.id}-p{p}") for c in FIXED_CASES for p in c.profiles]


# ---- Nair's variometer (csrc/vario.c): update(accel, baro_alt, dt) ------
# Its own input kind ("vario") and catalogue section (catalogue.VARIO), outside
# the IMU/1-D filters, so it has its own matrix (tests/test_vario.py).
@dataclass(frozen=True)
class VarioCase(Case):
    @property
    def kind(self):
        return "vario"

    def make(self, backend, dtype):
        return catalogue.ALL_ENTRIES[self.name].make(backend, **self.params, dtype=dtype)


EXTRA_CASES_VARIO = [
    VarioCase("VarioKF", {}, "seed_defaults"),
    VarioCase("VarioKF", dict(predict="model"), "model"),
    VarioCase("VarioKF", dict(var_z=150.0, var_acc=5000.0, var_bias=0.01,
                              p0=(10.0, 100.0, 1e3), z0=12345.0, v0=20.0, b0=-3.0,
                              predict="model"), "tuned"),
    VarioCase("VarioKF", dict(var_z=1.0, var_acc=0.0, var_bias=0.0, p0=(0.0, 0.0, 0.0)),
              "zero_noise"),
]
CASES_VARIO = _with_defaults(EXTRA_CASES_VARIO, catalogue.VARIO, None, VarioCase)


def vario_matrix():
    """(case, dtype) pairs for every variometer configuration."""
    return [_param(c, dt, id=f"{c.id}-{dt}") for c in CASES_VARIO for dt in DTYPES]


# ---- the Fusion suite (Longbin's Fusion walkthrough): csrc/fusion_ahrs.c, fusion_offset.c ------------
# Not in FLOAT_CASES, on purpose: the generic harnesses construct a filter with
# dt at init and call update(gyr, acc[, mag]) in rad/s. FusionAHRS is imufusion's
# API: Fusion's units (deg/s, g), dt given with every update, three update forms;
# FusionOffset returns the corrected gyroscope. tests/test_fusion.py runs the same
# checks on them (C vs twin bit for bit in both precisions, update vs run, bad
# input, the non-finite policy, a long run at rest) and tests/test_fusion_oracle.py
# compares them with imufusion 1.2.3. A filter of catalogue.FUSION without a case
# here runs with its catalogue defaults.
EXTRA_FUSION_CASES = [
    Case("FusionAHRS", dict(gain=1.0, gyroscope_range=500.0, acceleration_rejection=5.0,
                            magnetic_rejection=20.0, recovery_trigger_period=100), "short"),
    Case("FusionAHRS", dict(), "defaults"),
    Case("FusionAHRS", dict(gain=0.5, gyroscope_range=2000.0, acceleration_rejection=10.0,
                            magnetic_rejection=10.0, recovery_trigger_period=50, invsqrt="fast"),
         "fast"),
    Case("FusionOffset", dict(sample_rate=100)),
]
FUSION_CASES = _with_defaults(EXTRA_FUSION_CASES, catalogue.FUSION, None)


# ---- representatives: filter-independent code is tested once per code path ---------------

def wrapper_base(case, fixed=False):
    """The compiled base class a case's class inherits its wrapper code from (update(),
    run(), state, reset: imufuse_c/_base.pxi, fixed_base.pxi), by name."""
    cls = getattr(imufuse_c, case.name)
    obj = cls(**case.params, **({"profile": "32"} if fixed else {}))
    base = type(obj).__mro__[1]
    return type(obj).__name__ if base is object else base.__name__     # a class of its own


def representatives(cases, fixed=False):
    """One case per compiled base class (the first of each, in catalogue order): the wrapper
    paths (row reading, state snapshots) are the base class's, so one filter of each base
    runs them; tests/test_wrapper_paths.py checks that no class overrides them."""
    seen, out = set(), []
    for c in cases:
        b = wrapper_base(c, fixed)
        if b not in seen:
            seen.add(b)
            out.append(c)
    return out
