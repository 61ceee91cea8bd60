"""`imufuse validate --target`: a user's firmware built by the target's cross compiler with the
user's flags, run on the emulated Cortex-M4F, Cortex-M0 and ATmega328P, compared bit for bit.

The firmware is examples/firmware-tests/cf.c (Eq. 2.2 as firmware writes it) and copies of it,
or of csrc, with planted faults. Where a test needs the expected result it computes it on its
own: the fused multiply-add model of cf.c in exact rational arithmetic, the wrong-sign mirror in
numpy float32, the per-update counts of the MCU benchmark harness (imufuse.mcu.filters).
"""
import os
import shutil
import subprocess
import sys
from fractions import Fraction

import numpy as np
import pytest

from imufuse import sim
from imufuse.shared.resources import csrc_dir
from imufuse.firmware import (DEFAULT_CFLAGS, Firmware, FirmwareError, csrc_firmware, validate)
from imufuse.mcu import ensure_toolchains
from imufuse.reference import Complementary1D, MahonyIMUQ
from imufuse.testing import validate_firmware

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FW = os.path.join(ROOT, "examples", "firmware-tests")
TARGETS = ("cortex-m4f", "cortex-m0", "atmega328p")
F32 = np.float32


@pytest.fixture(scope="module", autouse=True)
def _toolchains():
    """The cross toolchains and emulators: installed when missing (tools/install-toolchains.sh);
    a target that still cannot run fails here, it is not skipped."""
    missing = ensure_toolchains(("m4f", "m0", "avr"))
    assert not missing, f"MCU toolchains missing: {missing}"


def _cf(tmp_path=None, old=None, new=None, prelude=""):
    """cf.c, or a copy with `old` replaced by `new` (exactly once)."""
    if tmp_path is None:
        src, inc = os.path.join(FW, "cf.c"), FW
    else:
        text = open(os.path.join(FW, "cf.c")).read()
        if old is not None:
            assert text.count(old) == 1, f"cf.c changed: {old!r}"
            text = text.replace(old, new)
        d = tmp_path / "fw"
        d.mkdir(exist_ok=True)
        shutil.copy(os.path.join(FW, "cf.h"), d / "cf.h")
        (d / "cf.c").write_text(prelude + text)
        src, inc = str(d / "cf.c"), str(d)
    return src, inc


def _fw(src, inc, cflags):
    return Firmware([src], headers=["cf.h"], include_dirs=[inc], init="cf_init", update="cf_update",
                    state={"theta": "theta"}, cflags=cflags)


def _motion(n=400, seed=1):
    d = sim.axis1d("slow", rate=200.0, duration=n / 200.0, seed=seed)
    return d.dt, (d.gyr, d.acc_angle)


PARAMS = dict(T=0.5)


def _validate(src, inc, cflags, target, n=400, timeout=60.0):
    dt, ins = _motion(n)
    return validate(_fw(src, inc, cflags), "Complementary1D", dict(dt=dt, **PARAMS), ins,
                    target=target, timeout=timeout), dt, ins


def _fma_model(dt, ins):
    """cf.c as GCC contracts it on the Cortex-M4F (two vfma.f32): t = fma(rate, dt, theta),
    theta = fma(alpha, t, oma * angle), each fma rounded once, in exact rational arithmetic."""
    f = Complementary1D(dt=dt, **PARAMS, dtype="float32")
    alpha = F32(f._params(dt, T=0.5)[1])
    dt32, oma = F32(dt), F32(1.0) - alpha
    theta = F32(0.0)
    out = []
    for r, a in zip(ins[0].astype(F32), ins[1].astype(F32)):
        t = F32(float(Fraction(float(r)) * Fraction(float(dt32)) + Fraction(float(theta))))
        p = oma * a
        theta = F32(float(Fraction(float(alpha)) * Fraction(float(t)) + Fraction(float(p))))
        out.append(theta)
    return np.array(out, dtype=F32)


def _first_diff(a, b):
    rows = np.flatnonzero(np.asarray(a, F32).view(np.uint32) != np.asarray(b, F32).view(np.uint32))
    return int(rows[0]) if rows.size else None


# ---------------------------------------------------------------------------
# Eq. 2.2 as firmware writes it, with the flags firmware builds use

