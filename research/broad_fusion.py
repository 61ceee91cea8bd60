"""Fusion 1.2.3 (FusionAHRS) and Fusion 1.3 (FusionAHRS13, defaults and x-io's advanced
settings) on the seven BROAD development trials: the BROAD errors (imufuse.evaluation) in
degrees, each trial's RMS averaged over the trials. Prints the markdown table of
docs/fusion.md and the Fusion rows of the README's real-data table.

    python research/broad_fusion.py [--dir ../shared/data/broad] [--write]   # --write: the README block

Both in float32 (the C library's precision), from the identity through their start-up, at
each trial's rate (1.3: sample_rate = the trial's rate; 1.2.3: dt = 1 / rate), the
gyroscope in deg/s and the accelerometer in g, Fusion's NWU convention; with and without the
magnetometer (update / update_no_magnetometer). The same script, one parameter set for all
trials, causal, as research/broad_compare.py scores the other filters.
"""
import argparse
import os
import re

import numpy as np

import imufuse_c
from imufuse import evaluation
from imufuse.reference import _fusion13 as fusion13

from broad_compare import DEFAULT_DIR, trials

G = 9.81


def _fusion12(settings, offset=False):
    """settings: rate -> FusionAHRS's settings; offset: FusionOffset in front."""
    def run(d, rate, nine):
        f = imufuse_c.FusionAHRS(**settings(rate), dtype="float32")
        gyr, acc = np.degrees(d["gyr"]), d["acc"] / G
        if offset:
            gyr, _ = imufuse_c.FusionOffset(int(round(rate)), dtype="float32").run(gyr)
        return f.run(gyr, acc, d["mag"] if nine else None, dt=1.0 / rate)[:, :4]
    return run


def _fusion13(settings, bias=False):
    """bias: FusionBias (its defaults at the trial's rate) in front, as x-io's advanced example."""
    def run(d, rate, nine):
        f = imufuse_c.FusionAHRS13(**{**settings, "sample_rate": rate}, dtype="float32")
        gyr, acc = np.degrees(d["gyr"]), d["acc"] / G
        if bias:
            gyr, _ = imufuse_c.FusionBias(rate, dtype="float32").run(gyr)
        return f.run(gyr, acc, d["mag"] if nine else None)[:, :4]
    return run


def _advanced12(rate):
    """x-io's advanced settings in 1.2.3's terms: the 5 s timeout as a period in samples."""
    adv = fusion13.ADVANCED
    return dict(gain=adv["gain"], gyroscope_range=adv["gyroscope_range"],
                acceleration_rejection=adv["acceleration_rejection"],
                magnetic_rejection=adv["magnetic_rejection"],
                recovery_trigger_period=int(rate * adv["rejection_timeout"]))


ROWS = [
    ("FusionAHRS (1.2.3), defaults", _fusion12(lambda rate: {})),
    ("FusionAHRS (1.2.3), x-io's advanced settings", _fusion12(_advanced12)),
    ("FusionAHRS13 (1.3), defaults", _fusion13(dict(fusion13.DEFAULTS))),
    ("FusionAHRS13 (1.3), x-io's advanced settings", _fusion13(dict(fusion13.ADVANCED))),
    ("FusionAHRS (1.2.3), advanced, FusionOffset in front", _fusion12(_advanced12, True)),
    ("FusionAHRS13 (1.3), advanced, FusionBias in front", _fusion13(dict(fusion13.ADVANCED),
                                                                     True)),
]


def score(data, run, nine):
    ev = []
    for _, d in data:
        rate = float(d["rate"])
        q = run(d, rate, nine)
        ev.append(evaluation.evaluate(q.astype(float), d["quat_ref"], est_frame="NWU",
                                      ref_frame="ENU", movement=d["movement"]))
    return evaluation.mean_over_trials(ev)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--dir", default=os.environ.get("IMUFUSE_BROAD", DEFAULT_DIR))
    p.add_argument("--write", action="store_true")
    a = p.parse_args(argv)
    data = trials(a.dir)
    rate = float(data[0][1]["rate"])
    print("| filter | 6D tilt | 9D tilt | 9D heading | 9D total |\n|---|---:|---:|---:|---:|")
    readme = ["| filter | kind | settings | inclination | heading | total |",
              "|---|---|---|---:|---:|---:|"]
    for label, run in ROWS:
        six = score(data, run, False)
        nine = score(data, run, True)
        print(f"| {label} | {six['inclination']:.3f} | {nine['inclination']:.3f} | "
              f"{nine['heading']:.3f} | {nine['total']:.3f} |")
        name, settings = label.split(" ", 1)[0], label.split(", ", 1)[1]
        readme.append(f"| {name} | ahrs | {settings} | {nine['inclination']:.2f} | "
                      f"{nine['heading']:.2f} | {nine['total']:.2f} |")
    print(f"\n(trials at {rate:g} Hz)")
    if a.write:
        path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "README.md")
        text = open(path).read()
        new, n = re.subn(r"(<!-- real-data-fusion[^>]*-->\n).*?(<!-- end real-data-fusion -->)",
                         lambda m: m.group(1) + "\n".join(readme) + "\n" + m.group(2), text,
                         flags=re.S)
        if n != 1:
            raise SystemExit("README.md: no <!-- real-data-fusion --> block")
        open(path, "w").write(new)


if __name__ == "__main__":
    main()
