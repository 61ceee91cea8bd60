"""Reliability, round three (docs/robustness.md): each class found by the third hostile round
holds here with several instances, each of which failed on the code before the fix.

- the batch path (imufuse_c.run_filters / run_many) checks everything it hands to C: one
  filter object twice, a Reference changed after prepare_reference, a fixed-point or a
  reference filter, a dtype inside a parameter set, threads and lanes of the wrong type;
- a value settable on a filter is checked in the filter's own precision (the magnetometer
  offset of a float32 RobustAHRS);
- validate's host build cache covers every file the compiler read, and the firmware's C
  constructors run only in validate's child process;
- compare keeps the estimate, never the trajectory (its memory on a long log is measured in
  tests/test_memory.py).
"""
import copy
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import imufuse_c
import imufuse.reference as reference
from imufuse import sim
from imufuse.evaluation import Reference, prepare_reference
from imufuse.session import Session, RunOptions

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.fixture(scope="module")
def log():
    d = sim.imu("fast", rate=200.0, duration=4.0, seed=11)
    return d


def _bits(a):
    a = np.ascontiguousarray(a)
    return a.view(np.uint64 if a.dtype == np.float64 else np.uint32)


# ---------------------------------------------------------------------------
# the batch path


@pytest.mark.parametrize("name,args", [("MadgwickAHRS", dict(dt=0.005, beta=0.1)),
                                       ("RobustAHRS", dict(dt=0.005)),
                                       ("MahonyAHRS", dict(dt=0.005))])
@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_one_filter_twice_is_refused(log, name, args, dtype):
    """[f] * P handed the same C struct to two lanes or two threads at once: refused, naming
    both entries, and nothing ran (f's state is unchanged)."""
    f = getattr(imufuse_c, name)(**args, dtype=dtype)
    before = f.state.copy()
    for filters, pair in (([f] * 4, "filters[0] and filters[1]"),
                          ([copy.copy(f), f, copy.copy(f), f], "filters[1] and filters[3]")):
        for lanes in (0, None):
            with pytest.raises(ValueError, match=r"same object") as e:
                imufuse_c.run_filters(filters, log.gyr, log.acc, log.mag, lanes=lanes,
                                      threads=2)
            assert pair in str(e.value)
    assert _bits(f.state).tobytes() == _bits(before).tobytes()


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_copies_give_the_same_bits_at_any_lanes_and_threads(log, dtype):
    """The documented alternative to [f] * P: copies, each the same trajectory whatever the
    lane width and thread count (and each its own run()'s)."""
    f = imufuse_c.MadgwickAHRS(dt=0.005, beta=0.1, dtype=dtype)
    want = copy.copy(f).run(log.gyr, log.acc, log.mag)
    for lanes in [0, *imufuse_c.lane_widths(dtype)]:
        for threads in (1, 2):
            out = imufuse_c.run_filters([copy.copy(f) for _ in range(5)], log.gyr, log.acc,
                                        log.mag, lanes=lanes, threads=threads)
            for row in out:
                assert _bits(row).tobytes() == _bits(want).tobytes(), (lanes, threads)


def _ref(log):
    return prepare_reference(log.q_true, ref_frame="NWU", remove_heading_offset=True)


