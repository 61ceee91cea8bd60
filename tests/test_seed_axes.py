"""Nair's sensor-axis mapping as a worked example of the Fusion suite's
axis alignment (imufuse_c.axes_apply): Nair's board (MAX21100 and
HMC5883L, datasheet frame with Z up) mapped to NED with

    gyroscope      (-y, -x, -z)   alignment "-Y-X-Z" (a rotation)
    accelerometer  ( y,  x,  z)   alignment "+Y+X+Z" (minus that rotation)
    magnetometer   (-y, -x, -z)   alignment "-Y-X-Z"

gives Nair's sign conventions: pitch up, roll right and yaw clockwise
positive. The accelerometer's mapping is the gyroscope's with the sign
flipped: Nair's NED accelerometer reads +1 g on D at rest (gravity, not
the specific force), which vertical_accel(convention="ned_seed") expects."""
import math

import numpy as np
import pytest

import imufuse.reference as reference
import imufuse_c
from imufuse.reference._fusion import alignment_is_rotation

GYR, ACC, MAG = "-Y-X-Z", "+Y+X+Z", "-Y-X-Z"
# the board: sensor x = -E (west when facing north), y = -N, z = -D (up);
# v_sensor = C v_body(NED)
C = np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
FIELD_NED = np.array([math.cos(math.radians(60)), 0.0, math.sin(math.radians(60))])  # dips down


def _rot(axis, angle):
    """NED body -> NED earth rotation matrix for a rotation about a body axis."""
    c, s = math.cos(angle), math.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R = np.eye(3)
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


def board(R, omega_body):
    """Raw sensor readings of the board at attitude R (body NED -> earth NED)
    turning at omega_body (rad/s, NED body axes): a specific-force
    accelerometer (+1 g up at rest), gyro, magnetometer."""
    f_body = R.T @ np.array([0.0, 0.0, -1.0])          # specific force at rest: up
    return C @ omega_body, C @ f_body, C @ (R.T @ FIELD_NED)


def mapped(R, omega_body):
    g, a, m = board(R, omega_body)
    return (imufuse_c.axes_apply(g[None], GYR)[0], imufuse_c.axes_apply(a[None], ACC)[0],
            imufuse_c.axes_apply(m[None], MAG)[0])


def angles(acc, mag):
    """Nair's angles from the mapped accelerometer and magnetometer (NED)."""
    roll = math.atan2(acc[1], acc[2])
    pitch = math.atan2(-acc[0], math.hypot(acc[1], acc[2]))
    # tilt-compensate the magnetometer, then yaw from north
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    mx = mag[0] * cp + mag[1] * sr * sp + mag[2] * cr * sp
    my = mag[1] * cr - mag[2] * sr
    return roll, pitch, math.atan2(-my, mx)


def test_the_mapping_is_a_rotation_and_a_sign():
    assert alignment_is_rotation(GYR) and alignment_is_rotation(MAG)
    assert not alignment_is_rotation(ACC)
    v = np.random.default_rng(0).normal(size=(20, 3))
    np.testing.assert_array_equal(imufuse_c.axes_apply(v, ACC), -imufuse_c.axes_apply(v, GYR))
    np.testing.assert_array_equal(reference.fusion.axes_apply(v, ACC), imufuse_c.axes_apply(v, ACC))


def test_level_at_rest():
    g, a, m = mapped(np.eye(3), np.zeros(3))
    np.testing.assert_allclose(a, [0.0, 0.0, 1.0], atol=1e-15)     # Nair: +1 g on D
    assert m[0] > 0 and abs(m[1]) < 1e-15                           # N points north: x max
    np.testing.assert_allclose(angles(a, m), 0.0, atol=1e-12)


@pytest.mark.parametrize("angle", [0.2, 0.7])
def test_pitch_up_roll_right_yaw_clockwise_are_positive(angle):
    # pitch up: about body E (y); roll right: about body N (x); yaw clockwise
    # seen from above: about body D (z)
    for axis, name in ((1, "pitch"), (0, "roll"), (2, "yaw")):
        omega = np.zeros(3)
        omega[axis] = 0.5
        g, a, m = mapped(_rot(axis, angle), omega)
        assert g[axis] == pytest.approx(0.5) and np.count_nonzero(np.abs(g) > 1e-12) == 1
        roll, pitch, yaw = angles(a, m)
        got = {"roll": roll, "pitch": pitch, "yaw": yaw}
        assert got[name] == pytest.approx(angle, abs=1e-12), name
        for other in set(got) - {name}:
            assert got[other] == pytest.approx(0.0, abs=1e-12)


def test_mapped_accelerometer_gives_zero_vertical_acceleration_at_rest():
    """With the NED attitude, Nair's vertical acceleration of the mapped
    accelerometer (convention "ned_seed") is zero at rest in any attitude."""
    from imufuse.rotations import matrix_to_quat
    rng = np.random.default_rng(1)
    for _ in range(20):
        R = _rot(2, rng.uniform(-3, 3)) @ _rot(1, rng.uniform(-1.4, 1.4)) @ _rot(0, rng.uniform(-3, 3))
        _, a, _ = mapped(R, np.zeros(3))
        q = matrix_to_quat(R)
        for conv, want in (("ned_seed", 0.0), ("ned", -2 * 980.0)):
            got = imufuse_c.vertical_accel(q[None], a[None], conv)[0]
            assert got == pytest.approx(want, abs=1e-9)