@pytest.mark.parametrize("target", TARGETS)
def test_contract_flags_are_bit_exact_on_every_target(target):
    v, _, _ = _validate(*_cf(), ["-O2", "-ffp-contract=off"], target)
    assert v.bit_exact, v.text()
    c = v.cost
    assert c.unit == ("cycles" if target == "atmega328p" else "instructions")
    assert 0 < c.min <= c.median <= c.max and len(c.counts) == 400
    assert c.flash and c.flash > 0 and c.ram >= 20 and c.stack is not None
    assert "cost per update" in v.text() and "stack" in v.text()


def test_gnu_defaults_on_the_m4f_fuse_and_the_report_names_the_fix(tmp_path):
    v, dt, ins = _validate(*_cf(), ["-O2"], "cortex-m4f")
    assert not v.bit_exact
    model = _fma_model(dt, ins)
    # the emulated M4F computes exactly the contracted expression, sample for sample
    assert np.array_equal(v.got[:, 0].view(np.uint32), model.view(np.uint32))
    want = Complementary1D(dt=dt, **PARAMS, dtype="float32").run(*(a.astype(F32) for a in ins))
    assert v.comparison.first_sample == _first_diff(model, want[:, 0])
    text = v.text()
    assert "fused multiply-add" in text and "vfma.f32" in text
    assert "fix: add -ffp-contract=off (confirmed" in text
    assert "largest orientation difference" in text
    assert v.max_angle_deg == pytest.approx(
        float(np.degrees(np.abs(model.astype(float) - want[:, 0].astype(float)).max())), rel=1e-6)
    # and through the command line: exit 1, the same diagnosis
    p = subprocess.run([sys.executable, "-m", "imufuse", "validate", os.path.join(FW, "cf.c"),
                        "--header", "cf.h", "-I", FW, "--filter", "Complementary1D", "--init",
                        "cf_init", "--update", "cf_update", "--state", "theta=theta",
                        "--target", "cortex-m4f", "--duration", "2"],
                       capture_output=True, text=True, cwd=tmp_path)
    assert p.returncode == 1, p.stdout + p.stderr
    assert "flags -O2)" in p.stdout and "-ffp-contract=off (confirmed" in p.stdout


@pytest.mark.parametrize("target", ["cortex-m0", "atmega328p"])
def test_gnu_defaults_without_an_fpu_stay_bit_exact_and_say_why(target):
    v, _, _ = _validate(*_cf(), ["-O2"], target)
    assert v.bit_exact, v.text()
    assert "no FPU" in v.text() and "no multiply-add" in v.text() or "no fused" in v.text()


def test_host_with_fma_names_the_cause(tmp_path):
    v, dt, ins = _validate(*_cf(), ["-O2", "-march=haswell"], "host")
    assert not v.bit_exact
    assert np.array_equal(v.got[:, 0].view(np.uint32), _fma_model(dt, ins).view(np.uint32))
    assert "vfmadd" in v.text() and "-ffp-contract=off (confirmed" in v.text()


# ---------------------------------------------------------------------------
# planted faults, on every target

@pytest.mark.parametrize("target", TARGETS)
def test_wrong_sign(tmp_path, target):
    src, inc = _cf(tmp_path, "rate * s->dt", "-rate * s->dt")
    v, dt, ins = _validate(src, inc, ["-O2", "-ffp-contract=off"], target)
    # the mirror of the mistake in float32
    f = Complementary1D(dt=dt, **PARAMS, dtype="float32")
    want = f.run(*(a.astype(F32) for a in ins))[:, 0]
    alpha = F32(f._params(dt, T=0.5)[1])
    theta, mirror = F32(0), []
    for r, a in zip(ins[0].astype(F32), ins[1].astype(F32)):
        theta = alpha * (theta + (-r) * F32(dt)) + (F32(1) - alpha) * a
        mirror.append(theta)
    mirror = np.array(mirror, F32)
    assert np.array_equal(v.got[:, 0].view(np.uint32), mirror.view(np.uint32))
    assert v.comparison.first_sample == _first_diff(mirror, want)
    assert "none of the known build causes" in v.text()


@pytest.mark.parametrize("target", TARGETS)
def test_missed_normalisation(tmp_path, target):
    d = tmp_path / "csrc"
    shutil.copytree(csrc_dir(), d)
    text = (d / "madgwick.c").read_text()
    old = "    return imf_normalise4(&x->q0, &x->q1, &x->q2, &x->q3, set->invsqrt) == IMF_NORM_OK;"
    assert text.count(old) == 1
    (d / "madgwick.c").write_text(text.replace(old, "    return 1;"))
    fw = csrc_firmware("MadgwickIMU", str(d), "float32", cflags=["-O2", "-ffp-contract=off"])
    s = sim.imu("slow", rate=200.0, duration=2.0, seed=1)
    v = validate(fw, "MadgwickIMU", dict(dt=s.dt, beta=0.1), (s.gyr, s.acc), target=target)
    assert not v.bit_exact
    norm = np.linalg.norm(v.got.astype(float), axis=1)
    assert abs(norm[-1] - 1.0) > 1e-3          # the firmware's quaternion left the unit sphere
    assert "none of the known build causes" in v.text()


