"""Nair's claims, measured on simulated flights (imufuse.sim.flight).

Each study returns plain numbers; tests/test_vario_claims.py asserts them
and ``python research/vario_study.py`` prints the tables of docs/vario.md.

- lag: climb-rate response to a thermal entry (sink -1 m/s to +3 m/s over
  1 s), fused filter against the barometer-only two-state filter;
- turns: climb-rate error during banked turns with the earth-frame vertical
  acceleration (true attitude, Madgwick with and without the gate) against
  |a| - 1, and the attitude error the gate leaves;
- bias: convergence of the bias state to the simulated accelerometer bias;
- predict: predict="seed" against predict="model".
"""
import numpy as np

import imufuse_c

from imufuse.sim import flight as sf
from imufuse import vario as V
from imufuse.rotations import quat_rotate, tilt_error

G_CM = 100.0 * V.GRAVITY


def lag90(t, est, t0, lo, hi):
    """Seconds from t0 until est first reaches lo + 0.9 (hi - lo)."""
    idx = np.flatnonzero((t >= t0) & (est >= lo + 0.9 * (hi - lo)))
    return float(t[idx[0]] - t0) if idx.size else float("nan")


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


def _kf_true_attitude(fl, **kf):
    """The Kalman filter fed with the vertical acceleration of the true
    attitude: the filter alone, without attitude errors."""
    va = imufuse_c.vertical_accel(fl.q, fl.acc, scale=G_CM)
    a_b = V.decimate(va, fl.baro_idx)
    dt = np.diff(fl.baro_t, prepend=fl.baro_t[0] - 1.0 / fl.baro_rate)
    return imufuse_c.VarioKF(**kf).run(a_b, fl.baro_alt * 100.0, dt)


def study_lag(seed=3, baro_var_acc=(200.0, 2e3, 2e4, 2e5)):
    """Thermal entry at t = 30 s (climb -1 -> +3 m/s, cosine step of 1 s),
    no gusts. Returns rows (name, lag90 s, steady climb RMS error m/s,
    climb RMS error m/s over the flight). The truth itself takes 0.80 s to
    reach 90 % (the shape of the step)."""
    fl = sf.flight(sf.thermal_entry(climb=3.0, sink=-1.0, before=30.0, after=30.0),
                   seed=seed, turbulence=0.0)
    tb, tc = fl.baro_t, fl.climb[fl.baro_idx]
    steady = tb > 45.0
    after_start = tb > 10.0
    rows = [("truth", lag90(tb, tc, 30.0, -1.0, 3.0), 0.0, 0.0)]
    r = V.run(fl.gyr, fl.acc, fl.baro_column("baro_alt"), rate=fl.rate)
    rows.append(("VarioKF (Nair's defaults, MadgwickIMU)", lag90(tb, r.climb, 30.0, -1.0, 3.0),
                 _rms((r.climb - tc)[steady]), _rms((r.climb - tc)[after_start])))
    for va in baro_var_acc:
        b = V.baro_kf(fl.baro_alt * 100.0, 1.0 / fl.baro_rate, var_acc=va)[:, 1] / 100.0
        rows.append((f"barometer only, var_acc {va:g}", lag90(tb, b, 30.0, -1.0, 3.0),
                     _rms((b - tc)[steady]), _rms((b - tc)[after_start])))
    return rows


TURN_METHODS = (
    ("‖a‖ − 1", dict(vertical="norm")),
    ("MadgwickIMU beta 0.1", dict(filter_params=dict(beta=0.1))),
    ("MadgwickIMU beta 0.1, gate 0.6-1.4", dict(filter_params=dict(beta=0.1,
                                                                    acc_gate=(0.6, 1.4)))),
    ("MadgwickIMU beta 0.01", dict(filter_params=dict(beta=0.01))),
    ("MadgwickIMU beta 0.01, gate 0.6-1.4", dict(filter_params=dict(beta=0.01,
                                                                     acc_gate=(0.6, 1.4)))),
    ("MadgwickIMU beta 0.01, gate 0.9-1.1", dict(filter_params=dict(beta=0.01,
                                                                     acc_gate=(0.9, 1.1)))),
)


