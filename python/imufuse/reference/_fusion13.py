"""Validation shared by both backends of Fusion 1.3 (imufuse_c.FusionAHRS13 /
imufuse.reference.FusionAHRS13, FusionBias): one definition of every check, so both accept
and reject the same things. The outputs and flags are packed as the 1.2.3 port's
(imufuse.reference._fusion), the start-up flag under the name `initialising` and the overrange
recovery under `angular_rate_recovery`."""
import math

import numpy as np

from ..shared import checks as _checks
from . import _fusion

AHRS_STATE_NAMES = (
    "q0", "q1", "q2", "q3", "acc_x", "acc_y", "acc_z", "startup_gain",
    "half_acc_res_x", "half_acc_res_y", "half_acc_res_z",
    "half_mag_res_x", "half_mag_res_y", "half_mag_res_z", "sample_period",
    "startup", "overrange_recovery", "accelerometer_ignored",
    "acceleration_recovery_trigger", "acceleration_recovery_threshold",
    "magnetometer_ignored", "magnetic_recovery_trigger", "magnetic_recovery_threshold")
N_REAL = 15          # the first 15 state variables are reals, the rest integers
BIAS_STATE_NAMES = ("offset_x", "offset_y", "offset_z", "timer")

#: the settings of FusionAhrsSettings (1.3), in order; invsqrt is chosen at construction
SETTINGS = ("sample_rate", "convention", "gain", "gyroscope_range", "acceleration_rejection",
            "magnetic_rejection", "rejection_timeout")
#: Fusion 1.3's defaults (fusionAhrsDefaultSettings)
DEFAULTS = dict(sample_rate=100.0, convention="NWU", gain=0.5, gyroscope_range=0.0,
                acceleration_rejection=0.0, magnetic_rejection=0.0, rejection_timeout=0.0)
#: x-io's advanced example (Fusion's README and examples): 100 Hz, gain 0.5, 2000 deg/s,
#: 10 degrees of acceleration and magnetic rejection, a 5 s rejection timeout
ADVANCED = dict(sample_rate=100.0, convention="NWU", gain=0.5, gyroscope_range=2000.0,
                acceleration_rejection=10.0, magnetic_rejection=10.0, rejection_timeout=5.0)
#: FusionBias's defaults (fusionBiasDefaultSettings)
BIAS_DEFAULTS = dict(sample_rate=100.0, stationary_threshold=3.0, stationary_period=3.0)

#: FusionRemapAlignment's 24 alignments, in the enum's order (remap(x, alignment) takes the
#: name or its number)
REMAP_ALIGNMENTS = (
    "+X+Y+Z", "+X+Z-Y", "+X-Z+Y", "+X-Y-Z", "+Y+X-Z", "+Y+Z+X", "+Y-Z-X", "+Y-X+Z",
    "+Z+X+Y", "+Z+Y-X", "+Z-Y+X", "+Z-X-Y", "-Z+X-Y", "-Z+Y+X", "-Z-Y-X", "-Z-X+Y",
    "-Y+X+Z", "-Y+Z-X", "-Y-Z+X", "-Y-X-Z", "-X+Y-Z", "-X+Z+Y", "-X-Z-Y", "-X-Y+Z")


def _samples(name, rate, seconds, dtype):
    """rate * seconds rounded in dtype and truncated, as Fusion's (int) conversion: it
    must fit in the state's exact integers."""
    with np.errstate(all="ignore"):
        if dtype == "float32":
            v = float(np.float32(rate) * np.float32(seconds))
        else:
            v = rate * seconds
    if not 0.0 <= v <= _fusion.MAX_PERIOD:
        raise ValueError(f"{name}: sample_rate * {name} = {v!r} samples, must be in "
                         f"[0, {_fusion.MAX_PERIOD}]")
    return v


def ahrs_params(dtype, sample_rate=100.0, convention="NWU", gain=0.5, gyroscope_range=0.0,
                acceleration_rejection=0.0, magnetic_rejection=0.0, rejection_timeout=0.0,
                invsqrt="exact"):
    """Validate FusionAHRS13 settings; return the C init arguments (sample rate, convention
    code, gain, range, acc. rejection, mag. rejection, timeout, invsqrt code)."""
    if not isinstance(convention, str) or convention.upper() not in _fusion.CONVENTIONS:
        raise ValueError(f"convention: must be one of 'NWU', 'ENU', 'NED', got {convention!r}")
    _checks.check_choice("invsqrt", invsqrt, tuple(_fusion.INVSQRT))
    rate = _fusion._as_real("sample_rate", sample_rate, dtype, lo=1e-3, hi=1e6)
    timeout = _fusion._as_real("rejection_timeout", rejection_timeout, dtype, lo=0.0, hi=1e6)
    _samples("rejection_timeout", rate, timeout, dtype)
    return (rate, _fusion.CONVENTIONS[convention.upper()],
            _fusion._as_real("gain", gain, dtype, lo=0.0, hi=1e6),
            _fusion._as_real("gyroscope_range", gyroscope_range, dtype, lo=0.0, hi=1e9),
            _fusion._rejection("acceleration_rejection", acceleration_rejection, dtype),
            _fusion._rejection("magnetic_rejection", magnetic_rejection, dtype),
            timeout, _fusion.INVSQRT[invsqrt])


