"""Planted mistakes ("mutants") across the C, the twins, the bindings and the command line, and
whether the test suite finds each one.

    python tools/mutants.py [--only ID,...] [--list]

Each mutant is one textual edit of one file, the kind of slip a change makes: an operator
flipped, an off-by-one, a dropped normalisation, a skipped validation. For each, the script
applies the edit in the checkout, rebuilds the compiled module when the edit is in a binding
(.pxi, or tools/bindgen.py which generates them), runs the tests that cover the edited code
(``-x``, stopping at the first failure), restores the file and records whether the suite
failed ("killed") or passed ("survived").
C mutants are found by the tests that compile csrc/ themselves (validate --csrc, the fixed-point
driver), so the compiled module is not rebuilt for them. The table goes to stdout (Markdown).

Run it on a clean checkout with the package installed editable (pip install -e . without
build isolation): it edits files in place and restores them, also on Ctrl-C.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from typing import List, Tuple

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@dataclass(frozen=True)
class Mutant:
    id: str
    path: str
    old: str
    new: str
    tests: Tuple[str, ...]
    what: str


C_BITEXACT = ("tests/test_firmware.py::test_csrc_is_bit_exact",)
FIXED_C = ("tests/test_fixed_bitexact.py::test_c_driver_equals_reference",)
TWINS = ("tests/test_bitexact.py::test_run_matches_reference",)

MUTANTS: List[Mutant] = [
    # ---- C (csrc/)
    Mutant("c-madgwick-sign", "csrc/madgwick.c",
           "two_q0 * ay - four_q1\n", "two_q0 * ay + four_q1\n", C_BITEXACT,
           "Madgwick gradient: a term's sign flipped"),
    Mutant("c-mahony-integral", "csrc/mahony.c",
           "x->ix += set->two_ki * ex * set->dt;", "x->ix -= set->two_ki * ex * set->dt;",
           C_BITEXACT, "Mahony integral term accumulates the wrong way"),
    Mutant("c-mahony-kp", "csrc/mahony.c", "self->set.two_kp = IMF_R(2.0) * s->kp;",
           "self->set.two_kp = s->kp;", C_BITEXACT, "twoKp without its factor 2"),
    Mutant("c-kalman1d-pred", "csrc/filters_1d.c",
           "theta_pred = self->x.theta + rate * self->dt;",
           "theta_pred = self->x.theta - rate * self->dt;", C_BITEXACT,
           "Kalman1D prediction integrates the rate backwards"),
    Mutant("c-complementary-alpha", "csrc/filters_1d.c",
           "theta = self->alpha * (self->x.theta + rate * self->dt) + self->one_minus_alpha * angle;",
           "theta = self->alpha * (self->x.theta + rate * self->dt) + self->alpha * angle;",
           C_BITEXACT, "complementary filter: alpha where 1 - alpha belongs"),
    Mutant("c-dcm-orth", "csrc/dcm.c", "dr = IMF_R(0.5) * (x0 * y0 + x1 * y1 + x2 * y2);",
           "dr = IMF_R(0.25) * (x0 * y0 + x1 * y1 + x2 * y2);", C_BITEXACT,
           "DCM re-orthogonalisation error shared by a quarter, not a half"),
    Mutant("c-dcm-taylor", "csrc/dcm.c",
           "sx = IMF_R(0.5) * (IMF_R(3.0) - (out.r00 * out.r00 + out.r01 * out.r01 + out.r02 * out.r02));",
           "sx = IMF_R(1.0);", C_BITEXACT, "DCM: a row's Taylor normalisation dropped"),
    Mutant("c-multiwii-window", "csrc/multiwii.c", "lo = (IMF_R(1.0) - window) * acc_1g;",
           "lo = (IMF_R(1.0) - window - window) * acc_1g;", C_BITEXACT,
           "MultiWii accelerometer window too wide at the bottom"),
    Mutant("c-kk-roll", "csrc/kk.c", "roll = roll + self->kp * (ay / norm - self->x.roll);",
           "roll = roll + self->kp * (ay / norm + self->x.roll);", C_BITEXACT,
           "KK roll correction sign"),
    Mutant("c-qrotate-sign", "csrc/imf_math.h",
           "o[1] = vy + w * ty + (z * tx - x * tz);", "o[1] = vy - w * ty + (z * tx - x * tz);",
           C_BITEXACT, "the shared quaternion rotation (imf_qrotate): a sign flipped"),
    Mutant("c-robust-rest-gain", "csrc/robust.c",
           "set->k_rest = dt / (set->s.tau_rest + dt);", "set->k_rest = dt / set->s.tau_rest;",
           C_BITEXACT, "Robust: the rest low-pass gain off by its + dt"),
    Mutant("c-robust-b6-axis", "csrc/robust_mag.h",
           "x->m_axis = i == 2u ? IMF_R(0.0) : x->m_axis + IMF_R(1.0);",
           "x->m_axis = i == 1u ? IMF_R(0.0) : x->m_axis + IMF_R(1.0);",
           C_BITEXACT, "Robust B6: the z axis of the magnetometer never updates the offset"),
    Mutant("c-robust-b6-trust", "csrc/robust_mag.h",
           "if (x->m_std < ROBUST_MAG_TRUST && x->m_ew < ROBUST_MAG_MEAN) {",
           "if (x->m_std < ROBUST_MAG_TRUST || x->m_ew < ROBUST_MAG_MEAN) {",
           C_BITEXACT, "Robust B6: an untrusted offset estimate is used"),
    Mutant("c-robust-rest-window", "csrc/robust_blocks.h",
           "set->rest_gyr2 + set->bias_var0 * (x->bu * x->bu);",
           "set->rest_gyr2 + set->bias_var0 * x->bu;",
           C_BITEXACT, "Robust B1: the rest window widened by bu, not bu^2"),
    Mutant("c-robust-bias-clip", "csrc/robust_blocks.h",
           "} else if (b[i] < -m) {", "} else if (b[i] < m) {",
           C_BITEXACT, "Robust B1/B3: every bias below the range's top clipped to its bottom"),
    Mutant("c-robust-bu-rest", "csrc/robust_blocks.h",
           "x->bu = x->bu - kb * x->bu;", "x->bu = x->bu - set->kb_rest * x->bu;",
           C_BITEXACT, "Robust B1: the bias's unknown part falls with the slow gain"),
    Mutant("c-robust-b2-bias-term", "csrc/robust_blocks.h",
           "rr = rr + set->bias_w2 * (ub * ub);", "rr = rr + set->bias_w2 * ub;",
           C_BITEXACT, "Robust B2: the unknown bias's rate term not squared"),
    Mutant("c-fusion-ramp", "csrc/fusion_ahrs.c",
           "x->ramped_gain = x->ramped_gain - set->ramped_gain_step * dt;",
           "x->ramped_gain = x->ramped_gain - set->ramped_gain_step;",
           ("tests/test_fusion.py::test_fusion_ahrs_on_mcu",),
           "Fusion start-up gain ramp ignores dt"),
    Mutant("c-vario-cov", "csrc/vario.c",
           "x->pzz = a00 + dt * a01 - h * a02 + IMF_R(0.25) * dt4 * set->var_acc;",
           "x->pzz = a00 + dt * a01 - h * a02 + IMF_R(0.5) * dt4 * set->var_acc;",
           ("tests/test_mcu_filters.py::test_state_bits", "-k", "VarioKF"),
           "variometer covariance prediction: dt^4/4 as dt^4/2"),
    Mutant("c-fixed-robust-2eps", "csrc/fixed/robust_q_blocks.h",
           "imf_scale32_s(x->p[1], k->eps, 29, 30)", "imf_scale32_s(x->p[1], k->eps, 30, 29)",
           FIXED_C, "RobustIMUQ B2: 2 e pvg taken as e pvg / 2 (a q29 read the wrong way)"),
    Mutant("c-fixed-robust-down", "csrc/fixed/robust_q_ops.h",
           "        r[0] = 0;\n        r[1] = 32767;", "        r[0] = 32767;\n        r[1] = 0;",
           ("tests/test_fixed_bitexact.py::test_c_driver_exact_axis_readings",),
           "RobustIMUQ: gravity straight down left uncorrected (no half turn)"),
    Mutant("c-fixed-robust-heading-sign", "csrc/fixed/robust_q_mag.h",
           "robust_q_half(ch[0], (int16_t)-ch[1], 0, f);", "robust_q_half(ch[0], ch[1], 0, f);",
           FIXED_C, "RobustAHRSQ B4: the heading correction turns away from north"),
    Mutant("c-fixed-robust-candidate-at-rest", "csrc/fixed/robust_q_mag.h",
           "if (x->n_rest < k->imu.n_rest && xm->n_cand < k->n_new) {",
           "if (xm->n_cand < k->n_new) {",
           FIXED_C, "RobustAHRSQ B4: a steady field at rest (an attached magnet) counts towards "
           "a new reference"),
    Mutant("c-fixed-robust-dip", "csrc/fixed/robust_q_mag.h",
           "imf_mul16(zn, imf_qn_to_q15s(h, 30)) - imf_mul16(hn, imf_qn_to_q15s(z, 30));",
           "imf_mul16(zn, imf_qn_to_q15s(h, 30)) + imf_mul16(hn, imf_qn_to_q15s(z, 30));",
           FIXED_C, "RobustAHRSQ B4: the dip test takes the sine of the sum of the dips"),
    Mutant("c-fixed-robust-renorm", "csrc/fixed/robust_q_ops.h",
           "q[i] = imf_sub_sat32(q[i], imf_q_mul_hq_p32(imf_rshr32(d, 1), qs[i]));",
           "q[i] = imf_add_sat32(q[i], imf_q_mul_hq_p32(imf_rshr32(d, 1), qs[i]));",
           FIXED_C, "RobustIMUQ: the first-order renormalisation pushes the norm away from 1"),
    Mutant("c-fixed-mahony-shift", "csrc/fixed/mahony_q.c",
           "imf_rshr32(x->i[i], 8));", "imf_rshr32(x->i[i], 7));", FIXED_C,
           "MahonyIMUQ integral term scaled by 2 (off-by-one shift)"),
    Mutant("c-fixed-saturation", "csrc/fixed/imf_fixed.h",
           "    if (n == 8 && x <= IMF_INT32_MAX - 128) {",
           "    if (n == 8 && x <= IMF_INT32_MAX - 127) {", ("tests/test_fixed_core_mcu.py",),
           "fixed point (AVR code path): rounding shift's overflow guard off by one"),
    # ---- the twins (python/imufuse/reference)
    Mutant("py-robust-b6-lag", "python/imufuse/reference/robust_mag.py",
           "        rr = self.mag_noise2 + rr\n", "        rr = self.mag_noise2\n",
           TWINS, "Robust twin B6: the rate term of the magnetometer noise dropped"),
    Mutant("py-robust-bias-gain", "python/imufuse/reference/robust_blocks.py",
           "tau = tm if tm > tau0 else tau0", "tau = tm if tm < tau0 else tau0",
           TWINS, "Robust twin B3: the running mean's time constant capped instead of floored"),
    Mutant("py-robust-set-bias", "python/imufuse/reference/robust_blocks.py",
           "        self.x.bu = R(0.0)\n", "        pass\n",
           ("tests/test_robust_bias.py",), "Robust twin: a seeded bias still counted unknown"),
    Mutant("py-madgwick-beta", "python/imufuse/reference/madgwick.py",
           "        return [dq[0] - self.beta * s[0],", "        return [dq[0] + self.beta * s[0],",
           TWINS, "twin: Madgwick correction sign on q0"),
    Mutant("py-mahony-ki", "python/imufuse/reference/mahony.py",
           "            ix = ix + self.two_ki * ex * self.dt",
           "            ix = ix + self.two_ki * ex", TWINS,
           "twin: Mahony integral without dt"),
    Mutant("py-kalman-gain", "python/imufuse/reference/filters_1d.py",
           "        self.one_minus_k0 = R(1.0) - self.k0\n        self.theta = R(0.0)",
           "        self.one_minus_k0 = R(1.0) + self.k0\n        self.theta = R(0.0)",
           TWINS, "twin: Kalman1D 1 - k0"),
    Mutant("py-skipped-count", "python/imufuse/reference/_base.py",
           "        self.skipped = (self.skipped + 1) & U32", "        self.skipped = self.skipped & U32",
           TWINS, "twin: a rejected sample not counted"),
    Mutant("py-fusion-ramp", "python/imufuse/reference/fusion.py",
           "            self.ramped_gain = self.ramped_gain - self.ramped_gain_step * dt",
           "            self.ramped_gain = self.ramped_gain - self.ramped_gain_step",
           ("tests/test_fusion.py",), "twin: Fusion gain ramp ignores dt"),
    Mutant("py-vario-cov", "python/imufuse/reference/vario.py",
           "        pzz = a00 + dt * a01 - h * a02 + R(0.25) * dt4 * self.var_acc",
           "        pzz = a00 + dt * a01 - h * a02 + R(0.5) * dt4 * self.var_acc",
           ("tests/test_vario.py::test_run_matches_reference",), "twin: variometer covariance"),
    Mutant("py-fixed-mahony-shift", "python/imufuse/reference/fixed_mahony.py",
           "ci.rshr32(self.i[i], 8))", "ci.rshr32(self.i[i], 7))",
           ("tests/test_fixed_bitexact.py::test_compiled_equals_reference",),
           "twin: MahonyIMUQ integral shift off by one"),
    # ---- the bindings (imufuse_c/*.pxi; rebuilt)
    Mutant("pxi-load-dtype", "imufuse_c/_base.pxi",
           "    if t == cnp.NPY_DOUBLE:\n        return <imf_real>(<const double *>base)[i]",
           "    if t != cnp.NPY_DOUBLE:\n        return <imf_real>(<const double *>base)[i]",
           ("tests/test_wrapper_paths.py::test_update_rows_of_any_form_agree",),
           "binding: the fast row path reads float64 rows as float32 and back"),
    Mutant("pxi-row3-index", "imufuse_c/_base.pxi",
           "    out[2] = _load(p, t, 2)", "    out[2] = _load(p, t, 1)",
           ("tests/test_wrapper_paths.py::test_update_rows_of_any_form_agree",),
           "binding: the fast row path reads z from y"),
    Mutant("bindgen-1d-order", "tools/bindgen.py",
           '2: ("_Filter1D", "imf_real rate, imf_real angle", "rate, angle"),',
           '2: ("_Filter1D", "imf_real rate, imf_real angle", "angle, rate"),',
           TWINS, "generated binding: a single-axis filter's update gets angle and rate swapped"),
    Mutant("pxi-skipped", "imufuse_c/_base.pxi",
           "        if not imf_finite3(g[0], g[1], g[2]):\n            self._skipped[0] += 1",
           "        if not imf_finite3(g[0], g[1], g[2]):\n            self._skipped[0] += 0",
           ("tests/test_time_init.py::test_first_c_equals_reference",),
           "binding: init='first' does not count a non-finite gyroscope sample"),
    # ---- the command line, the session, reading and scoring (Python)
    Mutant("session-frame", "python/imufuse/session.py",
           '    return q if frame == "NWU" else from_enu(to_enu(q, "NWU"), frame)',
           '    return q if frame == "NWU" else to_enu(q, "NWU")',
           ("tests/test_reallogs.py::test_run_frame_option_converts_output",),
           "session: --frame NED written as ENU"),
    Mutant("session-skip", "python/imufuse/session.py",
           "            late = log.t >= log.t[0] + options.skip",
           "            late = log.t >= log.t[0]",
           ("tests/test_cli_hostile.py::test_skip_leaves_the_start_out_of_the_errors",),
           "session: --skip ignored"),
    Mutant("io-acc-unit", "python/imufuse/io/log.py",
           'ACC_UNITS = {"g": 1.0, "m/s2": 1.0 / GRAVITY, "m/s^2": 1.0 / GRAVITY}',
           'ACC_UNITS = {"g": 1.0, "m/s2": 1.0 / GRAVITY, "m/s^2": 1.0}',
           ("tests/test_journeys.py", "tests/test_broad_hdf5.py", "tests/test_reallogs.py"),
           "io: m/s^2 from a header not converted to g"),
    Mutant("plausible-gyro", "python/imufuse/plausible.py",
           "MAX_GYRO_RAD_S = 35.0", "MAX_GYRO_RAD_S = 350.0",
           ("tests/test_plausible.py::test_the_gyro_limit_is_that_of_mems_parts",),
           "plausibility: deg/s read as rad/s no longer noticed"),
    Mutant("tune-order", "python/imufuse/tune.py",
           "        return sorted(good, key=lambda p: self.results[p][0])",
           "        return sorted(good, key=lambda p: -self.results[p][0])",
           ("tests/test_journeys.py", "tests/test_plausible.py", "tests/test_tune.py"),
           "tune: the worst set reported as the best"),
    Mutant("preset-ignored", "python/imufuse/catalogue.py",
           "    params = dict(e.defaults if preset is None else e.presets[preset])",
           "    params = dict(e.defaults)", ("tests/test_cli_names.py", "tests/test_published.py"),
           "catalogue: --preset ignored"),
    Mutant("check-dt", "python/imufuse/shared/checks.py",
           'return check_real("dt", dt, lo=0.0, lo_open=True)',
           'return check_real("dt", dt, lo=0.0, lo_open=False)', ("tests/test_bad_input.py",),
           "validation: dt = 0 accepted"),
    Mutant("strict-ignored", "python/imufuse/session.py",
           "        if read.strict and self.log.suspicions:",
           "        if False and read.strict and self.log.suspicions:", ("tests/test_plausible.py",),
           "--strict ignored"),
    Mutant("fusion-units", "python/imufuse/session.py",
           "            gyr = np.degrees(log.gyr)          # Fusion's unit",
           "            gyr = log.gyr", ("tests/test_fusion_cli.py", "tests/test_journeys.py"),
           "session: FusionAHRS fed rad/s"),
]


def _rebuild() -> None:
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-build-isolation",
                    "--no-deps", "-e", ROOT], check=True, cwd=ROOT, capture_output=True)


def run(m: Mutant, timeout: float) -> Tuple[str, float, str]:
    path = os.path.join(ROOT, m.path)
    text = open(path).read()
    if text.count(m.old) != 1:
        return "broken", 0.0, f"the edit's text occurs {text.count(m.old)} times"
    t0 = time.time()
    build = m.path.endswith(".pxi") or m.path == "tools/bindgen.py"   # bindings: rebuilt
    try:
        open(path, "w").write(text.replace(m.old, m.new))
        if build:
            try:
                _rebuild()
            except subprocess.CalledProcessError:
                return "broken", time.time() - t0, "the mutant does not build"
        try:
            r = subprocess.run([sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider",
                                *m.tests], cwd=ROOT, capture_output=True, text=True,
                               timeout=timeout)
            verdict = "killed" if r.returncode != 0 else "survived"
            tail = r.stdout.strip().splitlines()[-1] if r.stdout.strip() else r.stderr[-200:]
        except subprocess.TimeoutExpired:
            verdict, tail = "timeout", ""
    finally:
        open(path, "w").write(text)
        if build:
            _rebuild()
    return verdict, time.time() - t0, tail


def main(argv: List[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", help="comma-separated mutant ids")
    ap.add_argument("--list", action="store_true")
    ap.add_argument("--timeout", type=float, default=900.0)
    args = ap.parse_args(argv)
    mutants = list(MUTANTS)
    if args.only:
        keep = set(args.only.split(","))
        mutants = [m for m in mutants if m.id in keep]
    if args.list:
        for m in mutants:
            print(f"{m.id:24s} {m.path}: {m.what}")
        return 0
    print("| mutant | file | what | tests | result | s |")
    print("|---|---|---|---|---|---:|")
    bad = 0
    for m in mutants:
        verdict, secs, tail = run(m, args.timeout)
        bad += verdict != "killed"
        tests = ", ".join(t.replace("tests/", "") for t in m.tests)
        print(f"| {m.id} | {m.path} | {m.what} | {tests} | {verdict} | {secs:.0f} |", flush=True)
        if verdict != "killed":
            print(f"<!-- {m.id}: {tail} -->", flush=True)
    print(f"\n{len(mutants) - bad} of {len(mutants)} mutants killed")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
