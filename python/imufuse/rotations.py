"""Quaternion, rotation-matrix and Euler-angle helpers (float64, vectorised).

Conventions (README.md, Conventions):

- A quaternion is ``[w, x, y, z]`` (scalar first, Madgwick's q0..q3) and rotates the *sensor*
  (body) frame into the *earth* frame: ``v_earth = R(q) v_body``, ``v_body = R(q)^T v_earth``.
  This is the article's R of Eq. (1.1), ``dR/dt = R Omega_x`` with the body rate ``omega``;
  in quaternion form ``dq/dt = 1/2 q (x) (0, omega)``.
- Earth z points up. imufuse's simulator uses NWU (x north, y west, z up); these helpers do
  not care which horizontal axes are chosen as long as the frame is right-handed.
- Euler angles are (roll, pitch, yaw) in radians, aerospace ZYX sequence:
  ``R = Rz(yaw) Ry(pitch) Rx(roll)``; pitch is in [-pi/2, pi/2], roll and yaw in [-pi, pi].
- Angles are radians, angular rates rad/s.

Every function takes a single quaternion ``(4,)`` or a batch ``(N, 4)`` (more generally
``(..., 4)``) and broadcasts like numpy; vectors are ``(3,)`` or ``(..., 3)``. Results are
float64 arrays (scalar-valued results are 0-d arrays / numpy floats for a single input).
Shape errors raise ``ValueError`` naming the argument and the shape seen.
"""

import numpy as np

__all__ = [
    "quat_mul", "quat_conj", "quat_normalize", "quat_from_axis_angle", "quat_from_rotvec",
    "quat_to_rotvec", "quat_to_matrix", "matrix_to_quat", "quat_to_euler", "euler_to_quat",
    "quat_rotate", "quat_rotate_inv", "tilt_error", "heading_error", "quat_angle_error",
    "to_scipy", "from_scipy", "IDENTITY",
]

#: The identity quaternion [w, x, y, z].
IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])

# Below this rotation angle (rad) sin(a/2)/a and its inverse use their Taylor series; the
# first dropped term is below 1e-30 relative there.
_SMALL_ANGLE = 1e-4


#: how a quaternion array is given: the rotation from the sensor to the earth, or back
DIRECTIONS = ("sensor-to-earth", "earth-to-sensor")


def quat_rows(q, name):
    """q as an (N, 4) float64 array of [w, x, y, z] quaternions; ValueError naming ``name``
    (with a hint when a filter's whole state was given)."""
    q = np.asarray(q, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != 4:
        hint = (" (a filter's run() returns its whole state: run(..., outputs='q') returns "
                "its (N, 4) quaternions)" if q.ndim == 2 and q.shape[1] > 4 else "")
        raise ValueError(f"{name}: expected an (N, 4) array of [w, x, y, z] quaternions, "
                         f"got shape {q.shape}{hint}")
    return q


def _arr(a, name, last):
    """float64 array of shape (..., last), or ValueError naming ``name`` and its shape."""
    a = np.asarray(a, dtype=np.float64)
    if a.ndim == 0 or a.shape[-1] != last:
        raise ValueError(f"{name} must have shape ({last},) or (N, {last}); got {a.shape}")
    return a


def quat_mul(p, q):
    """Hamilton product ``p (x) q`` of quaternions ``[w, x, y, z]``.

    ``R(p (x) q) = R(p) R(q)``: ``q`` is applied first (in the frame already rotated by
    ``p``). Broadcasts: (4,) x (N, 4) is fine.
    """
    p = _arr(p, "p", 4)
    q = _arr(q, "q", 4)
    pw, px, py, pz = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    qw, qx, qy, qz = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    ], axis=-1)


def quat_conj(q):
    """Conjugate ``[w, -x, -y, -z]``; the inverse rotation for a unit quaternion."""
    q = _arr(q, "q", 4)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_normalize(q):
    """``q / |q|``. A zero (or non-finite-norm) quaternion raises ValueError."""
    q = _arr(q, "q", 4)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    if not np.all(np.isfinite(n)) or np.any(n == 0.0):
        raise ValueError("q has zero or non-finite norm; cannot normalise")
    return q / n


def quat_from_rotvec(rotvec):
    """Unit quaternion ``exp(rotvec / 2)`` of a rotation vector (axis * angle, rad).

    This is the exact integrator of a constant body rate: ``q_k = q_{k-1} (x)
    quat_from_rotvec(omega * dt)``. Exact at zero and accurate for tiny angles (series).
    """
    rv = _arr(rotvec, "rotvec", 3)
    a = np.linalg.norm(rv, axis=-1)
    a2 = a * a
    small = a < _SMALL_ANGLE
    safe = np.where(small, 1.0, a)
    # sin(a/2)/a = 1/2 - a^2/48 + a^4/3840 - ...
    k = np.where(small, 0.5 - a2 / 48.0 + a2 * a2 / 3840.0, np.sin(0.5 * safe) / safe)
    w = np.cos(0.5 * a)
    return np.concatenate([w[..., None], rv * k[..., None]], axis=-1)


