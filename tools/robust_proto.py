"""Prototype of the recommended AHRS (float64, plain Python) with ablation switches.

Private development tool: the shipped filter is csrc/robust.c and its twin
python/imufuse/reference/robust.py. This file exists to evaluate design choices on
the BROAD development trials (tools/robust_eval.py).
"""
import math


def qmul(a, b):
    a0, a1, a2, a3 = a
    b0, b1, b2, b3 = b
    return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
            a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
            a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0)


def qnorm(q):
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


def qrot(q, v):
    """R(q) v."""
    w, x, y, z = q
    vx, vy, vz = v
    # t = 2 (q_v x v)
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (vx + w * tx + (y * tz - z * ty),
            vy + w * ty + (z * tx - x * tz),
            vz + w * tz + (x * ty - y * tx))


def qrot_inv(q, v):
    return qrot((q[0], -q[1], -q[2], -q[3]), v)


DEG = math.pi / 180.0

DEFAULTS = dict(
    tau_acc=3.0,          # s, low-pass of the accelerometer in the inertial frame
    acc_stages=2,         # 1 or 2 first-order stages (each tau_acc/stages)
    tau_mag=10.0,         # s, heading correction time constant
    tau_bias=50.0,        # s, bias estimation time constant in motion (0: off)
    bias_max=2.0,         # deg/s, bound on the motion-estimated bias change
    tau_rest=0.5,         # s, low-pass for rest detection
    rest_gyr=2.0,         # deg/s
    rest_acc=0.05,        # g (relative to the mean magnitude)
    rest_time=1.5,        # s
    tau_bias_rest=3.0,    # s, bias low-pass at rest (0: rest bias off)
    mag_norm=0.1,         # relative
    mag_dip=10.0,         # deg
    tau_mag_ref=20.0,     # s, reference learning
    mag_new_time=20.0,    # s, a stable new field is accepted after this time
    mag_reject=True,
    tau_mlp=0.0, mag_hold=0.0,
    xi=0.0,               # damping of the second-order velocity filter (0: stages)
    order=2,
    kf=False, p0=-1e4, sv=1.0, T_v=1.0, sv_rest=1.0,
    w_ref=0.0,            # deg/s, rotation rate that halves the accelerometer time constant
    startup=True,         # running-mean start of the low-passes
)


