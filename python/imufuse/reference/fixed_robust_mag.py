"""B4 of the fixed-point RobustAHRS: the magnetometer confined to heading, one function a
step, named as csrc/robust.c's: pure-Python twin of csrc/fixed/robust_q_mag.h, line for line.

k: B4's constants (a dict, imf_robust_ahrs_q_consts_t's members, "imu" RobustIMUQ's); x:
the filter, whose attributes are the state.
"""
from __future__ import annotations

from . import _cint as ci
from . import fixed_quat as fq
from .fixed_robust_ops import gain, half, lowpass, rotate16, turn_z, unit
from .fixed_robust_p8 import exponent_p8, narrow_p8, shift_p8, turn_z_p8, unit16_p8


def mag_test(k, mn, hn, zn, n, h, z):
    """robust_q_mag_test: the field matches the reference (n, h, z): norm within mag_norm
    n and dip within mag_dip (the sine of the dip difference: zn h - hn z, q30)."""
    dn = ci.sub_sat32(mn, n)
    tn = ci.scale32_s(n, k["knorm"], 15, 15)
    dd = zn * ci.qn_to_q15s(h, 30) - hn * ci.qn_to_q15s(z, 30)
    return dn < tn and ci.sub_sat32(0, dn) < tn and dd < k["kdip"] and -dd < k["kdip"]


def mag_field(p8, me):
    """robust_q_mag_field: B4's field me (q15 counts, earth frame): (its unit vector u, its
    norm mn = m . u in q15 counts, the horizontal direction ch or None where the field is
    vertical), or None for no usable reading."""
    if p8:
        # 8-bit profile: u from me's 15 leading bits w (exponent e; unit16_p8),
        # |m| = w . u 2^(e - 15); the horizontal direction from u's (unit16_p8: the half
        # angle of the heading below needs the norm of the 32-bit profile's too)
        e = exponent_p8(me)
        w = narrow_p8(me, e)
        u = unit16_p8(w)
        if u is None:
            return None                      # no usable reading: gyro and accelerometer only
        mn = shift_p8(ci.check32(w[0] * u[0] + w[1] * u[1] + w[2] * u[2]), 15 - e)
        return u, mn, unit16_p8([u[0], u[1], 0])
    u = unit(me)
    if u is None:
        return None                          # no usable reading: gyro and accelerometer only
    mn = 0
    for i in range(3):
        mn = ci.add_sat32(mn, fq.mul_hq_p32(me[i], u[i]))
    return u, mn, unit([me[0], me[1], 0])


def mag_match(k, x, mn, hn, zn):
    """robust_q_mag_match: the field (mn, hn, zn) tested against the reference, the first
    reading taken as it; True where it is used: matching for mag_hold."""
    if x.rn == 0:
        # first reading: it is the reference
        x.rn = x.cn = mn
        x.rh = x.ch = hn * 32768
        x.rz = x.cz = zn * 32768
        x.n_ok = k["n_hold"]
    match = mag_test(k, mn, hn, zn, x.rn, x.rh, x.rz)
    if not match:
        x.n_ok = 0
    elif x.n_ok < k["n_hold"]:
        x.n_ok += 1
    return match and x.n_ok >= k["n_hold"]


def mag_reference(k, x, mn, hn, zn):
    """robust_q_mag_reference: an undisturbed field (mn, hn, zn): the reference learnt from
    it, the candidate it."""
    kk = gain(k["imu"]["profile"] == 8, x.n, k["n_ref"], k["k_ref"])
    x.n_dist = 0
    x.n_cand = 0
    x.rn = ci.add_sat32(x.rn, ci.scale32_s(ci.sub_sat32(mn, x.rn), kk, 15, 15))
    x.rh = lowpass(x.rh, hn, kk)
    x.rz = lowpass(x.rz, zn, kk)
    x.cn = mn
    x.ch = hn * 32768
    x.cz = zn * 32768


