"""Validation and result packing shared by both backends of the Fusion suite
(imufuse_c.FusionAHRS / imufuse.reference.FusionAHRS, FusionOffset): one
definition of every check, so both accept and reject the same things."""
import math

import numpy as np

from ..shared import checks as _checks

CONVENTIONS = {"NWU": 0, "ENU": 1, "NED": 2}
INVSQRT = {"exact": 0, "fast": 1}

AHRS_STATE_NAMES = (
    "q0", "q1", "q2", "q3", "acc_x", "acc_y", "acc_z", "ramped_gain",
    "half_acc_fb_x", "half_acc_fb_y", "half_acc_fb_z",
    "half_mag_fb_x", "half_mag_fb_y", "half_mag_fb_z",
    "initialising", "angular_rate_recovery", "accelerometer_ignored",
    "acceleration_recovery_trigger", "acceleration_recovery_timeout",
    "magnetometer_ignored", "magnetic_recovery_trigger", "magnetic_recovery_timeout")
N_REAL = 14          # the first 14 state variables are reals, the rest integers
OFFSET_STATE_NAMES = ("offset_x", "offset_y", "offset_z", "timer")

# outputs of imf_fusion_ahrs_outputs, in order: name -> (start, width)
OUTPUTS = {"gravity": (0, 3), "linear_acceleration": (3, 3), "earth_acceleration": (6, 3),
           "euler": (9, 3), "acceleration_error": (12, 1), "acceleration_recovery_trigger": (13, 1),
           "magnetic_error": (14, 1), "magnetic_recovery_trigger": (15, 1)}
N_OUT = 16
FLAGS = {"initialising": 1, "angular_rate_recovery": 2, "acceleration_recovery": 4,
         "magnetic_recovery": 8, "accelerometer_ignored": 16, "magnetometer_ignored": 32}
MAX_PERIOD = 1 << 24   # integers in the state stay exact in float32

#: Fusion's defaults (FusionAhrsInitialise)
DEFAULTS = dict(convention="NWU", gain=0.5, gyroscope_range=0.0, acceleration_rejection=90.0,
                magnetic_rejection=90.0, recovery_trigger_period=0)


def _as_real(name, value, dtype, lo=None, hi=None):
    """A real setting checked in the filter's own precision: finite there, and (unless
    zero) a normal number there, so it cannot vanish to 0 or turn subnormal."""
    v = _checks.check_real(name, value, lo=lo, hi=hi)
    with np.errstate(all="ignore"):
        r = float(np.float32(v)) if dtype == "float32" else float(v)
    if not math.isfinite(r):
        raise ValueError(f"{name}: not representable in {dtype}, got {value!r}")
    tiny = float(np.finfo(dtype).tiny)
    if v != 0.0 and abs(r) < tiny:
        raise ValueError(f"{name}: {value!r} is too small for {dtype} (below the smallest "
                         f"normal number {tiny:g})")
    return v


def _rejection(name, value, dtype):
    """A rejection threshold (degrees) whose derived (sin(threshold) / 2)^2 stays a normal
    number in dtype (a threshold of 1e-20 degrees would act as 0 in float32)."""
    v = _as_real(name, value, dtype, lo=0.0, hi=180.0)
    x = (math.sin(math.radians(v)) * 0.5) ** 2
    if 0.0 < v < 90.0 and x < float(np.finfo(dtype).tiny) * 2.0 ** 24:
        raise ValueError(f"{name}: {value!r} degrees is too small for {dtype} (its threshold "
                         f"(sin/2)^2 = {x:g} is not a normal number there)")
    return v


def _as_int(name, value, lo, hi):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        else:
            raise ValueError(f"{name}: must be an integer, got {value!r}")
    value = int(value)
    if not lo <= value <= hi:
        raise ValueError(f"{name}: must be in [{lo}, {hi}], got {value}")
    return value


def ahrs_params(dtype, convention="NWU", gain=0.5, gyroscope_range=0.0,
                acceleration_rejection=90.0, magnetic_rejection=90.0,
                recovery_trigger_period=0, invsqrt="exact"):
    """Validate FusionAHRS settings; return the C init arguments
    (convention code, gain, range, acc. rejection, mag. rejection, period, invsqrt code)."""
    if not isinstance(convention, str) or convention.upper() not in CONVENTIONS:
        raise ValueError(f"convention: must be one of 'NWU', 'ENU', 'NED', got {convention!r}")
    _checks.check_choice("invsqrt", invsqrt, tuple(INVSQRT))
    return (CONVENTIONS[convention.upper()],
            _as_real("gain", gain, dtype, lo=0.0, hi=1e6),
            _as_real("gyroscope_range", gyroscope_range, dtype, lo=0.0, hi=1e9),
            _rejection("acceleration_rejection", acceleration_rejection, dtype),
            _rejection("magnetic_rejection", magnetic_rejection, dtype),
            _as_int("recovery_trigger_period", recovery_trigger_period, 0, MAX_PERIOD),
            INVSQRT[invsqrt])


