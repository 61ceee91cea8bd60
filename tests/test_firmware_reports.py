"""What `imufuse validate` reports beyond bit-exact or not (imufuse.firmware.report): rounding
or formula with the error's growth, the --within tolerance verdict (exit 7), and the JSON and
JUnit files a CI reads, on a small user firmware (Kalman1D-compatible, bit-exact) and planted
variants: a gain changed from 0.02 to 0.0201 (formula), a*b + c*d computed in double and
rounded once (rounding), the same plus a jump at sample 299 (formula by a step), a source that
does not compile and one that crashes (error reports)."""
import hashlib
import json
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from imufuse import sim
from imufuse.cli import main

pytest.importorskip("cffi")

from imufuse.firmware import Firmware, angle_divergence_deg, validate          # noqa: E402
from imufuse.firmware.host import compiler_identity                            # noqa: E402
from imufuse.firmware.report import classify, tolerance                        # noqa: E402
from imufuse.testing import target_missing, validate_firmware                  # noqa: E402

FW = """
#include <math.h>
#include "att.h"
float att_theta;
static float att_k0, att_omk0;
static int att_n;
void att_begin(float k0) { att_k0 = K0; att_omk0 = 1.0f - att_k0; att_theta = 0.0f; att_n = 0; }
void att_step(float gyro, float acc_angle, float dt)
{
    float pred, th;
    if (!isfinite(gyro) || !isfinite(acc_angle)) return;
    pred = att_theta + gyro * dt;
    th = TH;
    STEP
    if (isfinite(th)) att_theta = th;
}
"""
H = ("extern float att_theta;\nvoid att_begin(float k0);\n"
     "void att_step(float gyro, float acc_angle, float dt);\n")
EXACT = dict(K0="k0", TH="att_omk0 * pred + att_k0 * acc_angle", STEP="")
DOUBLE = "(float)((double)att_omk0 * pred + (double)att_k0 * acc_angle)"
VARIANTS = {
    "exact": EXACT,
    "formula": {**EXACT, "K0": "k0 + 0.0001f"},                 # 0.02 -> 0.0201
    "rounding": {**EXACT, "TH": DOUBLE},
    "step": {**EXACT, "TH": DOUBLE, "STEP": "if (++att_n == 300) th += 1e-3f;"},
    "crash": {**EXACT, "STEP": "if (++att_n == 8) { volatile int *p = 0; *p = 1; }"},
    "broken": {**EXACT, "STEP": "this is not C;"},
}
PARAMS = dict(dt=0.005, k0=0.02)


@pytest.fixture(scope="module")
def fwdir(tmp_path_factory):
    d = tmp_path_factory.mktemp("fw")
    (d / "att.h").write_text(H)
    for name, sub in VARIANTS.items():
        src = FW
        for k, v in sub.items():
            src = src.replace(k, v)
        (d / f"{name}.c").write_text(src)
    (d / "cache").mkdir()
    return d


@pytest.fixture(autouse=True)
def cache(fwdir, monkeypatch):
    monkeypatch.setenv("IMUFUSE_CACHE", str(fwdir / "cache"))


def firmware(fwdir, name):
    return Firmware([str(fwdir / f"{name}.c")], headers=["att.h"], include_dirs=[str(fwdir)],
                    init="att_begin", update="att_step", state={"theta": "att_theta"})


@pytest.fixture(scope="module")
def inputs():
    d = sim.axis1d("slow", rate=200.0, duration=5.0, seed=1)
    return [d.gyr, d.acc_angle]


def run(fwdir, name, inputs):
    v = validate(firmware(fwdir, name), "Kalman1D", PARAMS, inputs, explain=False)
    v.params = dict(PARAMS)
    return v


def cli(fwdir, capsys, name, *extra, duration=5):
    rc = main(["validate", str(fwdir / f"{name}.c"), "--header", "att.h", "-I", str(fwdir),
               "-f", "Kalman1D", "--init", "att_begin", "--update", "att_step", "--state",
               "theta=att_theta", "-p", "k0=0.02", "--duration", str(duration),
               *map(str, extra)])
    out = capsys.readouterr()
    return rc, out.out, out.err


