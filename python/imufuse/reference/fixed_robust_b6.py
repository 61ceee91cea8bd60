"""B6 of the fixed-point RobustAHRS: the magnetometer's offset learnt while the sensor turns:
pure-Python twin of csrc/fixed/robust_q_b6.h, line for line (formats there and in
robust_q.h: h, o q26 of the field unit n0; P q30; gains q24; P H^T q29; the innovation's
variance q28; the normalised innovation and its mean q16).

k: RobustAHRSQ's constants (a dict, imf_robust_ahrs_q_consts_t's members); x: the filter,
whose attributes are the state.
"""
from __future__ import annotations

from . import _cint as ci
from . import fixed_quat as fq
from .fixed_robust_ops import matrix, mul_signed, norm2, recip, rotate16, scale_of

P0 = 1073741824            # the prior variance 1, q30
JUMP = 53687091            # the offset's variance added after an innovation beyond the gate
GATE = 1245184             # 19, q16
MEAN = 524288              # 8, q16
EW = 20972                 # 0.02 = 20972 2^-20
TRUST = 107374             # 0.01^2, q30
EARLY = 2684355            # the early use: the estimate's variance below 0.05^2, q30
NORM2 = 67109              # the norm through the stored offset moving by 0.001 (squared), q26
RESET2 = 2684355           # a switch of the offset in use beyond 0.05 of n0 (squared), q30

#: index of P[i][j] in P[21], the covariance's upper triangle by rows
PI = ((0, 1, 2, 3, 4, 5), (1, 6, 7, 8, 9, 10), (2, 7, 11, 12, 13, 14),
      (3, 8, 12, 15, 16, 17), (4, 9, 13, 16, 18, 19), (5, 10, 14, 17, 19, 20))


def invsqrt(n2):
    """robust_q6_invsqrt: the q-scale of 1 / sqrt(n2), n2 > 0."""
    y, sh = ci.invsqrt_u32(n2)
    m = (y >> 1) + (y & 1)
    if m >= 32768:
        m = 16384
        sh -= 1
    return ci.QScale(m, sh - 1)


def rel(v, inv):
    """robust_q6_rel: counts (within int16) times 1 / n0, q26."""
    return ci.scale32_s(ci.sat_q15s(v) * 32768, inv, 15, 26)


def start(x, c, n2):
    """robust_q6_start: n0 = |m - u|, h = R(s) (m - u) / n0, o = u / n0, the prior."""
    inv = invsqrt(n2)
    n0, _ = scale_of(ci.mul_32x16(n2 >> 1, inv.m, inv.s - 16), 15)
    x.m_n2 = min(n2, 2147483647)
    x.m_im, x.m_is = inv.m, inv.s
    x.m_nm, x.m_ns = n0.m, n0.s
    for k in range(3):
        x.hi[k] = ci.scale32_s(c[k], inv, 15, 26)
        x.hi[3 + k] = rel(x.u[k], inv)
    x.P[:] = [0] * 21
    for k in range(6):
        x.P[PI[k][k]] = P0
    x.m_ew = 65536
    x.m_d2 = 0
    x.mn = [67108864, 0, 67108864, 0]        # 1, 0, 1, 0 (q26)


def exponent(v):
    """robust_q6_exponent: e >= 0 with |v| >> e at most 32766 for every component."""
    mx = max(min(abs(a), 2147483647) for a in v)
    e = 0
    while mx > 32766:
        mx >>= 1
        e += 1
    return e