@pytest.mark.parametrize("target", TARGETS)
def test_double_arithmetic(tmp_path, target):
    src, inc = _cf(tmp_path, "s->oma * angle", "(1.0 - s->alpha) * angle")
    v, _, _ = _validate(src, inc, ["-O2", "-ffp-contract=off"], target)
    if target == "atmega328p":
        # double is float here: the same bits, and the report says where double was meant
        assert v.bit_exact, v.text()
        assert "computes in double at cf.c:" in v.text() and "32 bits" in v.text()
    else:
        assert not v.bit_exact
        assert "double-precision arithmetic" in v.text() and "__aeabi_d" in v.text()
        assert "-fsingle-precision-constant (confirmed" in v.text()


@pytest.mark.parametrize("target", TARGETS)
def test_fast_math(target):
    fw = csrc_firmware("MadgwickIMU", str(csrc_dir()), "float32",
                       cflags=["-O2", "-ffp-contract=off", "-ffast-math"])
    s = sim.imu("slow", rate=200.0, duration=2.0, seed=1)
    v = validate(fw, "MadgwickIMU", dict(dt=s.dt, beta=0.1), (s.gyr, s.acc), target=target)
    assert not v.bit_exact
    fm = [c for c in v.causes if c.what == "fast-math"]
    assert fm and fm[0].fix == "-fno-fast-math"
    together = [c for c in v.causes if c.what == "together"]
    assert fm[0].confirmed or (together and together[0].confirmed), v.text()


_BIG = {"cortex-m4f": 1_100_000, "cortex-m0": 5000, "atmega328p": 700}   # floats > the RAM


@pytest.mark.parametrize("target", TARGETS)
@pytest.mark.parametrize("fault", ["stack", "hard fault", "endless loop", "exit"])
def test_runtime_faults_name_the_sample(tmp_path, target, fault):
    code = {
        "stack": "if (s->n == 50u) { volatile float big[BIG]; uint32_t i; "
                 "for (i = 0u; i < BIG; ++i) { big[i] = angle; } s->theta += big[7] * 0.0f; }",
        "hard fault": "if (s->n == 50u) { ((void (*)(void))0)(); }",
        "endless loop": "if (s->n == 50u) { for (;;) { __asm__ volatile(\"\"); } }",
        "exit": "if (s->n == 50u) { exit(3); }",
    }[fault]
    prelude = f"#include <stdlib.h>\n#define BIG {_BIG[target]}u\n"
    src, inc = _cf(tmp_path, "/* FAULT */", code, prelude)
    with pytest.raises(FirmwareError) as e:
        _validate(src, inc, ["-O2", "-ffp-contract=off"], target, timeout=3.0)
    msg = str(e.value)
    assert "\n" not in msg
    if fault == "stack":
        # the frame is allocated on entry (sample 0) or in the branch (sample 49)
        assert "stack overflow" in msg and ("sample 49" in msg or "sample 0" in msg), msg
    elif fault == "hard fault":
        assert "sample 49" in msg and (("hard fault" in msg) if target != "atmega328p"
                                       else ("restarted" in msg)), msg
    elif fault == "endless loop":
        assert "no answer within 3 s at sample 49" in msg, msg
    else:
        assert "exit(3) at sample 49" in msg, msg


def test_cli_fault_exits_5(tmp_path):
    src, inc = _cf(tmp_path, "/* FAULT */", "if (s->n == 50u) { ((void (*)(void))0)(); }")
    p = subprocess.run([sys.executable, "-m", "imufuse", "validate", src, "--header", "cf.h",
                        "-I", inc, "--filter", "Complementary1D", "--init", "cf_init", "--update",
                        "cf_update", "--state", "theta=theta", "--target", "cortex-m0",
                        "--cflags", "-O2"],
                       capture_output=True, text=True, cwd=tmp_path)
    assert p.returncode == 5, p.stdout + p.stderr
    assert "hard fault at sample 49" in p.stderr and len(p.stderr.strip().splitlines()) == 1