def test_classification_and_growth(fwdir, inputs):
    assert run(fwdir, "exact", inputs).classification is None
    n = len(inputs[0])
    for name, kind in (("formula", "formula"), ("rounding", "rounding"), ("step", "formula")):
        v = run(fwdir, name, inputs)
        c = classify(v)
        assert c is not None and c.kind == kind, (name, v.text())
        assert (c.sample, c.variable) == (v.comparison.first_sample, "theta")
        # the growth table, recomputed here: decades of samples, max |got - want|, max degrees
        assert [(r.start, r.stop) for r in c.growth] == [(0, 10), (10, 100), (100, 1000)] and n == 1000
        d = np.abs(v.got[:, 0].astype(np.float64) - v.want[:, 0].astype(np.float64))
        for r in c.growth:
            assert r.max_abs == d[r.start:r.stop].max()
            assert r.differ == np.count_nonzero(v.got[r.start:r.stop, 0] != v.want[r.start:r.stop, 0])
            assert r.max_deg == pytest.approx(np.degrees(d[r.start:r.stop].max()), rel=1e-12)
        assert max(r.max_deg for r in c.growth) == pytest.approx(
            angle_divergence_deg("Kalman1D", PARAMS, v.got, v.want, False), rel=1e-12)
        text = v.text()
        assert f"class: {kind} " in text and "error growth per decade of samples:" in text
        assert "  100-999" in text
    f = classify(run(fwdir, "formula", inputs))
    assert f.sample == 0 and f.first_ulps >= 1e3 and f.first_relative >= 1e-4 and f.step is None
    r = classify(run(fwdir, "rounding", inputs))
    assert r.first_ulps <= 2 and r.step is None and r.max_scale_ulps < 64
    assert max(g.max_abs for g in r.growth) < 1e-6          # bounded: a few ulps of 0.25 rad
    s = classify(run(fwdir, "step", inputs))
    assert s.first_ulps <= 2 and s.sample < 10             # rounding first ...
    assert s.step == 299 and s.step_to >= 1e3 * max(s.step_from, 1)   # ... then a jump
    assert s.growth[2].max_abs == pytest.approx(1e-3, rel=1e-3)
    assert "a step at sample 299" in run(fwdir, "step", inputs).text()


def test_tolerance_in_python(fwdir, inputs):
    v = run(fwdir, "rounding", inputs)
    deg = np.degrees(np.abs(v.got[:, 0].astype(np.float64) - v.want[:, 0]))
    t = tolerance(v, 1e-3)
    assert t.passed and t.max_deg == pytest.approx(deg.max(), rel=1e-12)
    assert t.rms_deg == pytest.approx(np.sqrt(np.mean(deg ** 2)), rel=1e-9)
    assert t.samples == 1000 and t.max_abs == v.comparison.max_abs
    assert not tolerance(v, deg.max() / 2).passed
    assert re.fullmatch(r"within 0\.001 deg: max \S+ deg, RMS \S+ deg over 1000 samples "
                        r"\(rounding: first difference 1 ulp at sample \d+ \(theta\), growing "
                        r"without a step\)", t.text()), t.text()
    # imufuse.testing: within= gives the verdict; assert_passed accepts it
    kw = dict(headers=["att.h"], include_dirs=[str(fwdir)], init="att_begin", update="att_step",
              state={"theta": "att_theta"}, filter="Kalman1D", params={"k0": 0.02}, duration=2.0)
    r = validate_firmware([str(fwdir / "rounding.c")], within=1e-3, **kw)
    assert r.verdict == "within" and r.classification.kind == "rounding"
    r.assert_passed()
    assert "within 0.001 deg" in r.report
    r = validate_firmware([str(fwdir / "formula.c")], within=1e-5, **kw)
    assert r.verdict == "differs"
    with pytest.raises(AssertionError, match="nor within the tolerance"):
        r.assert_passed()
    assert validate_firmware([str(fwdir / "exact.c")], within=1e-5, **kw).verdict == "bit-exact"


