"""The blocks of the fixed-point RobustIMU and RobustAHRS, one function each, named as
csrc/robust.c's: pure-Python twin of csrc/fixed/robust_q_blocks.h, line for line.

k: the constants (a dict, imf_robust_imu_q_consts_t's members); x: the filter, whose
attributes are the state (imf_robust_imu_q_state_t's members).
"""
from __future__ import annotations

from . import _cint as ci
from . import fixed_quat as fq
from .fixed_robust_ops import (counts, gain, half, integrate, lowpass3, matrix, mul_signed,
                               norm2, norm2_counts, qmul, recip, renorm, rotate, rotate16,
                               scale_of, unit)
from .fixed_robust_p8 import (exponent_p8, narrow_p8, qmul_p8, recip_p8, renorm_p8,
                              shift_p8)

Q29_ONE = 1 << 29


def acc_reading(x, acc, first):
    """robust_q_acc_reading: the accelerometer is a reading: not all zero (then gyro only, and
    no start without one), and after the first sample not beyond 100 times the gravity
    estimate (100 g: a shock or a hostile value)."""
    has_acc = not (acc[0] == 0 and acc[1] == 0 and acc[2] == 0)
    if has_acc and not first:
        f2 = norm2_counts(x.f)
        an2 = norm2(acc[0], acc[1], acc[2])
        if f2 < 429497 and an2 > f2 * 10000:
            return False
    return has_acc


def rest(k, x, gyr, acc, has_acc):
    """robust_q_rest: B1, rest detection from low-passes of gyro and accelerometer in the
    sensor frame, and the bias observed at rest (Eq. 3.1: b_k = b_{k-1}); (at rest, w2:
    |low-passed gyro|^2 in counts^2, B2's process noise)."""
    kk = gain(k["profile"] == 8, x.n, k["n_tau"], k["k_rest"])
    lowpass3(x.lw, gyr, kk)
    if has_acc:
        lowpass3(x.la, acc, kk)
    w2 = norm2_counts(x.lw)
    # at rest: the low-passed and the raw gyro below rest_gyr, the accelerometer within
    # rest_acc of its low-pass (each test only where the ones before hold)
    still = has_acc and w2 < k["rest_g2"] and norm2(gyr[0], gyr[1], gyr[2]) < k["rest_g2"]
    if still:
        # the accelerometer's difference from its low-pass, counts, within +-32767
        lc = [counts(v) for v in x.la]
        de = [ci.sat_q15s(acc[i] - lc[i]) for i in range(3)]
        still = ((norm2(de[0], de[1], de[2]) >> 2)
                 < ci.scale32_s(norm2(lc[0], lc[1], lc[2]) >> 2, k["kacc2"], 0, 0))
    if still:
        if x.n_rest < k["n_rest"]:
            x.n_rest += 1
    else:
        x.n_rest = 0
    if x.n_rest < k["n_rest"]:
        return False, w2
    lowpass3(x.b, gyr, k["kb_rest"])
    return True, w2


def strapdown(k, x, gyr):
    """robust_q_strapdown: s = s (x) exp(1/2 (w - b) dt), the series of the float filter;
    returns the new s's q15 snapshot (s is not changed again in the update)."""
    return integrate(k["profile"] == 8, x.s, gyr, x.b, k["kg"])


def gravity_start(k, x, ai):
    """robust_q_gravity_start: B5, gravity from the first sample (ai: the accelerometer in the
    inertial frame)."""
    x.f[:] = ai
    x.v[:] = [0, 0, 0]
    x.p[:] = [0, 0, k["pg0"]]