# ---------------------------------------------------------------------------
# logs longer than the target's flash; state that lives outside the filter object

def test_long_log_in_chunks_carries_static_state(tmp_path):
    """A file-scope counter in the firmware plants one wrong sample at 5000: found there only
    if the firmware's RAM (not only its filter object) carries from chunk to chunk."""
    src, inc = _cf(tmp_path, "/* FAULT */",
                   "if (++calls == 5001u) { s->theta += 1.0f; }", "static unsigned long calls;\n")
    v, _, _ = _validate(src, inc, ["-O2", "-ffp-contract=off"], "atmega328p", n=6000)
    assert v.timing["chunks"] >= 2
    assert v.comparison.first_sample == 5000 and v.comparison.n_different == 1000


def test_fixed_point_firmware_compared_as_integers():
    """A user's MahonyIMUQ (imufuse's fixed sources behind the user's own API) as integers on
    the ATmega328P and the Cortex-M0."""
    fx = str(csrc_dir() / "fixed")
    params = dict(dt=1 / 200, kp=1.0, ki=0.05, gyr_scale=1.0642e-3)
    c = MahonyIMUQ(**params).c_init_args()
    defs = {"FW_KG_M": c["kg"].m, "FW_KG_S": c["kg"].s, "FW_KP_M": c["kp"].m,
            "FW_KP_S": c["kp"].s, "FW_KI_M": c["ki"].m, "FW_KI_S": c["ki"].s,
            "IMF_FIXED_PROFILE": 32}
    exprs = [f"=att.x.q[{k}]" for k in range(4)] + [f"=att.x.i[{k}]" for k in range(3)] + \
        [f"=att.x.c[{k}]" for k in range(3)]
    s = sim.imu("fast", rate=200.0, duration=3.0, seed=4)
    g = np.clip(np.rint(s.gyr / params["gyr_scale"]), -32768, 32767).astype(np.int16)
    a = np.clip(np.rint(s.acc * 4096), -32768, 32767).astype(np.int16)
    want = MahonyIMUQ(**params).run(g, a)
    for target in ("atmega328p", "cortex-m0"):
        fw = Firmware([os.path.join(FW, "mahony_fw.c"), os.path.join(fx, "mahony_q.c")],
                      headers=["mahony_fw.h"], include_dirs=[FW, fx], init="att_init",
                      update="att_update", state=dict(zip(MahonyIMUQ.state_names, exprs)),
                      defines=defs, cflags=["-Os"])
        v = validate(fw, "MahonyIMUQ", params, (g, a), target=target)
        assert v.bit_exact, v.text()
        assert v.got.dtype == np.int64 and np.array_equal(v.got, want.astype(np.int64))
        assert v.comparison.dtype == "int32" and "(int32)" in v.text(), v.text()


@pytest.mark.parametrize("target", TARGETS)
def test_same_counts_as_the_mcu_benchmarks(target):
    """imufuse's own MadgwickIMU validated as firmware costs, update for update, what the
    MCU benchmark harness (bench/mcu) measures on the same inputs."""
    from imufuse import reference
    from imufuse.mcu import filters as mf
    params = dict(dt=1 / 100, beta=0.1)
    spec = mf.FilterSpec.make(reference.MadgwickIMU, params, "float32")
    ins = mf.inputs_for("float32", "3d", 120)
    bench = mf.run_filters({"cortex-m4f": "m4f", "cortex-m0": "m0", "atmega328p": "avr"}[target],
                           [spec], ins, count=True).results[0].counts
    fw = csrc_firmware("MadgwickIMU", str(csrc_dir()), "float32", cflags=list(DEFAULT_CFLAGS))
    v = validate(fw, "MadgwickIMU", params, [ins["gyr"], ins["acc"]], target=target)
    assert v.bit_exact, v.text()
    assert np.array_equal(v.cost.counts, bench)


def test_settings_struct_init_on_the_target():
    """A firmware whose init takes a settings struct (imufuse's RobustAHRS, 16 members) is
    validated member by member: every setting reaches the target (a changed one changes the
    result) and the run is bit-exact."""
    from imufuse.mcu import filters as mf
    ins = mf.inputs_for("float32", "3d", 150)
    args = [ins["gyr"], ins["acc"], ins["mag"]]
    fw = csrc_firmware("RobustAHRS", str(csrc_dir()), "float32", cflags=list(DEFAULT_CFLAGS))
    assert fw.init_struct and fw.init_struct[0] == "imf_robust_settings_t"
    params = dict(dt=1 / 200, tau_acc=1.0, tau_bias=20.0, rest_time=0.2, tau_rest=0.1,
                  latency=0.003, tau_mag=3.0, mag_dip=30.0)
    v = validate(fw, "RobustAHRS", params, args, target="cortex-m0")
    assert v.bit_exact, v.text()
    w = validate(fw, "RobustAHRS", dict(params, tau_acc=2.0), args, target="cortex-m0")
    assert w.bit_exact and not np.array_equal(v.got, w.got)


