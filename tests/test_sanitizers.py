"""csrc and csrc/fixed under AddressSanitizer and UndefinedBehaviorSanitizer,
driven with random and extreme inputs (tests/hostile_c), and a bounded
coverage-guided fuzzing run (libFuzzer, clang) of the same drivers.

The float driver checks the C-level invariants of the valid-attitude policy
after every update (docs/robustness.md) for every float configuration of the
test registry (its table is generated: tests/hostile_c/hostile_table.py), the variometer
and FusionAHRS; the fixed-point driver relies on the
sanitizers (no int16 input may cause undefined behaviour). The fuzzing time
per target is IMUFUSE_FUZZ_SECONDS (default 15 s); the number of executions
is printed (pytest -s)."""
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

import hostile_table as table  # tests/hostile_c (on the suite's pythonpath): the drivers' filter tables

ROOT = Path(__file__).resolve().parents[1]
CSRC = ROOT / "csrc"
DRIVERS = ROOT / "tests" / "hostile_c"
SAN = ["-fsanitize=address,undefined", "-fno-sanitize-recover=all"]
BASE = ["-std=c99", "-O1", "-g", "-ffp-contract=off", f"-I{CSRC}", f"-I{CSRC / 'fixed'}"]
TARGETS = {
    "float32": ("float_filters.c", sorted(CSRC.glob("*.c")), []),
    "float64": ("float_filters.c", sorted(CSRC.glob("*.c")), ["-DIMF_DOUBLE"]),
    "fixed": ("fixed_filters.c", sorted((CSRC / "fixed").glob("*.c")), []),
}
ENV = {**os.environ, "ASAN_OPTIONS": "detect_leaks=0:abort_on_error=0",
       "UBSAN_OPTIONS": "print_stacktrace=1:halt_on_error=1"}


def _compiler(*names):
    for n in names:
        if shutil.which(n):
            return n
    pytest.skip(f"none of {names} installed (tools/install-toolchains.sh)")


def _build(cc, target, out, extra):
    driver, sources, macros = TARGETS[target]
    gen = out.parent / "generated"
    gen.mkdir(exist_ok=True)
    (gen / "hostile_table.h").write_text(table.table_header())
    (gen / "hostile_table_q.h").write_text(table.fixed_table_header())
    cmd = [cc, *BASE, f"-I{gen}", *SAN, *macros, *extra, str(DRIVERS / driver), *map(str, sources),
           "-lm", "-o", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    if proc.returncode != 0 and "sanitizer" in proc.stderr and "cannot find" in proc.stderr:
        pytest.skip(f"{cc}: sanitizer runtime missing: {proc.stderr[-300:]}")
    assert proc.returncode == 0, proc.stderr[-3000:]


@pytest.mark.parametrize("target", TARGETS)
def test_random_and_extreme_inputs_under_sanitizers(tmp_path, target):
    exe = tmp_path / "driver"
    _build(_compiler("gcc", "clang", "cc"), target, exe, [])
    proc = subprocess.run([str(exe), "100000", "12345"], capture_output=True, text=True,
                          timeout=600, env=ENV)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-4000:]
    lines = proc.stdout.splitlines()
    if target != "fixed":
        # every registry configuration (the recommended filter among them), the variometer
        # and Fusion
        want = [c.id for c in table.cases()] + ["VarioKF", "FusionAHRS-rejection"]
        assert [ln.split(":")[0] for ln in lines] == want, proc.stdout
        assert {"RobustAHRS-quick", "RobustIMU-defaults"} <= set(want)
    else:   # every fixed-point registry configuration, in both profiles where they differ
        want = [n for n, _ in table.fixed_configurations()]
        assert [ln.split(":")[0] for ln in lines] == want, proc.stdout
        assert {"MahonyIMUQ/q8", "MahonyIMUQ/q32", "MultiWiiQ-extreme"} <= set(want)
    print(proc.stdout)


@pytest.mark.parametrize("target", TARGETS)
def test_coverage_guided_fuzzing(tmp_path, target):
    cc = _compiler("clang", "clang-14")
    exe = tmp_path / "fuzz"
    try:
        _build(cc, target, exe, ["-fsanitize=fuzzer", "-DIMF_FUZZ"])
    except AssertionError as e:
        if "fuzzer" in str(e) and ("cannot find" in str(e) or "unsupported" in str(e)):
            pytest.skip(f"libFuzzer runtime missing (libclang-rt-14-dev): {e}")
        raise
    corpus = tmp_path / "corpus"
    corpus.mkdir()
    seconds = int(os.environ.get("IMUFUSE_FUZZ_SECONDS", "15"))
    # csrc allocates nothing: the process's memory is libFuzzer's own (corpus, feature
    # tables, ASan quarantine), seen above 3 GB in 15 s on a loaded machine; inputs are
    # capped at 200 samples and the RSS limit only guards the machine
    proc = subprocess.run([str(exe), f"-max_total_time={seconds}", "-print_final_stats=1",
                           "-max_len=1201", "-rss_limit_mb=6144", str(corpus)], capture_output=True, text=True,
                          timeout=seconds + 300, env=ENV, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-4000:]
    runs = int(re.search(r"stat::number_of_executed_units:\s*(\d+)", proc.stderr).group(1))
    print(f"{target}: {runs} executions in {seconds} s, no finding")
    assert runs > 1000