def quat_from_axis_angle(axis, angle):
    """Unit quaternion of a rotation by ``angle`` (rad) about ``axis`` (any non-zero length).

    ``axis`` (3,) or (N, 3), ``angle`` scalar or (N,); right-hand rule.
    """
    axis = _arr(axis, "axis", 3)
    n = np.linalg.norm(axis, axis=-1, keepdims=True)
    if np.any(n == 0.0) or not np.all(np.isfinite(n)):
        raise ValueError("axis has zero or non-finite length")
    angle = np.asarray(angle, dtype=np.float64)
    half = 0.5 * angle
    return np.concatenate([np.cos(half)[..., None], (axis / n) * np.sin(half)[..., None]],
                          axis=-1)


def quat_to_rotvec(q):
    """Rotation vector (axis * angle, rad, angle in [0, pi]) of a unit quaternion.

    Inverse of :func:`quat_from_rotvec` up to the sign of ``q`` (``q`` and ``-q`` give the
    same result: the shorter rotation is returned).
    """
    q = _arr(q, "q", 4)
    s = np.where(q[..., 0] < 0.0, -1.0, 1.0)
    w = s * q[..., 0]
    v = s[..., None] * q[..., 1:]
    n = np.linalg.norm(v, axis=-1)
    angle = 2.0 * np.arctan2(n, w)
    # angle / n -> 2 / w for n -> 0 (w -> |q| = 1)
    small = n < 0.5 * _SMALL_ANGLE
    safe_n = np.where(small, 1.0, n)
    safe_w = np.where(small, w, 1.0)
    n2 = n * n
    k = np.where(small, (2.0 / safe_w) * (1.0 - n2 / (3.0 * safe_w * safe_w)), angle / safe_n)
    return v * k[..., None]


def quat_to_matrix(q):
    """Rotation matrix ``R`` (..., 3, 3) with ``v_earth = R v_body``.

    Uses ``2 / |q|^2`` so any non-zero quaternion gives a proper rotation.
    """
    q = _arr(q, "q", 4)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    s = 2.0 / (w * w + x * x + y * y + z * z)
    xx, yy, zz = s * x * x, s * y * y, s * z * z
    xy, xz, yz = s * x * y, s * x * z, s * y * z
    wx, wy, wz = s * w * x, s * w * y, s * w * z
    r = np.stack([
        1.0 - (yy + zz), xy - wz, xz + wy,
        xy + wz, 1.0 - (xx + zz), yz - wx,
        xz - wy, yz + wx, 1.0 - (xx + yy),
    ], axis=-1)
    return r.reshape(q.shape[:-1] + (3, 3))


def matrix_to_quat(R):
    """Unit quaternion (w >= 0) of a rotation matrix (..., 3, 3), ``v_earth = R v_body``.

    Shepperd's method: the largest of 4 w^2, 4 x^2, 4 y^2, 4 z^2 is taken from the diagonal
    and the others from off-diagonal sums, which keeps it accurate for every rotation.
    """
    R = np.asarray(R, dtype=np.float64)
    if R.ndim < 2 or R.shape[-2:] != (3, 3):
        raise ValueError(f"R must have shape (3, 3) or (N, 3, 3); got {R.shape}")
    r00, r01, r02 = R[..., 0, 0], R[..., 0, 1], R[..., 0, 2]
    r10, r11, r12 = R[..., 1, 0], R[..., 1, 1], R[..., 1, 2]
    r20, r21, r22 = R[..., 2, 0], R[..., 2, 1], R[..., 2, 2]
    # 4*w^2, 4*x^2, 4*y^2, 4*z^2 (each minus 1 common term folded in)
    d = np.stack([1.0 + r00 + r11 + r22, 1.0 + r00 - r11 - r22,
                  1.0 - r00 + r11 - r22, 1.0 - r00 - r11 + r22], axis=-1)
    i = np.argmax(d, axis=-1)
    t = np.sqrt(np.maximum(np.take_along_axis(d, i[..., None], axis=-1)[..., 0], 0.0))
    h = 0.5 / t
    # each case: [w, x, y, z] * 2t where the pivot component is t^2
    cand = np.stack([
        np.stack([t * t, r21 - r12, r02 - r20, r10 - r01], axis=-1),
        np.stack([r21 - r12, t * t, r01 + r10, r02 + r20], axis=-1),
        np.stack([r02 - r20, r01 + r10, t * t, r12 + r21], axis=-1),
        np.stack([r10 - r01, r02 + r20, r12 + r21, t * t], axis=-1),
    ], axis=-2)
    q = np.take_along_axis(cand, i[..., None, None], axis=-2)[..., 0, :] * h[..., None]
    q = np.where(q[..., :1] < 0.0, -q, q)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def quat_to_euler(q):
    """(roll, pitch, yaw) in rad, ZYX aerospace sequence, as (..., 3).

    ``R = Rz(yaw) Ry(pitch) Rx(roll)``. The asin argument for pitch is clamped to [-1, 1]
    (it can exceed it by rounding near +-90 deg); there roll and yaw are not unique.
    Scale invariant: ``q`` need not be exactly unit.
    """
    q = _arr(q, "q", 4)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    ww, xx, yy, zz = w * w, x * x, y * y, z * z
    n = ww + xx + yy + zz
    roll = np.arctan2(2.0 * (w * x + y * z), ww - xx - yy + zz)
    pitch = np.arcsin(np.clip(2.0 * (w * y - x * z) / n, -1.0, 1.0))
    yaw = np.arctan2(2.0 * (w * z + x * y), ww + xx - yy - zz)
    return np.stack([roll, pitch, yaw], axis=-1)