def bias_params(dtype, sample_rate=100.0, stationary_threshold=3.0, stationary_period=3.0):
    rate = _fusion._as_real("sample_rate", sample_rate, dtype, lo=1e-3, hi=1e6)
    threshold = _fusion._as_real("stationary_threshold", stationary_threshold, dtype, lo=0.0,
                                 hi=1e9)
    period = _fusion._as_real("stationary_period", stationary_period, dtype, lo=0.0, hi=1e6)
    _samples("stationary_period", rate, period, dtype)
    return (rate, threshold, period)


def check_settings(settings):
    """set_settings' keywords: the seven Fusion 1.3 settings; anything else is refused."""
    for k in settings:
        if k not in SETTINGS:
            raise ValueError(f"{k}: not a setting of FusionAHRS13; set_settings changes "
                             f"{', '.join(SETTINGS)} (invsqrt is chosen at construction)")


def user_settings(args):
    """The C init arguments back as set_settings keywords."""
    conv = [k for k, v in _fusion.CONVENTIONS.items() if v == args[1]][0]
    return dict(zip(SETTINGS, (args[0], conv, *args[2:7])))


def invsqrt_name(code):
    return [k for k, v in _fusion.INVSQRT.items() if v == code][0]


def ahrs_state(value, dtype, timeout):
    """A full state vector to set: finite, integers integral and in range."""
    arr = _checks.as_state(value, len(AHRS_STATE_NAMES), dtype, AHRS_STATE_NAMES)
    ints = arr[N_REAL:].astype(np.float64)
    if not np.all(ints == np.trunc(ints)):
        raise ValueError("state: the flag and counter entries must be integers")
    for i in (0, 1, 2, 5):
        if ints[i] not in (0, 1):
            raise ValueError(f"state: {AHRS_STATE_NAMES[N_REAL + i]} must be 0 or 1")
    for i in (3, 4, 6, 7):
        if not 0 <= ints[i] <= timeout:
            raise ValueError(f"state: {AHRS_STATE_NAMES[N_REAL + i]} must be in [0, {timeout}]")
    if not arr[14] >= 0:
        raise ValueError("state: sample_period must be >= 0 seconds")
    n2 = float(np.dot(arr[:4].astype(np.float64), arr[:4].astype(np.float64)))
    if not abs(n2 - 1.0) <= 0.01:
        raise ValueError(f"state: not a valid attitude (|q|^2 = {n2!r}, must be within 1 +- "
                         "0.01)")
    return arr


def states_array(states, dtype):
    arr = np.ascontiguousarray(np.asarray(states, dtype=dtype))
    if arr.ndim != 2 or arr.shape[1] != len(AHRS_STATE_NAMES):
        raise ValueError(f"outputs(): expected (N, {len(AHRS_STATE_NAMES)}) states, got "
                         f"{arr.shape}")
    ints = arr[:, N_REAL:].astype(np.float64)
    if not (np.all(np.isfinite(arr)) and np.all(ints == np.trunc(ints))
            and np.all(np.abs(ints) <= _fusion.MAX_PERIOD)):
        raise ValueError("outputs(): states must be finite, with integral flags and counters "
                         f"within +-{_fusion.MAX_PERIOD} (rows of run())")
    return arr


def run_arrays(dtype, gyr, acc, mag, heading, dt):
    """run() inputs: (gyr, acc, mag or None, heading or None, dt (N,) or None: the
    settings' period)."""
    if dt is None:
        g, a, m, h, _ = _fusion.run_arrays(dtype, gyr, acc, mag, heading, 0.0)
        return g, a, m, h, None
    return _fusion.run_arrays(dtype, gyr, acc, mag, heading, dt)


def remap_alignment(alignment):
    """An alignment name of FusionRemap ('+X+Z-Y') or its number -> (perm, negate)."""
    if isinstance(alignment, (int, np.integer)) and not isinstance(alignment, bool):
        if not 0 <= int(alignment) < len(REMAP_ALIGNMENTS):
            raise ValueError(f"alignment: must be 0..23 or a name like '+X+Z-Y', got "
                             f"{alignment!r}")
        alignment = REMAP_ALIGNMENTS[int(alignment)]
    perm, neg = _fusion.parse_alignment(alignment)
    if not _fusion.alignment_is_rotation(alignment):
        raise ValueError(f"alignment: {alignment!r} is a reflection; FusionRemap takes the 24 "
                         "rotations")
    return perm, neg


def finite_period(dt):
    v = _fusion.check_dt_value(dt)
    if not math.isfinite(v):
        raise ValueError(f"sample_period: must be finite, got {dt!r}")
    return v