# ---------------------------------------------------------------------------
# imufuse.testing

def test_testing_api_assertions():
    base = dict(sources=[os.path.join(FW, "cf.c")], headers=["cf.h"], include_dirs=[FW],
                init="cf_init", update="cf_update", state={"theta": "theta"},
                filter="Complementary1D", params=PARAMS, duration=2.0)
    r = validate_firmware(**base, target="cortex-m4f", cflags="-O2")
    with pytest.raises(AssertionError, match="(?s)not bit-exact.*first divergence.*-ffp-contract"):
        r.assert_bit_exact()
    r.assert_within(deg=1e-3)
    with pytest.raises(AssertionError, match="differs by up to"):
        r.assert_within(deg=1e-9)
    with pytest.raises(AssertionError, match="slowest update"):
        r.assert_cost(max_per_update=1)
    ok = validate_firmware(**base, target="cortex-m0", cflags="-O2 -ffp-contract=off")
    ok.assert_bit_exact()
    ok.assert_cost(max_per_update=5000, max_stack=256, max_flash=4096, max_ram=64)


def test_example_tests_run(tmp_path):
    """examples/firmware-tests/test_cf_firmware.py, as a firmware team runs it."""
    p = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                        "--rootdir", str(tmp_path), os.path.join(FW, "test_cf_firmware.py")],
                       capture_output=True, text=True, cwd=tmp_path)
    assert p.returncode == 0 and "5 passed" in p.stdout, p.stdout + p.stderr


def test_bad_target_is_an_error():
    with pytest.raises(ValueError, match="unknown target 'cortex-m85'.*cortex-m7"):
        _validate(*_cf(), ["-O2"], "cortex-m85")


def test_readme_firmware_section_shows_a_real_report():
    """The README's firmware command, run as written, prints the README's report."""
    import re
    import shlex
    readme = open(os.path.join(ROOT, "README.md")).read()
    sec = readme[readme.index("## Firmware: validate your C where it runs"):]
    cmd = re.search(r"```sh\n(.*?)```", sec, re.S).group(1).replace("\\\n", " ")
    report = re.search(r"```\n(inputs:.*?)```", sec, re.S).group(1)
    argv = shlex.split(cmd)
    assert argv[0] == "imufuse"
    p = subprocess.run([sys.executable, "-m", "imufuse", *argv[1:]], capture_output=True,
                       text=True, cwd=ROOT)
    assert p.returncode == 1, p.stderr
    assert p.stdout == report


@pytest.mark.parametrize("flags", [["-std=c89", "-O2"], ["-ansi", "-pedantic", "-Werror", "-O2"],
                                   ["-std=gnu11", "-Os", "-flto", "-Wall", "-Wextra", "-Werror"]])
def test_firmware_flags_of_other_standards(flags):
    """C89 firmware (no hexadecimal literals in the driver: decimal ones that round the same),
    warnings as errors (the driver's own code is not the user's to warn about), LTO."""
    v, _, _ = _validate(*_cf(), flags, "atmega328p", n=200)
    assert v.bit_exact, v.text()


def test_architecture_flags_of_the_user_are_named():
    v, _, _ = _validate(*_cf(), ["-O2", "-mcpu=cortex-m0plus"], "cortex-m0", n=200)
    assert v.bit_exact, v.text()
    assert "your --cflags set the architecture (-mcpu=cortex-m0plus)" in v.text()


# ---------------------------------------------------------------------------
# the binary records the emulated target sends (imf_fw_main.c, imufuse.firmware.target_run)

_PLANT_H = """#ifndef PLANT_H
#define PLANT_H
#include "madgwick.h"
void plant_init(imf_madgwick_t *self, const imf_madgwick_settings_t *settings);
void plant_update(imf_madgwick_t *self, imf_real gx, imf_real gy, imf_real gz, imf_real ax,
                  imf_real ay, imf_real az);
#endif
"""

