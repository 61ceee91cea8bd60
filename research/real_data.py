"""The real-data table of the README: every 3D filter on the BROAD
development trials (../shared/data/broad/*.npz), BROAD errors (imufuse.evaluation)
averaged over the trials, with the command line's defaults (init="first", or the
filter's own start for those that start from their first sample, RobustIMU/AHRS; each
trial's rate), with the published code's gains where they differ (--preset published),
and with the gains `imufuse tune` finds.

    python research/real_data.py [DIR] [--write]   # --write: refresh the README block
"""
import concurrent.futures as cf
import glob
import os
import re
import subprocess
import sys

from imufuse import io
from imufuse.catalogue import (entry, estimate, filter_names, make_filter, reference_class,
                               resolve_params)
from imufuse.session import effective_params
from imufuse.evaluation import evaluate, mean_over_trials

HERE = os.path.dirname(os.path.abspath(__file__))
# the grids of the tuned rows (parameters not named keep their defaults)
_PI = ["kp=0.1:10:9", "ki=0,0.01,0.05,0.2,0.5"]
TUNE = {"MadgwickIMU": ["beta=0.003:3:13"], "MadgwickAHRS": ["beta=0.003:3:13"],
        "MahonyIMU": _PI, "MahonyAHRS": _PI, "Mahony2D": _PI, "DCM": _PI,
        "KK": ["kp=0.0003:0.3:10"]}


def score(name, paths, over=None, preset=None):
    cls = reference_class(name)
    evs = []
    for p in paths:
        log = io.read_log(p)
        start = {} if getattr(cls, "own_start", None) else {"init": "first"}
        f = make_filter(name, "c", "float64", {**resolve_params(name, log.dt, over or {}, preset),
                                               **start})
        ins = (log.gyr, log.acc, log.mag) if cls.kind == "ahrs" else (log.gyr, log.acc)
        evs.append(evaluate(estimate(cls, f.run(*ins)).q, log.q_ref, ref_frame="ENU",
                            movement=log.movement))
    return mean_over_trials(evs)


def tuned(name, paths, metric):
    grids = [a for g in TUNE[name] for a in ("--grid", g)]
    r = subprocess.run([sys.executable, "-m", "imufuse", "tune", *paths, "-f", name, *grids,
                        "--refine", "1", "--metric", metric, "--quiet"],
                       capture_output=True, text=True, check=True)
    best = re.search(r"^best: (.*) \(", r.stdout, re.M).group(1)
    return {k: float(v) for k, v in (kv.split("=") for kv in best.split(", "))}


def table(paths):
    names = filter_names({"imu", "ahrs"})
    rows = []
    with cf.ThreadPoolExecutor() as ex:
        base = dict(zip(names, ex.map(lambda n: score(n, paths), names)))
    for n in names:
        cls = reference_class(n)
        metric = "total" if cls.kind == "ahrs" else "inclination"
        d = effective_params(n, resolve_params(n, 0.01))
        shown = {k: v for k, v in d.items() if isinstance(v, float) and k != "dt"
                 and not (k == "acc_1g" and d.get("acc_gate") is None)}   # no effect then
        gains = ("defaults" if len(shown) > 4 else
                 ", ".join(f"{k}={v:g}" for k, v in shown.items()) or "-")
        rows.append((n, cls.kind, gains, base[n]))
        pub = entry(n).presets.get("published")
        if pub is not None and effective_params(n, resolve_params(n, 0.01, preset="published")) != d:
            rows.append((n, cls.kind, ", ".join(f"{k}={v:g}" for k, v in pub.items())
                         + " (published)", score(n, paths, preset="published")))
        if n in TUNE:
            best = tuned(n, paths, metric)
            rows.append((n, cls.kind, ", ".join(f"{k}={v:.3g}" for k, v in best.items())
                         + " (tuned)", score(n, paths, best)))
    out = ["| filter | kind | gains | inclination | heading | total |", "|---|---|---|---:|---:|---:|"]
    for n, kind, g, s in rows:
        h = f"{s['heading']:.2f}" if kind == "ahrs" else "-"
        t = f"{s['total']:.2f}" if kind == "ahrs" else "-"
        out.append(f"| {n} | {kind} | {g} | {s['inclination']:.2f} | {h} | {t} |")
    return "\n".join(out)


def main(argv):
    if "-h" in argv or "--help" in argv:
        print(__doc__)
        return
    args = [a for a in argv if not a.startswith("--")]
    d = args[0] if args else os.path.join(HERE, "..", "..", "shared", "data", "broad")
    paths = sorted(glob.glob(os.path.join(d, "*.npz")))
    if not paths:
        raise SystemExit(f"no BROAD trials (*.npz) in {d}")
    t = table(paths)
    print(t)
    if "--write" in argv:
        readme = os.path.join(HERE, "..", "README.md")
        text = open(readme).read()
        new, n = re.subn(r"(<!-- real-data[^>]*-->\n).*?(<!-- end real-data -->)",
                         lambda m: m.group(1) + t + "\n" + m.group(2), text, flags=re.S)
        if n != 1:
            raise SystemExit("README.md: no <!-- real-data --> block")
        open(readme, "w").write(new)


if __name__ == "__main__":
    main(sys.argv[1:])