def axis(x, i, c, y, rr):
    """robust_q6_axis: the scalar update of axis i, measurement y (q26), noise rr (q28)."""
    ph = []
    for j in range(6):
        a = ci.rshr32(x.P[PI[j][3 + i]], 1)
        for k in range(3):
            a = ci.add_sat32(a, ci.mul_32x16(x.P[PI[j][k]], c[k], 16))
        ph.append(a)
    sv = ci.rshr32(ph[3 + i], 1)             # H P H^T, q28
    hx = x.hi[3 + i]                         # H x, q26
    for k in range(3):
        sv = ci.add_sat32(sv, ci.mul_32x16(ph[k], c[k], 16))
        hx = ci.add_sat32(hx, ci.mul_32x16(x.hi[k], c[k], 15))
    sv = ci.add_sat32(sv, rr) if sv > 0 else rr  # at least rr (P's rounding)
    nu = ci.sub_sat32(y, hx)
    ri = recip(sv, 0)
    nq, sign = scale_of(nu, 26)
    kk = []
    for j in range(6):
        kk.append(ci.mul_32x16(ph[j], ri.m, ri.s - 23))
        x.hi[j] = ci.add_sat32(x.hi[j], mul_signed(kk[j], nq, sign, 24, 26))
    # P -= P H^T K^T: P H^T narrowed to int16 with one exponent e, times K (q24)
    e = exponent(ph)
    p16 = [ci.rshr32(ph[j], e) for j in range(6)]
    for j in range(6):
        for k in range(j, 6):
            t = PI[j][k]
            x.P[t] = ci.sub_sat32(x.P[t], ci.mul_32x16(kk[k], p16[j], 23 - e))
    nn = nq.m * nq.m
    n = ri.s + 2 * nq.s - 44
    if nq.m == 0:
        x.m_d2 = 0
    elif n < 0:
        x.m_d2 = 2147483647
    else:
        x.m_d2 = ci.mul_32x16(nn, ri.m, min(n, 47))
    x.m_ew = ci.add_sat32(x.m_ew, ci.mul_32x16(ci.sub_sat32(x.m_d2, x.m_ew), EW, 20))


def update(k, x, i, c, y, w2):
    """robust_q6_update: predict, then the measurement y of axis i (c: column i of R(s)),
    its noise growing with the rate (w2 = |gyr|^2, counts^2)."""
    qo = (x.m_qo & 65535) + k["kqo"]
    x.m_qo = qo & 65535
    qo >>= 16
    for j in range(6):
        pb = ci.add_sat32(x.P[PI[j][j]], k["kqh"] if j < 3 else qo)
        if j >= 3 and x.m_d2 > GATE and pb < P0:
            pb = ci.add_sat32(pb, JUMP)
        x.P[PI[j][j]] = pb
    rr = 0
    lag = k["klag2"]
    if lag.m != 0:
        rr = min(ci.mul_32x16(w2 >> 1, lag.m, lag.s - 29), 268435456)
    axis(x, i, c, y, ci.add_sat32(k["knoise2"], rr))
    x.m_axis = 0 if i == 2 else i + 1


def k3(d, k):
    """robust_q6_k3: d times 3 k, saturated."""
    p = ci.mul_32x16(d, k.m, k.s)
    return ci.add_sat32(ci.add_sat32(p, p), p)


def norm_lp(w, o, v, c, k):
    """robust_q6_norm_lp (w + o: C's pointer): the norm of v - c (q26, through q12) into the
    low-pass w[o] and its squared deviation into the low-pass w[o + 1] (q26), the gain 3 k."""
    n2 = 0
    for j in range(3):
        a = ci.sat_q15s(ci.rshr32(ci.sub_sat32(v[j], c[j]), 14))
        n2 += a * a
    nrm = 0
    if n2 >= 64:
        r = invsqrt(n2)
        nrm = ci.mul_32x16(n2 >> 1, r.m, r.s - 15)
    d = ci.sub_sat32(nrm, w[o])
    w[o] = ci.add_sat32(w[o], k3(d, k))
    a = ci.sat_q15s(ci.rshr32(d, 13))
    w[o + 1] = ci.add_sat32(w[o + 1], k3(ci.sub_sat32(a * a, w[o + 1]), k))


