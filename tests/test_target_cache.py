"""The program cache of `imufuse validate --target`: a firmware validated again (another log,
the same log, a CI matrix) reuses the program built before, with nothing compiled or linked,
and reports the same; any change that can change the program builds it again.

The firmware is examples/firmware-tests/cf.c (Eq. 2.2), or a copy of it whose header and an
included file of another extension live in other directories. Each test keeps its cache in
its own directory. Whether the compiler ran is read from the build's own steps (the compile
and link runs of imufuse.firmware.target_build counted), and from the cache's directory (no
new entry, the entry's files untouched).
"""
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap

import numpy as np
import pytest

from imufuse import sim
from imufuse.firmware import Firmware, FirmwareError, target_build, validate
from imufuse.mcu import ensure_toolchains

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FW = os.path.join(ROOT, "examples", "firmware-tests")
FLAGS = ["-O2", "-ffp-contract=off"]

pytestmark = pytest.mark.emulator


@pytest.fixture(scope="module", autouse=True)
def _toolchains():
    missing = ensure_toolchains(("m4f", "avr"))
    assert not missing, f"MCU toolchains missing: {missing}"


@pytest.fixture
def builds(monkeypatch):
    """The compile and link runs of target builds, counted."""
    n = {"runs": 0}
    run, run_all = target_build._run, target_build._run_all

    def counted_run(*a, **k):
        n["runs"] += 1
        return run(*a, **k)

    def counted_run_all(jobs, cwd):
        n["runs"] += len(jobs)
        return run_all(jobs, cwd)
    monkeypatch.setattr(target_build, "_run", counted_run)
    monkeypatch.setattr(target_build, "_run_all", counted_run_all)
    return n


def _copy(tmp_path):
    """cf.c in src/ including inc2/fault.inc where the fault goes (empty: Eq. 2.2), its
    header in inc/."""
    for d in ("src", "inc", "inc2"):
        (tmp_path / d).mkdir()
    text = open(os.path.join(FW, "cf.c")).read()
    assert text.count("/* FAULT */") == 1
    (tmp_path / "src" / "cf.c").write_text(text.replace("/* FAULT */", '#include "fault.inc"'))
    shutil.copy(os.path.join(FW, "cf.h"), tmp_path / "inc" / "cf.h")
    (tmp_path / "inc2" / "fault.inc").write_text("/* none */\n")
    return tmp_path


def _fw(cache, src=os.path.join(FW, "cf.c"), incs=(FW,), cflags=FLAGS, defines=None):
    return Firmware([str(src)], headers=["cf.h"], include_dirs=[str(d) for d in incs],
                    init="cf_init", update="cf_update", state={"theta": "theta"},
                    cflags=list(cflags), defines=defines, cache_dir=str(cache))


def _log(n=200, seed=1):
    d = sim.axis1d("slow", rate=200.0, duration=n / 200.0, seed=seed)
    return dict(dt=d.dt, T=0.5), (d.gyr, d.acc_angle)


def _validate(fw, target="cortex-m4f", n=200, seed=1, explain=True):
    params, ins = _log(n, seed)
    return validate(fw, "Complementary1D", params, ins, target=target, explain=explain)


def _entries(cache):
    d = cache / "targets"
    return sorted(os.listdir(d)) if d.is_dir() else []


def _stamps(cache):
    """Every file of the cache with its modification time (ns)."""
    out = {}
    for dirpath, _, files in os.walk(cache):
        for f in files:
            p = os.path.join(dirpath, f)
            out[p] = os.stat(p).st_mtime_ns
    return out


def _bits(v):
    return np.ascontiguousarray(v.got).view(np.uint8).tobytes()