def mag_candidate(k, x, mn, hn, zn):
    """robust_q_mag_candidate: disturbed (or not yet matching for mag_hold): no heading
    correction; a new field (mn, hn, zn) that stays the same for mag_new_time of motion
    becomes the reference."""
    if x.n_dist < 1073741824:
        x.n_dist += 1
    if mag_test(k, mn, hn, zn, x.cn, x.ch, x.cz):
        kr = k["imu"]["k_rest"]
        x.cn = ci.add_sat32(x.cn, ci.scale32_s(ci.sub_sat32(mn, x.cn), kr, 15, 15))
        x.ch = lowpass(x.ch, hn, kr)
        x.cz = lowpass(x.cz, zn, kr)
        if x.n_rest < k["imu"]["n_rest"] and x.n_cand < k["n_new"]:
            # only motion counts: at rest an attached magnet's field is steady too
            x.n_cand += 1
        if x.n_cand >= k["n_new"]:
            x.rn, x.rh, x.rz = x.cn, x.ch, x.cz
            x.n_cand = 0
    else:
        x.cn = mn
        x.ch = hn * 32768
        x.cz = zn * 32768
        x.n_cand = 0


def field_used(k, x, mn, hn, zn):
    """robust_q_field_used: B4, the disturbance detector. The field (mn, hn, zn) is used
    (True) when it has matched the reference for mag_hold, and the reference learns it;
    otherwise (disturbed) a new field that stays the same for mag_new_time of motion becomes
    the reference."""
    if mag_match(k, x, mn, hn, zn):
        mag_reference(k, x, mn, hn, zn)
        return True
    mag_candidate(k, x, mn, hn, zn)
    return False


def heading(k, x, ch):
    """robust_q_heading: the rotation about earth z that turns the horizontal field ch
    onto north (+x), (1 + cos, 0, 0, -sin) normalised, taken by the fraction k:
    (1 + k (f_w - 1), k f_z), normalised with c and q."""
    p8 = k["imu"]["profile"] == 8
    kk = gain(p8, x.n, k["n_mag"], k["k_mag"])
    if p8:
        # 8-bit profile: (1 + cos, -sin) / 2 normalised by unit3_p8 (within 1.2e-3: the
        # turn's gain); (0, 1) where it is 0, as half()
        f = fq.unit3_p8([(32768 + ch[0]) >> 1, -ch[1] >> 1, 0]) or [0, 32767]
    else:
        f = half(ch[0], -ch[1], 0)
    if p8:
        # 8-bit profile: (dw, dz) = z 2^(15 - kk.s) in q30, z = kk.m (f_w - 1, f_z) 2^-15
        # rounded; c and q turned, neither normalised here (the next update normalises c
        # and takes q = c (x) s again)
        z16 = [ci.rshr32((f[0] - 32768) * kk.m, 15), ci.rshr32(f[1] * kk.m, 15)]
        x.c[:] = turn_z_p8(x.c, z16, kk.s - 15)
        x.q[:] = turn_z_p8(x.q, z16, kk.s - 15)
    else:
        dz = [ci.scale32_s(f[0] - 32768, kk, 15, 30), ci.scale32_s(f[1], kk, 15, 30)]
        x.c[:] = turn_z(x.c, dz[0], dz[1])
        x.q[:] = turn_z(x.q, dz[0], dz[1])


def magnetometer(k, x, mag, rm):
    """robust_q_magnetometer: B4, heading from the magnetometer (counts, less the stored offset);
    rm: R(q), q15. The field's unit vector u, norm mn, the dip's cosine hn = u . ch and
    sine u_z."""
    if mag[0] == 0 and mag[1] == 0 and mag[2] == 0:
        return                               # no reading: gyro and accelerometer only
    # the reading less the offset in use, counts within +-32767, in the earth frame
    m = [ci.sat_q15s(ci.sub_sat32(mag[i], x.u[i])) for i in range(3)]
    me = rotate16(rm, 0, m)                  # q15 counts
    field = mag_field(k["imu"]["profile"] == 8, me)
    if field is None:
        return                               # no usable reading: gyro and accelerometer only
    u, mn, ch = field
    hn = ci.qn_to_q15s(u[0] * ch[0] + u[1] * ch[1], 30) if ch is not None else 0
    if not field_used(k, x, mn, hn, u[2]):
        return                               # B4: disturbed
    if ch is None:
        return                               # field vertical: no heading information
    heading(k, x, ch)