def use(k, x):
    """robust_q6_use: the offset's largest variance; the offset in use u (counts): trusted
    and consistent, the stored one while the estimate agrees with it within mag_offset_min,
    else the estimate; consistent but not yet trusted, the estimate when its variance is
    below EARLY and the reading's norm says the stored offset, still in use, is wrong. A
    switch between the two beyond RESET2 starts B4's reference again."""
    inv = ci.QScale(x.m_im, x.m_is)
    n0 = ci.QScale(x.m_nm, x.m_ns)
    pb = max(0, x.P[15], x.P[18], x.P[20])
    x.m_var = pb
    if not x.m_ew < MEAN:
        return
    trust = pb < TRUST
    same = list(x.u) == list(x.so)           # the stored offset in use
    if not (trust or (pb < EARLY and same and x.n_dist == 0
                      and x.mn[1] > NORM2 and x.mn[3] < (x.mn[1] >> 2))):
        return
    o2 = 0
    for j in range(3):
        e = ci.qn_to_q15s(ci.sub_sat32(x.hi[3 + j], rel(x.so[j], inv)), 26)
        o2 += e * e
    if o2 < k["kmin2"] and not trust:
        return                               # early: only an estimate that differs
    if o2 < k["kmin2"]:
        x.u = list(x.so)
    else:
        x.u = [ci.sat_q15s(ci.scale32_s(x.hi[3 + j], n0, 26, 0)) for j in range(3)]
    # a switch between the stored offset and the estimate (o2 their difference) beyond RESET2
    if same != (o2 < k["kmin2"]) and o2 > RESET2:
        x.rn = 0                             # B4: a new reference from the next reading


def started(x):
    """robust_q6_started: the field unit's words within the ranges start() gives them."""
    return (x.m_n2 > 0 and 16384 <= x.m_im <= 32767 and 16 <= x.m_is <= 31
            and 16384 <= x.m_nm <= 32767 and -2 <= x.m_ns <= 12)


def offset(k, x, gyr, mag):
    """robust_q_offset: B6, one reading (mag; all zero: none) into the estimator, then the
    offset in use u."""
    i = 1 if x.m_axis == 1 else 2 if x.m_axis == 2 else 0
    if not k["learn"] or (mag[0] == 0 and mag[1] == 0 and mag[2] == 0):
        return
    if x.m_n2 != 0 and not started(x):
        x.m_n2 = 0                           # a unit out of its ranges: start again
    if x.m_n2 != 0:
        # the reading against the field unit: absurd readings are not used
        n2 = norm2(mag[0], mag[1], mag[2])
        if not ((n2 >> 6) <= x.m_n2 and n2 >= (x.m_n2 >> 6)):
            if x.m_bad < k["n_bad"]:
                x.m_bad += 1
            if x.m_bad >= k["n_bad"]:
                x.m_n2 = 0
                x.m_bad = 0
            return
        x.m_bad = 0
    r = matrix(fq.snapshot(x.s))             # R(s), sensor -> inertial frame
    if x.m_n2 == 0:
        m = [ci.sat_q15s(ci.sub_sat32(mag[j], x.u[j])) for j in range(3)]
        n2 = norm2(m[0], m[1], m[2])
        if n2 < 64:
            return                           # below 8 counts: no field to start from
        start(x, rotate16(r, 0, m), n2)
    else:
        # column i of R(s): the row of axis i in m = R^T h + o
        c = [r[3 * j + i] for j in range(3)]
        update(k, x, i, c, rel(mag[i], ci.QScale(x.m_im, x.m_is)),
               norm2(gyr[0], gyr[1], gyr[2]))
        if i == 2:
            # how well the offset in use and the estimate each explain the reading's norm
            # (relative to n0), with the axis cycle: every third sample, the gain 3 k_mag
            inv = ci.QScale(x.m_im, x.m_is)
            rm = [rel(mag[j], inv) for j in range(3)]
            ru = [rel(x.u[j], inv) for j in range(3)]
            norm_lp(x.mn, 0, rm, ru, k["k_mag"])
            norm_lp(x.mn, 2, rm, x.hi[3:6], k["k_mag"])
    use(k, x)