@pytest.mark.parametrize("target", ["cortex-m4f", "atmega328p"])
def test_the_same_firmware_again_is_a_hit(tmp_path, builds, target):
    """The second validation of a firmware, on the same log and on another, compiles and
    links nothing, writes nothing to the cache (its files; the entry's time says it was
    used), and is bit-exact with the same states, cost
    and notes as the first; the build time says it was cached."""
    cache = tmp_path / "cache"
    first = _validate(_fw(cache), target)
    assert first.bit_exact, first.text()
    assert builds["runs"] > 0 and first.timing["build_cached"] == 0.0
    entries, stamps = _entries(cache), _stamps(cache)
    assert len(entries) == 1 and not any(".part-" in e for e in entries)
    builds["runs"] = 0
    again = _validate(_fw(cache), target)
    assert builds["runs"] == 0
    assert _entries(cache) == entries and _stamps(cache) == stamps
    assert again.bit_exact and again.timing["build_cached"] == 1.0
    assert _bits(again) == _bits(first)
    assert again.cost.counts.tolist() == first.cost.counts.tolist()
    for f in ("flash", "ram", "stack", "library", "library_flash", "min", "max", "median"):
        assert getattr(again.cost, f) == getattr(first.cost, f), f
    assert again.notes == first.notes and again.text() == first.text()
    # another log, longer: the same program (the inputs are written at run time)
    other = _validate(_fw(cache), target, n=300, seed=7)
    assert builds["runs"] == 0 and _stamps(cache) == stamps
    assert other.bit_exact and len(other.got) == 300


def test_a_fault_is_reported_the_same_from_the_cache(tmp_path, builds):
    """A stack overflow on a hit names the sample and the frame (-fstack-usage) as the
    build did."""
    d = _copy(tmp_path)
    (d / "inc2" / "fault.inc").write_text(
        "if (s->n == 50u) { volatile float big[5000]; uint32_t i; for (i = 0u; i < 5000u; ++i)"
        " { big[i] = angle; } s->theta += big[7] * 0.0f; }\n")
    cache = tmp_path / "cache"
    msgs = []
    for _ in range(2):
        builds["runs"] = 0
        with pytest.raises(FirmwareError) as e:
            _validate(_fw(cache, d / "src" / "cf.c", (d / "inc", d / "inc2")), "cortex-m0")
        msgs.append((str(e.value), builds["runs"]))
    assert "stack overflow" in msgs[0][0] and "B of stack (-fstack-usage)" in msgs[0][0]
    assert msgs[1][0] == msgs[0][0] and msgs[0][1] > 0 and msgs[1][1] == 0


def test_json_and_junit_say_cached(tmp_path):
    from imufuse.firmware.report import junit_xml, report_dict
    cache = tmp_path / "cache"
    _validate(_fw(cache))
    v = _validate(_fw(cache))
    rep = report_dict(v)
    assert rep["timing"]["build_cached"] is True and rep["timing"]["build"] >= 0
    assert "cached" in junit_xml(rep)


def test_an_edited_include_misses(tmp_path, builds):
    """An edit of a file included from another directory (an .inc, then the header) builds
    again, and the new code is what is validated."""
    d = _copy(tmp_path)
    cache = tmp_path / "cache"

    def fw():
        return _fw(cache, d / "src" / "cf.c", (d / "inc", d / "inc2"))
    assert _validate(fw()).bit_exact
    assert len(_entries(cache)) == 1
    builds["runs"] = 0
    (d / "inc2" / "fault.inc").write_text("s->theta = s->theta * 1.0001f;\n")
    v = _validate(fw(), explain=False)
    assert builds["runs"] > 0 and v.timing["build_cached"] == 0.0
    assert not v.bit_exact
    assert len(_entries(cache)) == 2
    builds["runs"] = 0
    (d / "inc2" / "fault.inc").write_text("/* none */\n")
    assert _validate(fw()).bit_exact and builds["runs"] == 0         # the first program
    with open(d / "inc" / "cf.h", "a") as fh:
        fh.write("/* edited */\n")
    assert _validate(fw()).bit_exact and builds["runs"] > 0
    assert len(_entries(cache)) == 3


def test_other_flags_or_defines_miss(tmp_path, builds):
    cache = tmp_path / "cache"
    assert _validate(_fw(cache)).bit_exact
    for i, fw in enumerate([_fw(cache, cflags=["-O1", "-ffp-contract=off"]),
                            _fw(cache, defines={"CF_UNUSED": "1"})]):
        builds["runs"] = 0
        v = _validate(fw)
        assert v.bit_exact and builds["runs"] > 0 and v.timing["build_cached"] == 0.0
        assert len(_entries(cache)) == i + 2