def study_turns(bank=40.0, seed=4):
    """A thermal worked in turns at `bank` degrees for 60 s between glides.
    Returns rows (method, climb RMS error in the turns m/s, max |error| m/s,
    mean tilt error of the attitude filter in the turns deg); the first row
    uses the true attitude."""
    fl = sf.flight(sf.turning_thermal(climb=2.0, bank=bank), seed=seed)
    tb, tc = fl.baro_t, fl.climb[fl.baro_idx]
    turns = (tb > 20.0) & (tb < 75.0)
    imu_turns = (fl.t > 20.0) & (fl.t < 75.0)
    X = _kf_true_attitude(fl)
    e = X[:, 1] / 100.0 - tc
    rows = [("true attitude", _rms(e[turns]), float(np.abs(e[turns]).max()), 0.0)]
    for name, kw in TURN_METHODS:
        r = V.run(fl.gyr, fl.acc, fl.baro_column("baro_alt"), rate=fl.rate, **kw)
        e = r.climb - tc
        tilt = float("nan") if kw.get("vertical") == "norm" else float(
            np.degrees(tilt_error(r.q[imu_turns], fl.q[imu_turns])).mean())
        rows.append((name, _rms(e[turns]), float(np.abs(e[turns]).max()), tilt))
    return rows


def study_bias(var_bias=(1.0, 0.1, 0.01, 0.001), seed=7, tol=0.05):
    """Straight glide, 120 s, MadgwickIMU beta 0.1. The truth is the vertical
    component of the simulated body-frame accelerometer bias (m/s^2).
    Returns rows (var_bias, time s after which |error| stays < tol m/s^2,
    mean error after 30 s, RMS error after 30 s, climb RMS error after 30 s)."""
    fl = sf.flight([sf.Phase(120.0, -1.0, 0.0)], seed=seed)
    tb = fl.baro_t
    btrue = (quat_rotate(fl.q, fl.acc_bias)[:, 2] * V.GRAVITY)[fl.baro_idx]
    late = tb > 30.0
    rows = []
    for vb in var_bias:
        r = V.run(fl.gyr, fl.acc, fl.baro_column("baro_alt"), rate=fl.rate,
                  kf_params=dict(var_bias=vb))
        e = r.bias - btrue
        bad = np.flatnonzero(np.abs(e) >= tol)
        t_in = float("inf") if bad.size and bad[-1] == len(tb) - 1 else (
            float(tb[bad[-1] + 1]) if bad.size else 0.0)
        rows.append((vb, t_in, float(e[late].mean()), _rms(e[late]),
                     _rms((r.climb - fl.climb[fl.baro_idx])[late])))
    return rows, float(btrue.mean())


def study_predict(seeds=range(5), baro_rates=(50.0, 10.0, 4.0)):
    """Random flights (120 s, thermals and turns), the true attitude, both
    predictions. Returns rows (barometer Hz, predict, climb RMS m/s,
    altitude RMS m), means over the seeds."""
    rows = []
    for hz in baro_rates:
        acc = {"seed": [], "model": []}
        for s in seeds:
            fl = sf.flight(duration=120.0, seed=s, baro_rate=hz)
            m = fl.baro_t > 10.0
            tc, ta = fl.climb[fl.baro_idx][m], fl.alt[fl.baro_idx][m]
            for p in acc:
                X = _kf_true_attitude(fl, predict=p)
                acc[p].append((_rms(X[m, 1] / 100.0 - tc), _rms(X[m, 0] / 100.0 - ta)))
        for p, v in acc.items():
            c, a = np.mean(v, axis=0)
            rows.append((hz, p, float(c), float(a)))
    return rows


def _table(head, rows, fmt):
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    out += ["| " + " | ".join(f.format(v) for f, v in zip(fmt, r)) + " |" for r in rows]
    return "\n".join(out)


def main():
    print("### Thermal entry: climb-rate lag (sink -1 to +3 m/s)\n")
    print(_table(("filter", "time to 90 %, s", "steady climb RMS, m/s",
                  "climb RMS, m/s"), study_lag(), ("{}", "{:.2f}", "{:.3f}", "{:.3f}")))
    for bank in (30.0, 40.0, 60.0):
        print(f"\n### Turns at {bank:.0f} deg bank ({1 / np.cos(np.radians(bank)):.2f} g)\n")
        print(_table(("vertical acceleration from", "climb RMS, m/s", "max error, m/s",
                      "tilt error, deg"), study_turns(bank),
                     ("{}", "{:.3f}", "{:.2f}", "{:.1f}")))
    rows, b = study_bias()
    print(f"\n### Bias convergence (true vertical bias {b:.3f} m/s²)\n")
    print(_table(("var_bias", "error within 0.05 m/s² after, s", "mean error, m/s²",
                  "RMS error, m/s²", "climb RMS, m/s"), rows,
                 ("{:g}", "{:.1f}", "{:+.4f}", "{:.4f}", "{:.4f}")))
    print("\n### predict=\"seed\" against predict=\"model\"\n")
    print(_table(("barometer, Hz", "predict", "climb RMS, m/s", "altitude RMS, m"),
                 study_predict(), ("{:g}", "{}", "{:.4f}", "{:.4f}")))


if __name__ == "__main__":
    main()
