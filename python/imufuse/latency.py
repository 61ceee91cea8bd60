"""The delay of a gyroscope behind an orientation reference (`imufuse latency`), measured
without running any filter: what RobustIMU's and RobustAHRS's `latency` compensates. The
reference's rates come from its quaternions (imufuse.evaluation's conventions; it is
imported from there too)."""
import math

import numpy as np

from .rotations import DIRECTIONS, quat_conj, quat_mul, quat_rows as _quats, quat_to_rotvec


def _ref_rates(q_ref, t):
    """Body rates of a sensor-to-earth reference between consecutive rows:
    ((N-1, 3) rad/s at the interval midpoints, (N-1,) midpoint times); NaN
    where either row is not finite."""
    q = q_ref / np.linalg.norm(q_ref, axis=1, keepdims=True)
    d = quat_mul(quat_conj(q[:-1]), q[1:])            # r_k^-1 (x) r_k+1, sensor frame
    return quat_to_rotvec(d) / np.diff(t)[:, None], 0.5 * (t[:-1] + t[1:])


def estimate_latency(gyr, q_ref, dt=None, *, t=None, ref_direction="sensor-to-earth",
                     max_delay=0.05):
    """Delay of a gyroscope behind a reference orientation, s (negative: it leads).

    The reference's body rates, from consecutive rows, are compared with the
    gyroscope as imufuse's filters integrate it (sample k is the rate over
    [t_k-1, t_k]); the time shift that fits them best in the least-squares
    sense, the mean difference (the gyro bias) removed, is found to a small
    fraction of a sample within +-max_delay. It is what RobustIMU's and
    RobustAHRS's `latency` compensates: the delay of this recording chain
    (the gyro's digital filter, the logger, the reference's own timing),
    measured without running any filter.

    gyr (N, 3) rad/s in the sensor axes of the reference (non-finite rows are
    left out); q_ref (N, 4) [w x y z], NaN rows where the reference dropped
    out (rate pairs touching them, and gyro samples that would need them, are
    left out); dt (s) for a fixed rate,
    or t (N,) increasing sample times. The earth frame of q_ref does not matter
    (body rates do not depend on it); its direction does.

    Raises ValueError for bad arguments, for a recording with too little
    rotation to time (reference rates below 0.05 rad/s RMS, or fewer than 100
    usable samples), when the best shift is at +-max_delay (the delay is
    larger than the range searched), and when even the best shift leaves a
    misfit above half the reference's RMS rate (the gyro's axes, units or
    the reference's direction do not match: no delay is reported then)."""
    gyr = np.asarray(gyr, dtype=np.float64)
    q = _quats(q_ref, "q_ref")
    if gyr.ndim != 2 or gyr.shape[1] != 3:
        raise ValueError(f"gyr: expected shape (N, 3), got {gyr.shape}")
    n = len(gyr)
    if len(q) != n:
        raise ValueError(f"gyr and q_ref: different lengths ({n} and {len(q)})")
    if ref_direction not in DIRECTIONS:
        raise ValueError(f"ref_direction: must be one of {', '.join(DIRECTIONS)}, "
                         f"got {ref_direction!r}")
    if not (isinstance(max_delay, (int, float)) and 0 < max_delay < math.inf):
        raise ValueError(f"max_delay: must be a positive number of seconds, got {max_delay!r}")
    if (dt is None) == (t is None):
        raise ValueError("give one of dt (a fixed sample period) or t (sample times)")
    if t is None:
        if not (isinstance(dt, (int, float)) and 0 < dt < math.inf):
            raise ValueError(f"dt: must be a positive number of seconds, got {dt!r}")
        t = np.arange(n) * float(dt)
    else:
        t = np.asarray(t, dtype=np.float64)
        if t.shape != (n,):
            raise ValueError(f"t: expected shape ({n},), got {t.shape}")
        if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
            raise ValueError("t: sample times must be finite and increasing")
    if n < 3:
        raise ValueError(f"too few samples to time ({n})")
    span = float(t[-1] - t[0])
    if max_delay > 0.5 * span:
        # the search grid grows with max_delay: bounded by the data, not by the argument
        raise ValueError(f"max_delay: {max_delay!r} s is more than half the log "
                         f"({span:.6g} s); no shift that large can line up the samples")
    if ref_direction == "earth-to-sensor":
        q = quat_conj(q)
    h = np.diff(t)
    # where each gyro sample's rate is taken: the middle of its interval
    tg = np.concatenate(([t[0] - h[0]], t[:-1])) + 0.5 * np.concatenate(([h[0]], h))
    with np.errstate(invalid="ignore", divide="ignore"):
        w, tw = _ref_rates(q, t)
    ok = np.all(np.isfinite(w), axis=1)
    w, tw = w[ok], tw[ok]
    g_ok = np.all(np.isfinite(gyr), axis=1)
    if np.any(np.abs(gyr[g_ok]) > 1e4):
        raise ValueError("gyr: values beyond 1e4 rad/s, which no gyroscope measures (the unit "
                         "is rad/s)")
    if len(tw) < 2:
        raise ValueError("the reference has fewer than two usable rate samples")
    gap = 1.5 * float(np.median(h))

    def msq(x):
        x = x - x.mean(axis=0)
        return float(np.mean(np.einsum("ij,ij->i", x, x)))

    def fit(tau):
        """(mean squared gyro - reference difference, mean squared reference rate), means
        removed, at shift tau; inf when fewer than 100 samples line up"""
        tq = tg - tau
        j = np.searchsorted(tw, tq)
        use = g_ok & (j > 0) & (j < len(tw))
        jj = j[use]
        use[use] = (tw[jj] - tw[jj - 1]) <= gap         # no interpolation across a dropout
        if np.count_nonzero(use) < 100:
            return math.inf, math.inf
        wi = np.column_stack([np.interp(tq[use], tw, w[:, i]) for i in range(3)])
        return msq(gyr[use] - wi), msq(wi)

    if len(w) < 100 or math.sqrt(msq(w)) < 0.05:
        raise ValueError("too little rotation to time: the reference's rates are below "
                         "0.05 rad/s RMS or fewer than 100 samples are usable")
    step = float(np.median(h)) / 2.0
    taus = np.arange(-max_delay, max_delay + 0.5 * step, step)
    res = np.array([fit(x)[0] for x in taus])
    if not np.any(np.isfinite(res)):
        raise ValueError("fewer than 100 gyro samples line up with the reference at any shift")
    i = int(np.argmin(res))
    if i == 0 or i == len(taus) - 1:
        raise ValueError(f"the best shift is at the edge of +-{max_delay} s: the delay is "
                         "larger than max_delay, or the gyro and the reference do not match "
                         "(axes, units, direction)")
    a, b = taus[i - 1], taus[i + 1]                      # golden section in the bracket
    r = (math.sqrt(5.0) - 1.0) / 2.0
    c, d = b - r * (b - a), a + r * (b - a)
    fc, fd = fit(c)[0], fit(d)[0]
    while b - a > 1e-7:
        if fc < fd:
            b, d, fd = d, c, fc
            c = b - r * (b - a)
            fc = fit(c)[0]
        else:
            a, c, fc = c, d, fd
            d = a + r * (b - a)
            fd = fit(d)[0]
    tau = 0.5 * (a + b)
    misfit, spread = fit(tau)
    if not misfit <= 0.25 * spread:
        raise ValueError(f"the gyroscope does not follow the reference's rates (RMS misfit "
                         f"{math.sqrt(misfit):.3g} against {math.sqrt(spread):.3g} rad/s at the "
                         f"best shift): check the sensor's axes, the gyroscope's unit and the "
                         f"reference's direction (ref_direction={ref_direction!r})")
    return tau