def test_within_exit_codes(fwdir, capsys):
    rc, out, _ = cli(fwdir, capsys, "rounding", "--within", "0.001")
    assert rc == 7, out
    assert re.search(r"^within 0\.001 deg: max \S+ deg, RMS \S+ deg over 1000 samples "
                     r"\(rounding: ", out, re.M), out
    rc, out, _ = cli(fwdir, capsys, "rounding", "--within", "1e-9")
    assert rc == 1 and re.search(r"^NOT within 1e-09 deg: max ", out, re.M), out
    rc, out, _ = cli(fwdir, capsys, "formula", "--within", "1")
    assert rc == 7 and "(a different computation: first difference" in out, out
    rc, out, _ = cli(fwdir, capsys, "exact", "--within", "1e-9")
    assert rc == 0 and "bit-exact" in out and "within" not in out, out
    assert cli(fwdir, capsys, "formula")[0] == 1               # without --within: as before
    assert cli(fwdir, capsys, "exact", "--within", "0")[0] == 2


def junit(path):
    """(testcase name -> (passed, result tag or None, message)) read by junitparser, and
    the suite's counts read by xml.etree."""
    junitparser = pytest.importorskip("junitparser")
    xml = junitparser.JUnitXml.fromfile(str(path))
    suites = list(xml) if isinstance(xml, junitparser.JUnitXml) else [xml]
    assert len(suites) == 1
    cases = {}
    for case in suites[0]:
        assert case.classname == "imufuse.validate.host"
        res = case.result
        tag = type(res[0]).__name__.lower() if res else None
        cases[case.name] = (case.is_passed, tag, res[0].message if res else None)
    root = ET.parse(path).getroot()
    suite = root.find("testsuite")
    counts = {k: int(suite.get(k)) for k in ("tests", "failures", "errors", "skipped")}
    assert counts["tests"] == len(suite.findall("testcase")) == len(cases)
    return cases, counts


def test_junit(fwdir, capsys, tmp_path):
    j = tmp_path / "exact.xml"
    assert cli(fwdir, capsys, "exact", "--junit", j)[0] == 0
    cases, counts = junit(j)
    assert cases == {"build": (True, None, None), "bit-exact": (True, None, None)}
    assert counts == dict(tests=2, failures=0, errors=0, skipped=0)
    # rounding beyond a tight tolerance: the check fails, and so do the causes named
    j = tmp_path / "tight.xml"
    assert cli(fwdir, capsys, "rounding", "--within", "1e-9", "--junit", j)[0] == 1
    cases, counts = junit(j)
    assert set(cases) == {"build", "within 1e-09 deg", "causes"}
    assert cases["build"] == (True, None, None)
    passed, tag, msg = cases["within 1e-09 deg"]
    assert not passed and tag == "failure" and msg.startswith("NOT within 1e-09 deg")
    passed, tag, msg = cases["causes"]
    assert not passed and tag == "failure" and "double: fix -fsingle-precision-constant" in msg
    assert counts == dict(tests=3, failures=2, errors=0, skipped=0)
    # within the tolerance: every check passes, the causes are said, not failed
    j = tmp_path / "loose.xml"
    assert cli(fwdir, capsys, "rounding", "--within", "0.001", "--junit", j)[0] == 7
    cases, counts = junit(j)
    assert all(c[0] for c in cases.values()) and counts["failures"] == 0
    assert "within 0.001 deg" in ET.parse(j).getroot().find(".//testcase[@name='within 0.001 deg']"
                                                             "/system-out").text
    # a formula without --within: the bit-exact check fails, no causes are found
    j = tmp_path / "formula.xml"
    assert cli(fwdir, capsys, "formula", "--junit", j)[0] == 1
    cases, _ = junit(j)
    assert set(cases) == {"build", "bit-exact"} and cases["bit-exact"][1] == "failure"
    assert cases["bit-exact"][2].startswith("first difference at sample 0, variable theta")