def _mutants(log):
    """References changed after prepare_reference, as a user can change them (the dataclass
    is public and its arrays mutable), with what must be said."""
    n = len(log.gyr)
    good = _ref(log)
    out = []
    r = _ref(log)
    r.use = list(r.use)
    out.append((r, TypeError, "Reference.use must be a numpy array"))
    r = _ref(log)
    r.n = r.n + 1000                               # a stale n with the heading offset
    out.append((r, ValueError, "Reference.n is"))
    r = _ref(log)
    r.n = r.n // 2
    out.append((r, ValueError, "Reference.n is"))
    r = _ref(log)
    r.n = -1
    out.append((r, ValueError, "Reference.n must be an int >= 0"))
    r = _ref(log)
    r.n = float(r.n)
    out.append((r, TypeError, "Reference.n must be an int"))
    r = _ref(log)
    r.r = r.r[: n // 2]                            # a short r
    out.append((r, ValueError, "Reference.r must be"))
    r = _ref(log)
    r.use = r.use.astype(np.float64)               # floats where 0/1 bytes are read
    out.append((r, ValueError, "Reference.use must be"))
    r = _ref(log)
    r.use = r.use.copy()
    r.use[5] = 7
    out.append((r, ValueError, "0 or 1 only"))
    r = _ref(log)
    r.r = r.r.copy()
    r.r[10] = [2.0, 0, 0, 0]
    out.append((r, ValueError, "unit rows"))
    r = _ref(log)
    r.r = np.asfortranarray(r.r)                   # another layout: copied
    out.append((r, None, None))
    out.append((good.use, TypeError, "an imufuse.evaluation.Reference"))
    out.append(({"use": good.use, "r": good.r, "n": good.n}, TypeError,
                "an imufuse.evaluation.Reference"))
    return out


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_a_changed_reference_is_refused_before_c_reads_it(log, dtype):
    """Every mutant of a Reference is refused by type or by name before C reads it (a list
    segfaulted, a stale n overflowed the heap, a short r read out of bounds and returned a
    wrong score with exit 0); a Reference of another layout is copied and scores the same."""
    make = lambda: imufuse_c.MadgwickAHRS(dt=0.005, beta=0.1, dtype=dtype)  # noqa: E731
    want = imufuse_c.run_filters([make()], log.gyr, log.acc, log.mag, score=_ref(log))[0]
    for ref, exc, msg in _mutants(log):
        if exc is None:
            got = imufuse_c.run_filters([make()], log.gyr, log.acc, log.mag, score=ref)[0]
            assert (got.total, got.heading, got.n) == (want.total, want.heading, want.n)
            continue
        with pytest.raises(exc, match=msg):
            imufuse_c.run_filters([make(), make()], log.gyr, log.acc, log.mag, score=ref)


def test_the_reference_handed_to_c_is_a_sealed_copy(log):
    ref = _ref(log)
    sealed = ref.sealed(len(log.gyr))
    assert isinstance(sealed, Reference)
    assert not sealed.use.flags.writeable and not sealed.r.flags.writeable
    assert not np.shares_memory(sealed.use, ref.use) and not np.shares_memory(sealed.r, ref.r)
    ref.use[:] = 0                     # the caller's object changes; the sealed copy does not
    assert sealed.n == int(np.count_nonzero(sealed.use)) > 0


@pytest.mark.parametrize("bad,exc,msg", [
    (lambda: [imufuse_c.MadgwickIMUQ(0.005, gyr_scale=1e-3)], TypeError,
     "fixed-point filter"),
    (lambda: [reference.MadgwickAHRS(dt=0.005)], TypeError, "pure-Python reference filter"),
    (lambda: [imufuse_c.MadgwickAHRS(dt=0.005), reference.MadgwickAHRS(dt=0.005)], TypeError,
     r"filters\[1\] is imufuse.reference"),
    (lambda: [imufuse_c.MadgwickAHRS(dt=0.005),
              imufuse_c.MadgwickAHRS(dt=0.005, dtype="float32")], TypeError, "one class and precision"),
    (lambda: [imufuse_c.MadgwickAHRS(dt=0.005), imufuse_c.MahonyAHRS(dt=0.005)], TypeError,
     "one class and precision"),
    (lambda: [object()], TypeError, "not a compiled float filter"),
    (lambda: imufuse_c.MadgwickAHRS(dt=0.005), TypeError, "a sequence of filters"),
])
def test_wrong_filters_are_named(log, bad, exc, msg):
    """Argument mistakes are named, never internals (KeyError: 'int32', AttributeError:
    _ref)."""
    filters = bad()
    with pytest.raises(exc, match=msg):
        imufuse_c.run_filters(filters, log.gyr, log.acc, log.mag)


@pytest.mark.parametrize("kw,exc,msg", [
    (dict(threads="2"), TypeError, "threads: a positive int"),
    (dict(threads=0), TypeError, "threads: a positive int"),
    (dict(threads=-1), TypeError, "threads: a positive int"),
    (dict(threads=2.0), TypeError, "threads: a positive int"),
    (dict(threads=True), TypeError, "threads: a positive int"),
    (dict(lanes=True), ValueError, "lanes:"),
    (dict(lanes="2"), ValueError, "lanes:"),
    (dict(lanes=2.0), ValueError, "lanes:"),
])
def test_threads_and_lanes_of_the_wrong_type(log, kw, exc, msg):
    with pytest.raises(exc, match=msg):
        imufuse_c.run_filters([imufuse_c.MadgwickAHRS(dt=0.005)], log.gyr, log.acc, log.mag,
                              **kw)


@pytest.mark.parametrize("params,msg", [
    ([dict(beta=0.1, dtype="float32")], "gives dtype='float32'"),
    ([dict(beta=0.1), dict(beta=0.2, dtype="float64")], "parameter set 1 gives dtype"),
    ([0.1, 0.2], "parameter set 0 must be a dict"),
    ("beta", "params must be a sequence"),
])
def test_run_many_parameter_sets(log, params, msg):
    with pytest.raises(TypeError, match=msg):
        imufuse_c.MadgwickAHRS.run_many(params, log.gyr, log.acc, log.mag, dt=None)
    # the same for a filter without a compiled batch path
    with pytest.raises(TypeError, match=msg.replace("beta", "k0")):
        imufuse_c.Kalman1D.run_many([{**p, "dt": 0.01} if isinstance(p, dict) else p
                                     for p in params] if not isinstance(params, str) else params,
                                    log.gyr[:, 0], log.gyr[:, 1])


# ---------------------------------------------------------------------------
# values in the filter's own precision


BIG = [(1e39, 0.0, 0.0), (0.0, -1e39, 0.0), (0.0, 0.0, 3.5e38), (np.float64(1e300), 0, 0)]


@pytest.mark.parametrize("backend", ["c", "ref"])
@pytest.mark.parametrize("offset", BIG)
def test_mag_offset_beyond_float32_is_refused_in_float32(log, backend, offset):
    """A float64 value that is inf in float32 was accepted: the state held inf and every
    later sample was rejected, gyro and accelerometer included."""
    mod = imufuse_c if backend == "c" else reference
    f = mod.RobustAHRS(dt=0.005, dtype="float32")
    with pytest.raises(ValueError, match=r"must be finite in float32"):
        f.set_mag_offset(offset)
    assert f.get_mag_offset()[0] == (0.0, 0.0, 0.0)
    # float64 holds it: accepted, and the filter still runs on gyro and accelerometer
    g = mod.RobustAHRS(dt=0.005, dtype="float64")
    g.set_mag_offset(offset)
    n = 400 if backend == "ref" else len(log.gyr)
    g.run(log.gyr[:n], log.acc[:n], log.mag[:n])
    assert g.skipped == 0


@pytest.mark.parametrize("backend", ["c", "ref"])
def test_largest_float32_offset_keeps_the_filter_alive(log, backend):
    """The largest offset float32 holds is accepted; the magnetometer reading less it is not
    usable, so the filter runs on gyro and accelerometer (no sample rejected), C and twin
    bit for bit."""
    big = float(np.finfo(np.float32).max)
    n = 400
    runs = []
    for mod in (imufuse_c, reference):
        f = mod.RobustAHRS(dt=0.005, dtype="float32")
        f.set_mag_offset((big, -big, big))
        runs.append((f.run(log.gyr[:n], log.acc[:n], log.mag[:n]), f.skipped))
    assert runs[0][1] == runs[1][1] == 0
    assert _bits(runs[0][0]).tobytes() == _bits(runs[1][0]).tobytes()


# ---------------------------------------------------------------------------
# validate: the cache covers every file the compiler read; constructors run in the child

FW_C = textwrap.dedent("""
    #include <math.h>
    #include "att.h"
    #include "sub/one.h"
    float att_theta;
    static float att_k0, att_omk0;
    void att_begin(float k0) { att_k0 = k0; att_omk0 = ONE - k0; att_theta = 0.0f; }
    #include "step.inc"
""")
STEP_INC = textwrap.dedent("""
    void att_step(float gyro, float acc_angle, float dt)
    {
        float pred, th;
        if (!isfinite(gyro) || !isfinite(acc_angle)) return;
        pred = att_theta + gyro * dt;
        th = att_omk0 * pred + att_k0 * acc_angle;
        if (isfinite(th)) att_theta = th;
    }
""")
ATT_H = ("extern float att_theta;\nvoid att_begin(float k0);\n"
         "void att_step(float gyro, float acc_angle, float dt);\n")


def _att_firmware(tmp_path, unity=False):
    from imufuse.firmware import Firmware
    (tmp_path / "sub").mkdir(exist_ok=True)
    (tmp_path / "sub" / "one.h").write_text("#define ONE 1.0f\n")
    (tmp_path / "step.inc").write_text(STEP_INC)
    (tmp_path / "att.h").write_text(ATT_H)
    if unity:
        (tmp_path / "att_impl.c").write_text(FW_C)
        (tmp_path / "unity.c").write_text('#include "att_impl.c"\n')
        src = tmp_path / "unity.c"
    else:
        (tmp_path / "att.c").write_text(FW_C)
        src = tmp_path / "att.c"
    return Firmware([str(src)], headers=["att.h"], include_dirs=[str(tmp_path)],
                    init="att_begin", update="att_step", state={"theta": "att_theta"},
                    cache_dir=str(tmp_path / "cache"))


@pytest.mark.parametrize("edit", ["sub/one.h", "step.inc", "att_impl.c"])
def test_an_edit_of_any_included_file_rebuilds(tmp_path, edit):
    """A file included from a subdirectory, with another extension, or a unity-build .c was
    not in the cache key: after an edit validate reused the old build and said bit-exact."""
    pytest.importorskip("cffi")
    from imufuse.firmware import validate_isolated
    fw = _att_firmware(tmp_path, unity=edit == "att_impl.c")
    d = sim.axis1d("fast", rate=200.0, duration=2.0, seed=3)
    params = dict(dt=0.005, k0=0.02)
    v = validate_isolated(fw, "Kalman1D", params, [d.gyr, d.acc_angle])
    assert v.bit_exact, v.text()
    p = tmp_path / edit
    text = p.read_text()
    planted = {"sub/one.h": ("1.0f", "0.999f"),
               "step.inc": ("att_k0 * acc_angle", "att_k0 * acc_angle * 1.0001f"),
               "att_impl.c": ("att_theta = 0.0f", "att_theta = 0.25f")}[edit]
    assert planted[0] in text
    p.write_text(text.replace(*planted))
    v2 = validate_isolated(fw, "Kalman1D", params, [d.gyr, d.acc_angle])
    assert not v2.bit_exact, "a stale build was reused"
    # and back: the first build is found again (the key is the content, not the time)
    p.write_text(text)
    assert validate_isolated(fw, "Kalman1D", params, [d.gyr, d.acc_angle]).bit_exact
    builds = [e for e in os.listdir(tmp_path / "cache") if e.startswith("_imufuse_fw_")]
    assert len(builds) == 2, builds


def test_the_compiler_is_part_of_the_key(tmp_path, monkeypatch):
    """Another compiler (or the same one upgraded) never reuses a build."""
    pytest.importorskip("cffi")
    from imufuse.firmware import host
    fw = _att_firmware(tmp_path)
    src = fw.source("1d", 1)
    keys = set()
    for cc in ("gcc", "cc", "gcc -fno-common"):
        monkeypatch.setenv("CC", cc)
        keys.add(fw._key(src))
    assert len(keys) == 3
    ident = host.compiler_identity()
    assert any("gcc" in part.lower() or "free software" in part.lower() for part in ident[-1:])


FW_H = textwrap.dedent("""
    typedef struct { struct { float theta; } x; float dt; } fw_t;
    void fw_init(fw_t *s, float dt, float k0);
    void fw_update(fw_t *s, float rate, float angle);
""")
FW = textwrap.dedent("""
    #include <stdlib.h>
    #include <unistd.h>
    #include "fw.h"
    __attribute__((constructor)) static void fw_ctor(void) { CTOR; }
    void fw_init(fw_t *s, float dt, float k0) { (void)k0; s->dt = dt; }
    void fw_update(fw_t *s, float rate, float angle) { (void)angle; s->x.theta += rate * s->dt; }
""")


@pytest.mark.parametrize("ctor,word", [
    ("exit(0)", "called exit(0) while being loaded"),
    ("_exit(0)", "called exit(0) while being loaded"),
    ("exit(7)", "called exit(7) while being loaded"),
    ("abort()", "crashed with SIGABRT while being loaded"),
    ("for (;;) {}", "no answer after 1.5 s while being loaded"),
])
def test_a_constructor_runs_only_in_the_child(tmp_path, ctor, word):
    """The firmware's C constructors ran in validate's own process: exit(0) made validate
    exit 0 with no output for a wrong update, an endless one hung past --timeout. Now: one
    line naming it, exit 5."""
    pytest.importorskip("cffi")
    (tmp_path / "fw.h").write_text(FW_H)
    src = tmp_path / "fw.c"
    src.write_text(FW.replace("CTOR", ctor))
    env = {**os.environ, "IMUFUSE_CACHE": str(tmp_path / "cache")}
    r = subprocess.run([sys.executable, "-m", "imufuse", "validate", str(src), "-I",
                        str(tmp_path), "--header", "fw.h", "-f", "Kalman1D", "--init",
                        "void fw_init(fw_t *s, float dt, float k0)", "--update",
                        "void fw_update(fw_t *s, float rate, float angle)", "--duration", "1",
                        "--timeout", "1.5"], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 5, (r.returncode, r.stdout, r.stderr)
    lines = [ln for ln in r.stderr.splitlines() if ln.startswith("imufuse:")]
    assert len(lines) == 1 and word in lines[0], r.stderr


# ---------------------------------------------------------------------------
# compare keeps the estimate only


@pytest.mark.parametrize("name", ["RobustAHRS", "MadgwickAHRS", "Kalman1D"])
@pytest.mark.parametrize("block", [1000, 4096])
def test_streamed_estimate_is_the_whole_runs(tmp_path, name, block):
    """Session.run(keep_states=False) runs block by block and keeps only the estimate: the
    same estimate, bit for bit, as the whole run's; no trajectory kept."""
    from imufuse import io
    d = sim.imu("fast", rate=200.0, duration=30.0, seed=2)
    path = tmp_path / "log.csv"
    io.write_log(path, d.t, d.gyr, d.acc, d.mag)
    s = Session(str(path))
    whole = s.run(name, {}, RunOptions())
    f, full, dts, _, _ = s.make(name, {}, RunOptions())
    inputs, _ = s.inputs(name)
    est = s.streamed_estimate(f, s.filter_class(name), name, full, inputs, "c", dts, None,
                              block=block)
    a = whole.estimate.angle if whole.estimate.angle is not None else whole.estimate.q
    b = est.angle if est.angle is not None else est.q
    assert _bits(a).tobytes() == _bits(b).tobytes()
    lean = s.run(name, {}, RunOptions(), keep_states=False)
    assert len(lean.states) == 0 and lean.n == len(d.t)
    c = lean.estimate.angle if lean.estimate.angle is not None else lean.estimate.q
    assert _bits(a).tobytes() == _bits(c).tobytes()


CONCURRENT = textwrap.dedent("""
    import sys
    from test_reliability3 import _att_firmware
    from pathlib import Path
    from imufuse import sim
    from imufuse.firmware import Firmware, validate_isolated
    d = Path(sys.argv[1])
    fw = Firmware([str(d / "att.c")], headers=["att.h"], include_dirs=[str(d)], init="att_begin",
                  update="att_step", state={"theta": "att_theta"}, cache_dir=str(d / "cache"))
    s = sim.axis1d("fast", rate=200.0, duration=1.0, seed=3)
    v = validate_isolated(fw, "Kalman1D", dict(dt=0.005, k0=0.02), [s.gyr, s.acc_angle])
    print("bit-exact" if v.bit_exact else "differs")
""")


def test_concurrent_builds_of_one_key(tmp_path):
    """Two validate processes building the same firmware into one cache at once (a CI
    matrix, pytest-xdist): each builds in a directory of its own and renames it into place,
    so neither loads a half-written module; both are bit-exact and nothing is left behind.
    A directory of an interrupted earlier build (no module in it) is replaced."""
    pytest.importorskip("cffi")
    fw = _att_firmware(tmp_path)
    key = fw._key(fw.source("1d", 1))
    stale = tmp_path / "cache" / key
    stale.mkdir(parents=True)
    (stale / "half.o").write_bytes(b"\0" * 100)
    # this module importable by name in the children (PYTHONPATH ahead of what is inherited)
    tests = os.path.dirname(os.path.abspath(__file__))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [tests, os.environ.get("PYTHONPATH")]))}
    procs = [subprocess.Popen([sys.executable, "-c", CONCURRENT, str(tmp_path)], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True, env=env) for _ in range(4)]
    outs = [p.communicate(timeout=300) for p in procs]
    for p, (out, errs) in zip(procs, outs):
        assert p.returncode == 0 and out.strip() == "bit-exact", errs[-2000:]
    left = sorted(os.listdir(tmp_path / "cache"))
    assert left == [key], left
    assert not (stale / "half.o").exists()