def euler_to_quat(euler):
    """Unit quaternion of (roll, pitch, yaw) in rad, ZYX: ``q = qz(yaw) (x) qy(pitch) (x) qx(roll)``.

    ``euler`` is (3,) or (N, 3) ordered [roll, pitch, yaw] like :func:`quat_to_euler`'s
    output.
    """
    e = _arr(euler, "euler", 3)
    hr, hp, hy = 0.5 * e[..., 0], 0.5 * e[..., 1], 0.5 * e[..., 2]
    cr, sr = np.cos(hr), np.sin(hr)
    cp, sp = np.cos(hp), np.sin(hp)
    cy, sy = np.cos(hy), np.sin(hy)
    return np.stack([
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    ], axis=-1)


def quat_rotate(q, v):
    """Body -> earth: ``R(q) v`` for unit ``q``; ``v`` (3,) or (N, 3), broadcasting with q."""
    q = _arr(q, "q", 4)
    v = _arr(v, "v", 3)
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def quat_rotate_inv(q, v):
    """Earth -> body: ``R(q)^T v`` for unit ``q`` (what a sensor at orientation q reads)."""
    return quat_rotate(quat_conj(q), v)


def _body_up(q):
    """Earth z seen in the body frame, ``R^T e_z`` (the third row of R), for any non-zero q."""
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    s = 2.0 / (w * w + x * x + y * y + z * z)
    return np.stack([s * (x * z - w * y), s * (y * z + w * x),
                     1.0 - s * (x * x + y * y)], axis=-1)


def tilt_error(q_est, q_true):
    """Attitude error ignoring yaw (rad, in [0, pi]).

    The angle between the earth z axis as seen in the body frame by the estimate and by the
    truth (``R_est^T e_z`` vs ``R_true^T e_z``): what an accelerometer-only observer could
    ever correct. Computed with atan2(|a x b|, a . b), accurate for small errors.
    """
    a = _body_up(_arr(q_est, "q_est", 4))
    b = _body_up(_arr(q_true, "q_true", 4))
    a, b = np.broadcast_arrays(a, b)
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


def heading_error(q_est, q_true):
    """Yaw difference ``yaw_est - yaw_true`` (ZYX yaw) wrapped to [-pi, pi], rad.

    Meaningless near pitch = +-90 deg, where yaw is not defined.
    """
    d = quat_to_euler(_arr(q_est, "q_est", 4))[..., 2] - \
        quat_to_euler(_arr(q_true, "q_true", 4))[..., 2]
    return np.arctan2(np.sin(d), np.cos(d))


def quat_angle_error(q_est, q_true):
    """Angle (rad, in [0, pi]) of the rotation taking ``q_true`` to ``q_est``.

    The full orientation error including yaw; invariant to the sign of either quaternion.
    """
    d = quat_mul(quat_conj(_arr(q_true, "q_true", 4)), _arr(q_est, "q_est", 4))
    return 2.0 * np.arctan2(np.linalg.norm(d[..., 1:], axis=-1), np.abs(d[..., 0]))


def to_scipy(q):
    """``[w, x, y, z]`` -> scalar-last ``[x, y, z, w]`` as used by
    ``scipy.spatial.transform.Rotation.from_quat``. Needs no scipy."""
    q = _arr(q, "q", 4)
    return np.concatenate([q[..., 1:], q[..., :1]], axis=-1)


def from_scipy(q_xyzw):
    """Scalar-last ``[x, y, z, w]`` (or any object with ``as_quat()``, e.g. a scipy
    ``Rotation``) -> ``[w, x, y, z]``. Needs no scipy."""
    if hasattr(q_xyzw, "as_quat"):
        q_xyzw = q_xyzw.as_quat()
    q = _arr(q_xyzw, "q_xyzw", 4)
    return np.concatenate([q[..., 3:], q[..., :3]], axis=-1)