def test_json(fwdir, capsys, tmp_path):
    p = tmp_path / "r.json"
    assert cli(fwdir, capsys, "exact", "--json", p)[0] == 0
    r = json.loads(p.read_text())
    assert r["verdict"] == "bit-exact" and r["first_divergence"] is None
    assert r["classification"] is None and r["samples"] == 1000 and r["causes"] == []
    b = r["build"]
    ident = compiler_identity()
    assert b["compiler"]["version"] == ident[-1] and b["compiler"]["version"].strip()
    assert b["compiler"]["path"] == ident[len(b["compiler"]["command"])]
    assert b["flags"] == ["-std=c99", "-O2", "-ffp-contract=off"] and b["target"] == "host"
    assert b["files_from"] == "the compiler's -M output"
    files = {f["path"]: f["sha256"] for f in b["files"]}
    for f in ("exact.c", "att.h"):
        path = str((fwdir / f).resolve())
        assert files[path] == hashlib.sha256((fwdir / f).read_bytes()).hexdigest()
    assert any(f.endswith("/math.h") for f in files)          # system headers too
    assert r["timing"]["total"] > 0

    assert cli(fwdir, capsys, "step", "--json", p, "--within", "0.01")[0] == 1
    r = json.loads(p.read_text())
    assert r["verdict"] == "differs" and r["within_deg"] == 0.01 and not r["within"]["passed"]
    fd = r["first_divergence"]
    assert fd["variable"] == "theta" and fd["sample"] == r["classification"]["sample"] < 10
    for side in ("got", "want"):
        bits = int(np.array(fd[side]["value"], dtype=np.float32).view(np.uint32))
        assert fd[side]["bits"] == f"0x{bits:08x}"
    assert fd["got"]["bits"] != fd["want"]["bits"]
    c = r["classification"]
    assert c["kind"] == "formula" and c["step"] == 299 and len(c["growth"]) == 3
    double = [x for x in r["causes"] if x["name"] == "double"]
    assert len(double) == 1 and double[0]["fix"] == "-fsingle-precision-constant"
    assert double[0]["confirmed"] is False and "-Wdouble-promotion" in double[0]["evidence"]
    assert "error growth per decade of samples" in r["text"]


def test_errors_still_write_reports(fwdir, capsys, tmp_path):
    j, x = tmp_path / "e.json", tmp_path / "e.xml"
    rc, _, err = cli(fwdir, capsys, "broken", "--json", j, "--junit", x)
    assert rc == 5 and "compilation failed" in err
    r = json.loads(j.read_text())
    assert (r["verdict"], r["stage"]) == ("error", "build") and "compilation failed" in r["message"]
    assert str((fwdir / "broken.c").resolve()) in {f["path"] for f in r["build"]["files"]}
    cases, counts = junit(x)
    assert cases["build"][1] == "failure" and cases["bit-exact"][1] == "skipped"
    assert counts == dict(tests=2, failures=1, errors=0, skipped=1)

    rc, _, err = cli(fwdir, capsys, "crash", "--json", j, "--junit", x, "--timeout", 20)
    assert rc == 5 and "crashed with SIGSEGV at sample 7" in err
    r = json.loads(j.read_text())
    assert (r["verdict"], r["stage"]) == ("error", "run")
    cases, counts = junit(x)
    assert cases["build"] == (True, None, None)
    assert cases["bit-exact"][1] == "error" and "SIGSEGV" in cases["bit-exact"][2]
    # outputs are checked before any work: not a source, not each other
    src = fwdir / "exact.c"
    before = src.read_bytes()
    assert cli(fwdir, capsys, "exact", "--json", src)[0] == 2 and src.read_bytes() == before
    assert cli(fwdir, capsys, "exact", "--json", j, "--junit", j)[0] == 2


@pytest.mark.emulator
@pytest.mark.slow
@pytest.mark.skipif(target_missing("cortex-m4f") is not None, reason="no Cortex-M4F toolchain")
def test_json_of_a_target_build(fwdir, capsys, tmp_path):
    p = tmp_path / "m4f.json"
    rc, out, _ = cli(fwdir, capsys, "exact", "--target", "cortex-m4f", "--json", p,
                     "--cflags", "-O2 -ffp-contract=off", duration=1)
    assert rc == 0, out
    r = json.loads(p.read_text())
    b = r["build"]
    assert b["compiler"]["command"] == ["arm-none-eabi-gcc"]
    assert b["compiler"]["version"].startswith("arm-none-eabi-gcc")
    assert b["flags"] == ["-O2", "-ffp-contract=off"] and "-mcpu=cortex-m4" in b["arch_flags"]
    files = {f["path"]: f["sha256"] for f in b["files"]}
    for f in ("exact.c", "att.h"):
        assert files[str((fwdir / f).resolve())] == hashlib.sha256((fwdir / f).read_bytes()).hexdigest()
    assert r["cost"]["unit"] == "instructions" and r["cost"]["min"] > 0
    assert r["timing"]["build"] > 0 and r["timing"]["emulator"] > 0