@pytest.mark.parametrize("name", ["RobustAHRS", "FusionAHRS", "Kalman1D"])
def test_run_csv_block_by_block_is_the_whole_run(tmp_path, name):
    """`imufuse run -o OUT.csv` writes block by block (keeping only the estimate); its rows are
    those of the whole run written at once (`-o OUT.npz`), every column, over several
    blocks."""
    from imufuse import io
    from imufuse.cli import main
    d = sim.imu("fast", rate=200.0, duration=200.0, seed=4)          # 40 000 samples
    log = tmp_path / "log.csv"
    io.write_log(log, d.t, d.gyr, d.acc, d.mag)
    assert main(["run", str(log), "-f", name, "-o", str(tmp_path / "a.csv")]) == 0
    assert main(["run", str(log), "-f", name, "-o", str(tmp_path / "b.npz")]) == 0
    import csv
    with open(tmp_path / "a.csv") as fh:
        rows = list(csv.reader(fh))
    head, body = rows[0], np.array(rows[1:], dtype=np.float64)
    b = np.load(tmp_path / "b.npz")
    assert sorted(head) == sorted(b.files)
    assert len(body) == len(d.t) > 2 * (1 << 14)
    for j, col in enumerate(head):
        assert _bits(body[:, j]).tobytes() == _bits(b[col].astype(np.float64)).tobytes(), col