def gravity_update(k, x, ai, w2):
    """robust_q_gravity_update: B2, the Kalman filter of gravity in the inertial frame (ai: the
    accelerometer there, q15 counts; w2: B1's |low-passed gyro|^2)."""
    p8 = k["profile"] == 8
    eps = k["eps"]
    # predict: v' = (a - g) / tau_acc, g' = 0 (+ process noise growing with the rate)
    x.v[:] = [ci.add_sat32(x.v[i], ci.scale32_s(ci.sub_sat32(ai[i], x.f[i]), eps, 15, 15))
              for i in range(3)]
    # e^2 (1 + |w|^2 / rate_ref^2), the rate term capped at 1e4 e^2
    qg = ci.scale32_s(w2 >> 2, k["kq"], 0, 30) if k["kq"].m != 0 else 0
    if qg > k["qcap"]:
        qg = k["qcap"]
    qg = k["qg0"] + qg
    p = x.p
    pe = ci.scale32_s(p[2], eps, 30, 30)                # e pgg
    pvv = ci.add_sat32(ci.sub_sat32(p[0], ci.scale32_s(p[1], eps, 29, 30)),
                       ci.scale32_s(pe, eps, 30, 30))
    pvg = ci.sub_sat32(p[1], pe)
    pgg = ci.add_sat32(p[2], qg)
    # update with the pseudo-measurement v = 0 (noise 1): gains P / (pvv + 1)
    inv = (recip_p8 if p8 else recip)((0 if pvv < 0 else pvv >> 1) + Q29_ONE, 29)
    # the 8-bit profile's in q27: a shift of inv.s + 3 >= 17 (imf_mul_32x16's fast path on
    # AVR); kvs and kgs keep their 15 leading bits
    ng = 27 if p8 else 30
    kv = ci.scale32_s(pvv, inv, 30, ng)
    kg = ci.scale32_s(pvg, inv, 30, ng)
    kvs, sv = scale_of(kv, ng)
    kgs, sg = scale_of(kg, ng)
    for i in range(3):
        x.f[i] = ci.sub_sat32(x.f[i], mul_signed(x.v[i], kgs, sg, 15, 15))
        x.v[i] = ci.sub_sat32(x.v[i], mul_signed(x.v[i], kvs, sv, 15, 15))
    x.p[:] = [ci.sub_sat32(pvv, mul_signed(pvv, kvs, sv, 30, 30)),
              ci.sub_sat32(pvg, mul_signed(pvg, kvs, sv, 30, 30)),
              ci.sub_sat32(pgg, mul_signed(pvg, kgs, sg, 30, 30))]


def gravity(k, x, acc, sn, first, has_acc, w2):
    """robust_q_gravity: B2, the accelerometer in the inertial frame (sn: the new s's q15
    snapshot), gravity from it: B5 at the first sample, else the Kalman filter where there
    is a reading."""
    ai = rotate16(matrix(sn), 0, acc)                  # q15 counts
    if first:
        gravity_start(k, x, ai)
    elif has_acc:
        gravity_update(k, x, ai, w2)


def level_p8(x, sn, ss):
    """robust_q_level_p8: level in the 8-bit profile: f narrowed to int16 (its
    largest at most 2^14), rotated by R(c) and rounded to f's format, the unit vector of its
    15 leading bits (unit3_p8); c += d (x) c with d = r - 1 in 16-bit products. For u_z >= 0,
    r = (1 + u_z, u_y, -u_x) / 2, not normalised (the normalisation of c takes it: the same
    direction); below (turned over), r normalised with 1 + u_z from its product with
    1 - u_z (below). B3 takes 2 (r1, r2): (u_y, -u_x) for the first, the doubled r for the
    second. ss: c's q15 snapshot. Returns r."""
    f16 = narrow_p8(x.f, exponent_p8(x.f) + 1)
    g16 = [ci.sat_q15s(ci.rshr32(v, 15)) for v in rotate16(matrix(ss), 0, f16)]
    u = fq.unit3_p8(g16)
    d = [0, 0, 0, 0]
    r = [0, 0, 0]
    half_ = 0
    if u is not None:
        if u[2] >= 0:
            d = [u[2] - 32768, u[1], -u[0], 0]   # [-32768, -1] first
            r = [0, u[1], -u[0]]
            half_ = 1                            # d is twice r - 1
        else:
            # turned over (the first samples only: c takes the whole r): r = (1 + u_z, u_y,
            # -u_x) normalised, as the direction of its product with 1 - u_z, (u_x^2 +
            # u_y^2, u_y (1 - u_z), -u_x (1 - u_z)) in q30, narrowed to its 15 leading bits;
            # (0, 1, 0) where it is 0 (exactly upside down)
            w = 32768 - u[2]                     # 1 - u_z, (2^15, 2^16)
            ge = [u[0] * u[0] + u[1] * u[1], u[1] * w, -(u[0] * w)]
            r = fq.unit3_p8(narrow_p8(ge, exponent_p8(ge))) or [0, 32767, 0]
            d = [r[0] - 32768, r[1], r[2], 0]
            r = [r[0], ci.sat_q15s(2 * r[1]), ci.sat_q15s(2 * r[2])]
    t = qmul_p8(d, ss)
    x.c[:] = renorm_p8([ci.add_sat32(x.c[i], ci.rshr32(t[i], half_)) for i in range(4)])
    # |q|^2 - 1: c's and the snapshots' rounding
    x.q[:] = qmul_p8(fq.snapshot(x.c), sn)
    return r