@pytest.mark.parametrize("damage", ["truncate", "meta", "missing"])
def test_a_damaged_entry_is_rebuilt(tmp_path, builds, damage):
    cache = tmp_path / "cache"
    first = _validate(_fw(cache))
    (entry,) = _entries(cache)
    e = cache / "targets" / entry
    elf = next(p for p in e.iterdir() if p.suffix == ".elf")
    if damage == "truncate":
        elf.write_bytes(elf.read_bytes()[:1000])
    elif damage == "meta":
        (e / "program.json").write_text("{")
    else:
        elf.unlink()
    builds["runs"] = 0
    v = _validate(_fw(cache))
    assert builds["runs"] > 0 and v.bit_exact and _bits(v) == _bits(first)
    assert _entries(cache) == [entry]
    builds["runs"] = 0
    assert _validate(_fw(cache)).bit_exact and builds["runs"] == 0   # stored whole again


def test_an_unwritable_cache_just_builds(tmp_path, builds):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    v = _validate(_fw(blocker / "cache"))
    assert v.bit_exact and builds["runs"] > 0


def test_the_cache_keeps_its_bound(tmp_path, builds, monkeypatch):
    """With room for one program, validating another removes the first (the least recently
    used), which then builds again, bit for bit the same (tests/test_cache_bound.py: the
    bound itself)."""
    cache = tmp_path / "cache"
    first = _validate(_fw(cache))
    (entry,) = _entries(cache)
    e = cache / "targets" / entry
    size = sum(f.stat().st_size for f in e.iterdir())
    monkeypatch.setenv("IMUFUSE_CACHE_MAX_MB", str(1.5 * size / 1e6))
    assert _validate(_fw(cache, defines={"CF_OTHER": 1})).bit_exact
    (other,) = _entries(cache)
    assert other != entry
    builds["runs"] = 0
    again = _validate(_fw(cache))
    assert builds["runs"] > 0 and _bits(again) == _bits(first) and _entries(cache) == [entry]


CONCURRENT = textwrap.dedent("""
    import sys
    from test_target_cache import _fw, _validate
    v = _validate(_fw(sys.argv[1]))
    print("bit-exact" if v.bit_exact else "differs")
""")


def test_concurrent_validations_of_one_key(tmp_path):
    """Validations of one firmware at once into one cache (a CI matrix): each builds in a
    directory of its own and renames it into place; all bit-exact, one entry left."""
    cache = tmp_path / "cache"
    # this module importable by name in the children (PYTHONPATH ahead of what is inherited)
    tests = os.path.dirname(os.path.abspath(__file__))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [tests, os.environ.get("PYTHONPATH")]))}
    procs = [subprocess.Popen([sys.executable, "-c", CONCURRENT, str(cache)], env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for _ in range(3)]
    outs = [p.communicate(timeout=300) for p in procs]
    for p, (out, err) in zip(procs, outs):
        assert p.returncode == 0 and out.strip() == "bit-exact", err[-2000:]
    (entry,) = _entries(cache)
    assert (cache / "targets" / entry / "program.json").is_file()
    v = _validate(_fw(cache))
    assert v.bit_exact and v.timing["build_cached"] == 1.0


def test_a_validation_leaves_no_build_behind(tmp_path, monkeypatch):
    """Each validation's build directory is removed whatever the outcome: bit-exact (built,
    then from the cache), refused after the build (a float32 firmware asked for float64: the
    state's types are known only once built), or failed on the emulator. (Refused, a
    validation left 2.5 MB in the temporary directory each time.)"""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    cache = tmp_path / "cache"
    assert _validate(_fw(cache)).bit_exact and _validate(_fw(cache)).bit_exact
    params, ins = _log(50)
    with pytest.raises(FirmwareError, match="float32 on the cortex-m4f, asked to compare with "
                       "float64"):
        validate(_fw(tmp_path / "c2"), "Complementary1D", params, ins, dtype="float64",
                 target="cortex-m4f")
    src = _copy(tmp_path)
    (src / "inc2" / "fault.inc").write_text("{ extern void exit(int); if (s->n == 5u) exit(3); }\n")
    with pytest.raises(FirmwareError, match=r"exit\(3\) at sample 4"):
        _validate(_fw(tmp_path / "c3", src / "src" / "cf.c", (src / "inc", src / "inc2")), n=50)
    # what stays is the cache of the harness's port objects, one per user
    assert sorted(p.name for p in tmp.iterdir()) == [f"imf_fw_ports_{os.getuid()}"]