def offset_params(sample_rate):
    return (_as_int("sample_rate", sample_rate, 1, MAX_PERIOD // 5),)


def to_real(R, x):
    """x in the filter's type R: beyond float32, +-inf, as C's conversion, without numpy's
    overflow warning (the sample is then rejected, as in C)."""
    with np.errstate(over="ignore"):
        return R(x)


def check_dt_value(dt):
    """dt of one update: a real number >= 0 (NaN/inf go to the non-finite policy)."""
    try:
        v = float(dt)
    except (TypeError, ValueError):
        raise ValueError(f"dt: must be a real number, got {dt!r}") from None
    if v < 0:
        raise ValueError(f"dt: must be >= 0 seconds, got {dt!r}")
    return v


def check_scalar(name, value):
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: must be a real number, got {value!r}") from None


def ahrs_state(value, dtype, period):
    """A full state vector to set: finite, integers integral and in range."""
    arr = _checks.as_state(value, len(AHRS_STATE_NAMES), dtype, AHRS_STATE_NAMES)
    ints = arr[N_REAL:].astype(np.float64)
    if not np.all(ints == np.trunc(ints)):
        raise ValueError("state: the flag and counter entries must be integers")
    for i in (0, 1, 2, 5):          # the 0/1 flags
        if ints[i] not in (0, 1):
            raise ValueError(f"state: {AHRS_STATE_NAMES[N_REAL + i]} must be 0 or 1")
    for i in (3, 4, 6, 7):          # triggers and timeouts
        if not 0 <= ints[i] <= period:
            raise ValueError(f"state: {AHRS_STATE_NAMES[N_REAL + i]} must be in [0, {period}]")
    n2 = float(np.dot(arr[:4].astype(np.float64), arr[:4].astype(np.float64)))
    if not abs(n2 - 1.0) <= 0.01:
        raise ValueError(f"state: not a valid attitude (|q|^2 = {n2!r}, must be within 1 +- "
                         "0.01)")
    return arr


def quaternion(value, dtype):
    arr = np.ascontiguousarray(np.asarray(value, dtype=dtype))
    if arr.shape != (4,):
        raise ValueError(f"quaternion: expected shape (4,) (w, x, y, z), got {arr.shape}")
    if not np.all(np.isfinite(arr)) or not np.any(arr):
        raise ValueError("quaternion: must be finite and not zero")
    return arr


def run_arrays(dtype, gyr, acc, mag, heading, dt):
    """Validate run() inputs; return (gyr, acc, mag or None, heading or None, dt (N,))."""
    if mag is not None and heading is not None:
        raise ValueError("run(): give mag or heading, not both")
    named = {"gyr": gyr, "acc": acc}
    if mag is not None:
        named["mag"] = mag
    arrays = _checks.as_nx3(dtype, **named)
    n = arrays[0].shape[0]
    h = None
    if heading is not None:
        with np.errstate(over="ignore"):    # float64 beyond float32: inf, a rejected sample
            h = np.ascontiguousarray(heading, dtype=dtype)
        if h.shape != (n,):
            raise ValueError(f"run(): heading must have shape ({n},), got {h.shape}")
    if dt is None:
        raise TypeError("run(): dt is required (seconds, scalar or (N,))")
    d = np.asarray(dt, dtype=np.float64)
    if d.ndim == 0:
        d = np.full(n, check_dt_value(dt))
    elif d.shape != (n,):
        raise ValueError(f"run(): dt must be a scalar or have shape ({n},), got {d.shape}")
    if np.any(d < 0):
        raise ValueError("dt: must be >= 0 seconds")
    with np.errstate(over="ignore"):        # likewise
        d = np.ascontiguousarray(d, dtype=dtype)
    return arrays[0], arrays[1], (arrays[2] if mag is not None else None), h, d


def states_array(states, dtype):
    arr = np.ascontiguousarray(np.asarray(states, dtype=dtype))
    if arr.ndim != 2 or arr.shape[1] != len(AHRS_STATE_NAMES):
        raise ValueError(f"outputs(): expected (N, {len(AHRS_STATE_NAMES)}) states, got {arr.shape}")
    ints = arr[:, N_REAL:].astype(np.float64)
    # the C converts these to int32_t: out-of-range values would be undefined behaviour
    if not (np.all(np.isfinite(arr)) and np.all(ints == np.trunc(ints))
            and np.all(np.abs(ints) <= MAX_PERIOD)):
        raise ValueError("outputs(): states must be finite, with integral flags and counters "
                         f"within +-{MAX_PERIOD} (rows of run())")
    return arr


def pack_outputs(out, flags):
    """out (N, 16) reals and flags (N,) bits -> dict of named arrays."""
    res = {}
    for name, (start, width) in OUTPUTS.items():
        res[name] = out[:, start] if width == 1 else out[:, start:start + width]
    for name, bit in FLAGS.items():
        res[name] = (flags & bit) != 0
    return res


def pack_one(out, flags):
    res = pack_outputs(np.asarray(out)[None, :], np.asarray([flags]))
    return {k: (v[0] if v.ndim == 2 else v[0].item()) for k, v in res.items()}


# ---- axis alignment -----------------------------------------------------------

#: FusionAxesSwap's 24 alignments (right-handed), in FusionAxesAlignment order
FUSION_ALIGNMENTS = (
    "+X+Y+Z", "+X-Z+Y", "+X-Y-Z", "+X+Z-Y", "-X+Y-Z", "-X+Z+Y", "-X-Y+Z", "-X-Z-Y",
    "+Y-X+Z", "+Y-Z-X", "+Y+X-Z", "+Y+Z+X", "-Y+X+Z", "-Y-Z+X", "-Y-X-Z", "-Y+Z-X",
    "+Z+Y-X", "+Z+X+Y", "+Z-Y+X", "+Z-X-Y", "-Z+Y+X", "-Z-X+Y", "-Z-Y-X", "-Z+X-Y")


def parse_alignment(alignment):
    """'+X-Z+Y' (output x = +sensor x, y = -sensor z, z = +sensor y) ->
    (perm, negate). Any of the 48 signed permutations; case-insensitive."""
    s = alignment.upper().replace(" ", "") if isinstance(alignment, str) else None
    if s is None or len(s) != 6:
        raise ValueError(f"alignment: expected three signed axes like '+X-Z+Y', got {alignment!r}")
    perm, neg = [], []
    for i in range(3):
        sign, axis = s[2 * i], s[2 * i + 1]
        if sign not in "+-" or axis not in "XYZ":
            raise ValueError(f"alignment: expected three signed axes like '+X-Z+Y', got {alignment!r}")
        perm.append("XYZ".index(axis))
        neg.append(1 if sign == "-" else 0)
    if sorted(perm) != [0, 1, 2]:
        raise ValueError(f"alignment: each of X, Y, Z must appear once, got {alignment!r}")
    return tuple(perm), tuple(neg)


def alignment_matrix(alignment):
    """The 3x3 matrix M of an alignment: output = M sensor (a signed permutation)."""
    perm, neg = parse_alignment(alignment)
    m = np.zeros((3, 3))
    for i in range(3):
        m[i, perm[i]] = -1.0 if neg[i] else 1.0
    return m


def alignment_is_rotation(alignment):
    return bool(np.linalg.det(alignment_matrix(alignment)) > 0)


ALL_ALIGNMENTS = tuple(
    f"{s0}{a0}{s1}{a1}{s2}{a2}"
    for a0, a1, a2 in ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX")
    for s0 in "+-" for s1 in "+-" for s2 in "+-")


def model_param(name, value, shape, dtype):
    """A calibration-model parameter (3x3 matrix or 3-vector) as a flat contiguous
    array of dtype; ValueError naming it for a wrong shape or non-finite values."""
    # checked before any conversion: complex, None and strings are refused, not cast
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError):
        raw = np.asarray(None)
    if isinstance(value, (str, bytes)) or raw.dtype.kind not in "biuf":
        raise ValueError(f"{name}: expected real numbers, got {value!r}")
    with np.errstate(over="ignore"):
        arr = raw.astype(dtype)
    if arr.shape != shape:
        raise ValueError(f"{name}: expected shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: must be finite")
    return np.ascontiguousarray(arr.reshape(-1))


#: what FusionAHRS.set_settings changes (FusionAhrsSettings); invsqrt is set at construction
SETTINGS = ("convention", "gain", "gyroscope_range", "acceleration_rejection",
            "magnetic_rejection", "recovery_trigger_period")


def check_settings(settings):
    """set_settings' keywords: the six Fusion settings; invsqrt (chosen at construction, as in
    the C init) and unknown names are refused with the names that can be set."""
    for k in settings:
        if k == "invsqrt":
            raise ValueError("invsqrt: chosen at construction (FusionAHRS(..., invsqrt=...)); "
                             f"set_settings changes {', '.join(SETTINGS)}")
        if k not in SETTINGS:
            raise ValueError(f"{k}: not a setting of FusionAHRS; set_settings changes "
                             f"{', '.join(SETTINGS)}")