def level_p32(x, ss):
    """robust_q_level_p32: level in the 32-bit profile: r = (1 + u_z, u_y,
    -u_x, 0) normalised by half(), c = r (x) c and q = c (x) s, each normalised; ss: c's q15
    snapshot. Returns r."""
    ge = rotate(matrix(ss), 0, x.f)
    u = unit(ge)
    if u is not None:
        # gravity straight down (upside down): the half turn about x
        r = half(u[2], u[1], -u[0])
    else:
        # no gravity estimate (a zero vector): no correction
        r = [32767, 0, 0]
    r.append(0)
    x.c[:] = renorm(qmul(r, x.c))
    x.q[:] = renorm(qmul(fq.snapshot(x.c), x.s))
    return r


def level(k, x, sn):
    """robust_q_level: B2, the inclination, the smallest rotation r that turns the
    gravity estimate onto earth z, (1 + u_z, u_y, -u_x, 0) normalised for the unit gravity u
    in the earth frame, taken into c, then q = c (x) s (sn: s's q15 snapshot). Returns r:
    what B3 takes."""
    ss = fq.snapshot(x.c)                       # c's q15 snapshot
    if k["profile"] == 8:
        return level_p8(x, sn, ss)
    return level_p32(x, ss)


def bias(k, x, at_rest, r, rq):
    """robust_q_bias: B3, the correction rate seen in the sensor frame is minus the bias
    error (Eq. 3.6, with Ki dt = 1 / tau_bias): b -= R(q)^T (2 r1, 2 r2, 0) / tau_bias, in
    motion after tau_acc. rq: None, or a list that takes the rotation matrix of q (B4's)."""
    p8 = k["profile"] == 8
    b3 = not at_rest and x.n >= k["n_acc"] and k["kbias"].m != 0
    m = None
    if b3 or rq is not None:
        m = matrix(fq.snapshot(x.q))   # the C computes the first two rows only for B3 alone
        if rq is not None:
            rq[:] = m
    if not b3:
        return
    # R^T (r1, r2, 0) in q30 (the error is twice that); the 8-bit profile's six products
    # inline (the same sums), the 32-bit profile's by rotate16
    if p8:
        e = [m[i] * r[1] + m[3 + i] * r[2] for i in range(3)]
    else:
        e = rotate16(m, 1, [r[1], r[2], 0])
    for i in range(3):
        if p8:
            # 8-bit profile: R^T 2 r in q15 (2 r is q15) times kbias, one 16x16 product
            kb = k["kbias"]
            x.b[i] = ci.sub_sat32(x.b[i], shift_p8(ci.sat_q15s(ci.rshr32(e[i], 15)) * kb.m,
                                                   kb.s))   # ci.scale16's value
            continue
        x.b[i] = ci.sub_sat32(x.b[i], ci.scale32_s(ci.add_sat32(e[i], e[i]), k["kbias"], 30, 15))


def output(k, x, gyr):
    """robust_q_output: the end of every update, the output predicted by the latency with
    the bias-corrected rate, then the clock of the start-up (saturating)."""
    if k["klat"].m != 0:
        integrate(k["profile"] == 8, x.q, gyr, x.b, k["klat"])
    if x.n < k["n_max"]:
        x.n += 1