class Proto:
    def __init__(self, dt, mag=True, **kw):
        p = dict(DEFAULTS)
        for k in kw:
            if k not in p:
                raise KeyError(k)
        p.update(kw)
        self.p = p
        self.dt = dt
        self.use_mag = mag
        self.qg = (1.0, 0.0, 0.0, 0.0)
        self.qc = (1.0, 0.0, 0.0, 0.0)
        self.f1 = [0.0, 0.0, 0.0]
        self.f2 = [0.0, 0.0, 0.0]
        self.b = [0.0, 0.0, 0.0]
        self.wl = [0.0, 0.0, 0.0]
        self.al = [0.0, 0.0, 0.0]
        self.t = 0.0          # elapsed time (saturating)
        self.t_rest = 0.0
        self.t_mag = 0.0      # time the mag reference has been learnt (saturating)
        self.mref = [0.0, 0.0, 0.0]  # norm, h, z (unit dip vector)
        self.mcand = [0.0, 0.0, 0.0]
        self.t_cand = 0.0
        self.rest = False
        self.dist = False
        self.t_ok = 0.0

    def gain(self, tau, t):
        dt = self.dt
        if not self.p["startup"]:
            return dt / (tau + dt)
        return dt / (min(t, tau) + dt)

    def update(self, g, a, m=None):
        p = self.p
        dt = self.dt
        # ---- rest detection (sensor frame low-passes)
        kr = self.gain(p["tau_rest"], self.t)
        for i in range(3):
            self.wl[i] += kr * (g[i] - self.wl[i])
            self.al[i] += kr * (a[i] - self.al[i])
        wn2 = self.wl[0] ** 2 + self.wl[1] ** 2 + self.wl[2] ** 2
        dx, dy, dz = a[0] - self.al[0], a[1] - self.al[1], a[2] - self.al[2]
        an2 = self.al[0] ** 2 + self.al[1] ** 2 + self.al[2] ** 2
        thg = p["rest_gyr"] * DEG
        gn2 = g[0] ** 2 + g[1] ** 2 + g[2] ** 2
        rest_now = wn2 < thg * thg and gn2 < thg * thg and dx * dx + dy * dy + dz * dz < p["rest_acc"] ** 2 * an2
        self.t_rest = self.t_rest + dt if rest_now else 0.0
        self.rest = self.t_rest >= p["rest_time"]
        if self.rest and p["tau_bias_rest"] > 0:
            kb = dt / (p["tau_bias_rest"] + dt)
            for i in range(3):
                self.b[i] += kb * (g[i] - self.b[i])
        # ---- strapdown integration with the bias-corrected rate
        wx, wy, wz = ((g[0] - self.b[0]) * dt, (g[1] - self.b[1]) * dt, (g[2] - self.b[2]) * dt)
        th2 = wx * wx + wy * wy + wz * wz
        c = 1.0 - th2 / 8.0
        s = 0.5 - th2 / 48.0
        self.qg = qnorm(qmul(self.qg, (c, s * wx, s * wy, s * wz)))
        # ---- accelerometer low-pass in the inertial frame
        aI = qrot(self.qg, a)
        ta = min(self.t, p["tau_acc"] / p["acc_stages"])
        if p["w_ref"] > 0:
            ta = ta / (1.0 + math.sqrt(wn2) / (p["w_ref"] * DEG))
        ka = dt / (ta + dt)
        if p["kf"]:
            if not hasattr(self, "gI"):
                self.gI = list(aI) if p["p0"] > 0 else [0.0, 0.0, 0.0]
                self.vI = [0.0, 0.0, 0.0]
                self.P = [0.0, 0.0, abs(p["p0"]) / p["tau_acc"] ** 3]   # vv, vg, gg
            P = self.P
            # predict
            for i in range(3):
                self.vI[i] += dt * (aI[i] - self.gI[i])
            wn = math.sqrt(wn2)
            rate_gain = (1.0 + (wn / (p["w_ref"] * DEG)) ** 2 if p["w_ref"] > 0 else 1.0)
            qg = (p["sv"] ** 2 * p["T_v"] / p["tau_acc"] ** 4) * rate_gain * dt
            pvv = P[0] - 2 * dt * P[1] + dt * dt * P[2]
            pvg = P[1] - dt * P[2]
            pgg = P[2] + qg
            S = pvv + (p["sv_rest"] if self.rest else p["sv"]) ** 2 * p["T_v"] / dt
            kv = pvv / S
            kg = pvg / S
            for i in range(3):
                y = self.vI[i]
                self.vI[i] -= kv * y
                self.gI[i] -= kg * y
            P[0] = pvv - kv * pvv
            P[1] = pvg - kv * pvg
            P[2] = pgg - kg * pvg
            f = self.gI
        elif p["xi"] > 0:
            # second-order: velocity state v (bounded), gravity g
            if not hasattr(self, "gI"):
                self.gI = list(aI)
                self.vI = [0.0, 0.0, 0.0]
            tt = min(self.t + dt, p["tau_acc"]) if p["startup"] else p["tau_acc"]
            w0 = 1.0 / tt
            k1 = 2.0 * p["xi"] * w0 * dt
            k2 = w0 * w0 * dt
            if p["order"] == 3:
                if not hasattr(self, "pI"):
                    self.pI = [0.0, 0.0, 0.0]
                # poles at -w0 (x3): s^3 + 3w0 s^2 + 3w0^2 s + w0^3
                for i in range(3):
                    self.pI[i] += dt * self.vI[i] - 3.0 * w0 * dt * self.pI[i]
                    self.vI[i] += dt * (aI[i] - self.gI[i]) - 3.0 * w0 * w0 * dt * self.pI[i]
                    self.gI[i] += w0 * w0 * w0 * dt * self.pI[i]
            else:
              for i in range(3):
                self.vI[i] += dt * (aI[i] - self.gI[i]) - k1 * self.vI[i]
                self.gI[i] += k2 * self.vI[i]
            f = self.gI
        elif not hasattr(self, "fs"):
            self.fs = [[0.0, 0.0, 0.0] for _ in range(p["acc_stages"])]
        src = aI
        for st in ([] if (p["xi"] > 0 or p["kf"]) else self.fs):
            for i in range(3):
                st[i] += ka * (src[i] - st[i])
            src = st
        if p["xi"] <= 0 and not p["kf"]:
            f = src
        # ---- inclination: rotate the filtered gravity onto earth z
        gE = qrot(self.qc, f)
        gn = math.sqrt(gE[0] ** 2 + gE[1] ** 2 + gE[2] ** 2)
        r = qnorm((gn + gE[2], gE[1], -gE[0], 0.0))
        self.qc = qnorm(qmul(r, self.qc))
        q = qnorm(qmul(self.qc, self.qg))
        # ---- motion bias estimation: earth-frame correction -> sensor frame
        if p["tau_bias"] > 0 and not self.rest and self.t >= p["tau_acc"]:
            ex, ey = 2.0 * r[1], 2.0 * r[2]
            eS = qrot_inv(q, (ex, ey, 0.0))
            lim = p["bias_max"] * DEG * dt / p["tau_bias"]
            for i in range(3):
                d = -eS[i] / p["tau_bias"]
                self.b[i] += max(-lim, min(lim, d))
        # ---- magnetometer: heading only
        if self.use_mag and m is not None:
            mE = qrot(q, m)
            mh = math.hypot(mE[0], mE[1])
            mn = math.sqrt(mh * mh + mE[2] ** 2)
            hn, zn = mh / mn, mE[2] / mn
            ref = self.mref
            if self.t_mag == 0.0:
                ref[:] = [mn, hn, zn]
                self.mcand[:] = [mn, hn, zn]
                self.mlp = [mn, hn, zn]
            kl = self.gain(p["tau_mlp"], self.t)
            self.mlp = [self.mlp[0] + kl * (mn - self.mlp[0]), self.mlp[1] + kl * (hn - self.mlp[1]),
                        self.mlp[2] + kl * (zn - self.mlp[2])]
            if p["tau_mlp"] > 0:
                mn, hn, zn = self.mlp
            ok_ref = (abs(mn - ref[0]) < p["mag_norm"] * ref[0]
                      and abs(zn * ref[1] - hn * ref[2]) < math.sin(p["mag_dip"] * DEG))
            if not p["mag_reject"]:
                ok_ref = True
            self.t_ok = self.t_ok + dt if ok_ref else 0.0
            ok_ref = ok_ref and (self.t_ok >= p["mag_hold"] or self.t_mag < p["tau_mag_ref"])
            self.dist = not ok_ref
            if ok_ref:
                kref = self.gain(p["tau_mag_ref"], self.t_mag)
                ref[0] += kref * (mn - ref[0])
                ref[1] += kref * (hn - ref[1])
                ref[2] += kref * (zn - ref[2])
                self.t_mag = min(self.t_mag + dt, p["tau_mag_ref"])
                self.t_cand = 0.0
                self.mcand[:] = [mn, hn, zn]
                km = self.gain(p["tau_mag"], self.t)
                # heading error: direction of the horizontal field vs earth x (north)
                if mh > 0:
                    cx, sy = mE[0] / mh, mE[1] / mh
                    # full correction quaternion about z: rotate (cx, sy) onto x
                    fw, fz = 1.0 + cx, -sy
                    fn = math.hypot(fw, fz)
                    if fn > 0:
                        fw, fz = fw / fn, fz / fn
                    else:
                        fw, fz = 0.0, 1.0
                    rz = qnorm((1.0 - km + km * fw, 0.0, 0.0, km * fz))
                    self.qc = qnorm(qmul(rz, self.qc))
            else:
                cand = self.mcand
                ok_c = (abs(mn - cand[0]) < p["mag_norm"] * cand[0]
                        and abs(zn * cand[1] - hn * cand[2]) < math.sin(p["mag_dip"] * DEG))
                if ok_c:
                    kc = dt / (1.0 + dt)
                    cand[0] += kc * (mn - cand[0])
                    cand[1] += kc * (hn - cand[1])
                    cand[2] += kc * (zn - cand[2])
                    self.t_cand += dt
                    if self.t_cand >= p["mag_new_time"]:
                        ref[:] = list(cand)
                        self.t_cand = 0.0
                else:
                    cand[:] = [mn, hn, zn]
                    self.t_cand = 0.0
        self.t = min(self.t + dt, 1e9)
        return qnorm(qmul(self.qc, self.qg))


def run(gyr, acc, mag=None, dt=1 / 285.714, **kw):
    import numpy as np
    f = Proto(dt, mag=mag is not None, **kw)
    n = len(gyr)
    out = np.empty((n, 4))
    G = gyr.tolist()
    A = acc.tolist()
    M = mag.tolist() if mag is not None else None
    for k in range(n):
        out[k] = f.update(G[k], A[k], M[k] if M is not None else None)
    return out
