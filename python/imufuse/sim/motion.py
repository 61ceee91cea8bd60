"""Ground-truth orientation trajectories: the Trajectory type, the exact integration of
piecewise-constant body rates (`integrate`), and the seeded generator of the motion kinds
(`trajectory`: static, slow, tilt steps, yaw spin, fast, custom)."""
import math
import struct
from dataclasses import dataclass, field

import numpy as np

from ..rotations import (
    euler_to_quat, quat_conj, quat_from_rotvec, quat_mul, quat_normalize, quat_rotate_inv,
    quat_to_euler, quat_to_rotvec,
)
from .common import (KINDS, _eval_sines, _finite, _max_freq, _samples, _seeds, _sines,
                     _sines_params, _step_schedule)

# Per kind: default amplitude and max frequency (Hz) of the random sinusoids.
_DEFAULTS_3D = {
    "slow": (math.radians(30.0), 0.2),      # rad (max roll/pitch; yaw twice that)
    "tilt_steps": (math.radians(30.0), None),  # rad (max roll/pitch of each step)
    "yaw_spin": (1.0, None),                # rad/s about earth z
    "fast": (5.0, 2.0),                     # rad/s per body axis
}


@dataclass(frozen=True)
class Trajectory:
    """Ground-truth orientation trajectory (see imufuse.sim for the timing).

    t: (N,) s, time of ``q[k]``, ``(k+1)/rate``.
    omega: (N, 3) rad/s, true body rate, constant over sample k's interval.
    q: (N, 4) unit quaternions [w, x, y, z] body -> earth after each sample.
    q0: (4,) orientation at t = 0.
    dt: s, ``1/rate``.
    params: the generator's arguments (seed included) and the drawn random parameters.
    """
    t: np.ndarray
    omega: np.ndarray
    q: np.ndarray
    q0: np.ndarray
    dt: float
    params: dict = field(default_factory=dict)

    def __len__(self):
        return len(self.t)


def integrate(q0, omega, dt):
    """Exact quaternion integration of piecewise-constant body rates.

    ``q[k] = q[k-1] (x) quat_from_rotvec(omega[k] * dt)`` with ``q[-1] = q0``; float64, no
    renormalisation. ``q0`` (4,), ``omega`` (N, 3) rad/s, ``dt`` s. Returns (N, 4).
    """
    q0 = np.asarray(q0, dtype=np.float64)
    if q0.shape != (4,):
        raise ValueError(f"q0 must have shape (4,); got {q0.shape}")
    omega = np.asarray(omega, dtype=np.float64)
    if omega.ndim != 2 or omega.shape[1] != 3:
        raise ValueError(f"omega must have shape (N, 3); got {omega.shape}")
    dq = quat_from_rotvec(omega * dt)
    n = len(omega)
    out = np.empty((n, 4))
    # steps by the identity, bit for bit (a rate of exactly zero): once such a step gives p
    # back bit for bit, every further one does, so the rest of the run at rest repeats p
    ident = np.all(dq.view(np.uint64) == np.array([1.0, 0.0, 0.0, 0.0]).view(np.uint64), axis=1)
    moving = np.flatnonzero(~ident)
    still = ident.tolist()
    rows = dq.tolist()
    pw, px, py, pz = (float(c) for c in q0)
    k = 0
    while k < n:
        qw, qx, qy, qz = rows[k]
        # same expression order as rotations.quat_mul, in Python floats (fast for a
        # sequential loop)
        p = (pw * qw - px * qx - py * qy - pz * qz,
             pw * qx + px * qw + py * qz - pz * qy,
             pw * qy - px * qz + py * qw + pz * qx,
             pw * qz + px * qy - py * qx + pz * qw)
        if still[k] and struct.pack("4d", *p) == struct.pack("4d", pw, px, py, pz):
            j = int(np.searchsorted(moving, k))
            end = int(moving[j]) if j < len(moving) else n
            out[k:end] = p
            k = end
            continue
        pw, px, py, pz = p
        out[k] = p
        k += 1
    return out