@pytest.mark.parametrize("offset", [(1e39, 0.0, 0.0), (0.0, -4e38, 0.0), (0.0, 0.0, 1e300)])
def test_mag_offset_files_hold_float32_values(tmp_path, offset):
    """save_mag_offset and mag_offset() passed a value beyond float32 through to the file and
    back, for a float32 filter to refuse (or, before, to hold as inf): the file serves filters
    of either precision, so both refuse it, naming the file and the axis."""
    from imufuse.calibration import CalibrationError, mag_offset
    from imufuse.calibration.log import save_mag_offset
    path = tmp_path / "cal.json"
    with pytest.raises(ValueError, match=r"cal.json: mag offset [xyz]: must be finite in float32"):
        save_mag_offset(str(path), offset)
    assert not path.exists()
    # a file written by hand (or by an older imufuse) is refused when read
    import json
    path.write_text(json.dumps({"magnetometer": {"S": np.eye(3).tolist(), "h": list(offset)}}))
    with pytest.raises(CalibrationError, match=r"cal.json: magnetometer.h [xyz]: must be finite"):
        mag_offset(str(path))
    # the largest float32 value is a value a float32 filter holds
    big = float(np.finfo(np.float32).max)
    save_mag_offset(str(path), (big, 0.0, -big))
    assert mag_offset(str(path)) == (big, 0.0, -big)


def test_a_source_that_is_not_c_is_one_line(tmp_path):
    """A source the compiler reads as no C at all (a text file given by mistake): its -M
    output holds no rule; validate says the compilation failed, in one line, exit 5."""
    src = tmp_path / "notes.txt"
    src.write_text("root:x:0:0:root:/root:/bin/bash\n")
    env = {**os.environ, "IMUFUSE_CACHE": str(tmp_path / "cache")}
    r = subprocess.run([sys.executable, "-m", "imufuse", "validate", str(src), "-f", "Kalman1D",
                        "--update", "void att_step(float a, float b)", "--state", "theta=x"],
                       capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 5, r.stderr
    assert "Traceback" not in r.stderr and r.stderr.count("imufuse: error:") == 1, r.stderr