_PLANT_C = """#include <string.h>
#include "plant.h"
static unsigned long plant_n;
void plant_init(imf_madgwick_t *self, const imf_madgwick_settings_t *settings)
{
    imf_madgwick_init(self, settings);
}
void plant_update(imf_madgwick_t *self, imf_real gx, imf_real gy, imf_real gz, imf_real ax,
                  imf_real ay, imf_real az)
{
    imf_madgwick_update_imu(self, gx, gy, gz, ax, ay, az);
    if (++plant_n == PLANT_AT + 1ul) {
        uint32_t b;
        memcpy(&b, &self->x.q2, sizeof b);
        b ^= 1u;
        memcpy(&self->x.q2, &b, sizeof b);
    }
}
"""


@pytest.mark.parametrize("target", ["cortex-m0", "atmega328p"])
def test_planted_bit_reported_at_its_sample_and_word(tmp_path, target):
    """MadgwickIMU with the last bit of q2 flipped after sample 1029: the records carry every
    state word of every sample (escaped bytes, the index byte wrapping past 255, two chunks on
    the ATmega328P) to the host unchanged, so the report names sample 1029 and q2, and every
    word before it is equal bit for bit."""
    at, n = 1029, 1100
    (tmp_path / "plant.h").write_text(_PLANT_H)
    (tmp_path / "plant.c").write_text(_PLANT_C)
    csrc = str(csrc_dir())
    fw = Firmware([os.path.join(csrc, "madgwick.c"), str(tmp_path / "plant.c")],
                  headers=["madgwick.h", "plant.h"], include_dirs=[csrc, str(tmp_path)],
                  defines={"PLANT_AT": at}, init="plant_init", update="plant_update",
                  state={f"q{k}": f"x.q{k}" for k in range(4)},
                  state_names=("q0", "q1", "q2", "q3"), cflags=list(DEFAULT_CFLAGS))
    s = sim.imu("slow", rate=200.0, duration=n / 200.0, seed=3)
    v = validate(fw, "MadgwickIMU", dict(dt=s.dt, beta=0.1), (s.gyr, s.acc), target=target,
                 explain=False)
    assert len(v.got) == n and v.cost.counts.size == n
    c = v.comparison
    assert (c.first_sample, c.first_variable) == (at, "q2"), v.text()
    got, want = v.got.view(np.uint32), np.asarray(v.want, dtype=F32).view(np.uint32)
    assert np.array_equal(got[:at], want[:at])
    assert got[at, 2] == want[at, 2] ^ 1 and np.array_equal(np.delete(got[at], 2),
                                                            np.delete(want[at], 2))
    if target == "atmega328p":
        assert v.timing["chunks"] >= 2


def _escaped(rec):
    """A record as imf_fw_main.c's imf_fw_put writes it."""
    out = bytearray()
    for b in rec:
        out += bytes((0x7E, b + 0x40)) if b < 0x20 or b in (0x2E, 0x7E) else bytes((b,))
    return bytes(out)


def test_records_decoded_word_for_word_and_cut_at_a_lost_byte():
    """The host's decoder (no emulator): every byte value in 32- and 64-bit words, counts and
    the wrapping index come back as sent; a byte lost in record 300 ends the samples at 300
    (the sample the report then names), and an emulator's message after the last record adds
    none."""
    import struct
    from imufuse.firmware.target_run import _records
    rng = np.random.default_rng(5)
    n = 600
    w32 = rng.integers(0, 2 ** 32, size=(n, 2), dtype=np.uint64)
    w32[:256, 0] = np.arange(256, dtype=np.uint64) * 0x01010101
    w64 = rng.integers(0, 2 ** 63, size=n, dtype=np.uint64) * 2 + 1
    counts = rng.integers(0, 2 ** 32, size=n, dtype=np.uint64)
    recs = [_escaped(b"S" + struct.pack("<IIQI", int(w32[i, 0]), int(w32[i, 1]), int(w64[i]),
                                        int(counts[i])) + bytes((i & 0xFF,))) for i in range(n)]
    words, c, k = _records(b"".join(recs), [4, 4, 8])
    assert k == n
    assert np.array_equal(words, np.column_stack([w32, w64]))
    assert np.array_equal(c, counts.astype(np.int64))
    lost = recs[300][:5] + recs[300][6:]
    assert _records(b"".join(recs[:300] + [lost] + recs[301:]), [4, 4, 8])[2] == 300
    assert _records(b"".join(recs) + b"qemu: fatal: Lockup", [4, 4, 8])[2] == n