def _integrate_earth(q0, omega_earth, dt):
    """Earth-frame piecewise-constant rates: the body rate of step k is R(q[k-1])^T omega_e[k]
    (a rotation about a fixed earth axis is one about a fixed body axis). Returns
    (omega_body (N, 3), q (N, 4))."""
    n = len(omega_earth)
    omega_b = np.empty((n, 3))
    q = np.empty((n, 4))
    prev = np.asarray(q0, dtype=np.float64)
    for k in range(n):
        omega_b[k] = quat_rotate_inv(prev, omega_earth[k])
        prev = quat_mul(prev, quat_from_rotvec(omega_b[k] * dt))
        q[k] = prev
    return omega_b, q


def _rates_from_path(p, dt):
    """Constant body rate per interval that moves p[k-1] exactly onto p[k]: (N+1, 4) -> (N, 3)."""
    return quat_to_rotvec(quat_mul(quat_conj(p[:-1]), p[1:])) / dt


def trajectory(kind=None, *, rate=200.0, duration=10.0, seed=0, q0=None, amplitude=None,
               max_freq=None, hold=2.0, ramp=0.5, omega=None, frame="body"):
    """Seeded ground-truth orientation trajectory.

    kind:
        ``"static"``: no rotation, at ``q0`` (default level, heading north).
        ``"slow"``: smooth random motion. roll and pitch are each a sum of 3 sinusoids with
        random phases and frequencies in [max_freq/5, max_freq] (default 0.2 Hz), bounded by
        ``amplitude`` (rad, default 30 deg); yaw likewise bounded by 2 * amplitude. The body
        rate of each interval is the constant rate joining consecutive points of that ZYX
        Euler path, so ``q`` follows the path to rounding. Default ``q0``: the path's start;
        another ``q0`` replays the same body motion from there.
        ``"tilt_steps"``: hold ``hold`` s, then rotate at constant body rate for ``ramp`` s to a
        new random tilt (roll, pitch uniform in +-amplitude rad, default 30 deg; yaw of
        ``q0``), hold, and so on.
        ``"yaw_spin"``: constant rotation about earth z at ``amplitude`` rad/s (default 1),
        keeping the tilt of ``q0``.
        ``"fast"``: each body rate axis a sum of 3 sinusoids bounded by ``amplitude`` rad/s
        (default 5), frequencies up to ``max_freq`` (default 2 Hz); tumbles freely. The rate
        of each interval is the sinusoid at its midpoint.
        ``"custom"``: ``omega`` gives the rates: a callable ``omega(t) -> (N, 3)`` rad/s,
        called once with the interval midpoints ``(k + 0.5) / rate`` (N,), or an (N, 3) array
        (then N = len(omega) and ``duration`` is ignored). ``frame="earth"`` reads them as
        earth-frame rates (converted to body rates step by step), ``"body"`` (default) as
        body rates.
        Default: ``"custom"`` if ``omega`` is given, else ``"slow"``.
    rate: Hz. duration: s. seed: int >= 0 or None (see imufuse.sim).
    q0: None, a (4,) quaternion (normalised here), or ``"random"`` (uniform, from the seed).
    Returns a :class:`Trajectory`.
    """
    if kind is None:
        kind = "slow" if omega is None else "custom"
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}; got {kind!r}")
    if (omega is not None) != (kind == "custom"):
        raise ValueError("omega is required for kind='custom' and only allowed with it")
    if frame not in ("body", "earth"):
        raise ValueError(f"frame must be 'body' or 'earth'; got {frame!r}")
    if frame == "earth" and kind != "custom":
        raise ValueError("frame='earth' applies to kind='custom' only")
    if kind == "custom" and not callable(omega):
        omega = np.asarray(omega, dtype=np.float64)
        if omega.ndim != 2 or omega.shape[1] != 3 or len(omega) < 1:
            raise ValueError(f"omega array must have shape (N, 3); got {omega.shape}")
        duration = len(omega) / _finite(rate, "rate", 0.0, lo_open=True)
    rate, duration, n = _samples(rate, duration)
    hold = _finite(hold, "hold", 0.0)
    ramp = _finite(ramp, "ramp", 0.0)
    dt = 1.0 / rate
    used_seed, (rng,) = _seeds(seed, 1)
    amp_default, f_default = _DEFAULTS_3D.get(kind, (None, None))
    amp = None if amp_default is None else (
        amp_default if amplitude is None else _finite(amplitude, "amplitude", 0.0))
    params = {"kind": kind, "rate": rate, "duration": duration, "n": n, "seed": used_seed,
              "amplitude": amp, "frame": frame}

    # q0 first (its draw, if any, precedes the motion's draws)
    q0_given = q0 is not None
    if isinstance(q0, str):
        if q0 != "random":
            raise ValueError(f"q0 must be None, a quaternion or 'random'; got {q0!r}")
        q0 = quat_normalize(rng.standard_normal(4))
    elif q0 is not None:
        q0 = np.asarray(q0, dtype=np.float64)
        if q0.shape != (4,) or not np.all(np.isfinite(q0)):
            raise ValueError(f"q0 must be a finite (4,) quaternion; got shape {q0.shape}")
        q0 = quat_normalize(q0)
    else:
        q0 = np.array([1.0, 0.0, 0.0, 0.0])

    t_mid = (np.arange(n) + 0.5) / rate
    q = None
    if kind == "static":
        om = np.zeros((n, 3))
    elif kind == "slow":
        f_hi = _max_freq(max_freq, f_default, rate)
        s = _sines(rng, 3, [amp, amp, 2.0 * amp], f_hi)
        params.update(max_freq=f_hi, sines=_sines_params(s))
        path = euler_to_quat(_eval_sines(s, np.arange(n + 1) / rate))
        om = _rates_from_path(path, dt)
        if not q0_given:
            q0 = path[0]
    elif kind == "tilt_steps":
        params.update(hold=hold, ramp=ramp)
        yaw0 = float(quat_to_euler(q0)[2])
        hold_n, ramp_n = max(1, int(round(hold * rate))), max(1, int(round(ramp * rate)))
        om = np.zeros((n, 3))
        cur, targets = q0, []
        for a, b, is_ramp in _step_schedule(n, hold_n, ramp_n):
            if is_ramp:
                rp = rng.uniform(-amp, amp, 2)
                tgt = euler_to_quat([rp[0], rp[1], yaw0])
                targets.append(rp.tolist())
                om[a:b] = quat_to_rotvec(quat_mul(quat_conj(cur), tgt)) / (ramp_n * dt)
                cur = tgt
        params["targets"] = targets
    elif kind == "yaw_spin":
        om = np.broadcast_to(quat_rotate_inv(q0, [0.0, 0.0, amp]), (n, 3)).copy()
    elif kind == "fast":
        f_hi = _max_freq(max_freq, f_default, rate)
        s = _sines(rng, 3, amp, f_hi)
        params.update(max_freq=f_hi, sines=_sines_params(s))
        om = _eval_sines(s, t_mid)
    else:  # custom
        if callable(omega):
            om = np.asarray(omega(t_mid), dtype=np.float64)
            if om.shape != (n, 3):
                raise ValueError(f"omega(t) must return shape ({n}, 3); got {om.shape}")
        else:
            om = omega.copy()
        if not np.all(np.isfinite(om)):
            raise ValueError("omega contains non-finite values")
        if frame == "earth":
            om, q = _integrate_earth(q0, om, dt)
    if q is None:
        q = integrate(q0, om, dt)
    params["q0"] = q0.tolist()
    t = np.arange(1, n + 1) / rate
    return Trajectory(t=t, omega=np.ascontiguousarray(om), q=q, q0=np.array(q0, dtype=float),
                      dt=dt, params=params)
