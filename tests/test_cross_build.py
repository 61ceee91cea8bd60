"""csrc/ as a firmware library: warning-free cross builds, the CMake and make builds, and the
example firmware (examples/firmware) on the host and the MCUs.

Every csrc/*.c and csrc/fixed/*.c compiles with -std=c99 -Wall -Wextra -pedantic
-Wdouble-promotion -Werror -ffp-contract=off for the host, Cortex-M4F, Cortex-M0 and
ATmega328P, float32 and float64 (not AVR: its double is 32 bits; csrc/fixed reads no
precision, so its float32 compile stands for both). The example's output, the
filter state after every recorded sample, is the same on the host and on the ATmega328P
(simavr) and equals the Python reference bit for bit.
"""

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
CSRC = ROOT / "csrc"
EXAMPLE = ROOT / "examples" / "firmware"

import imufuse.mcu as mcu

import imufuse.reference as reference  # noqa: E402

TARGETS = ["host", "m4f", "m0", "avr"]
SOURCES = sorted(CSRC.glob("*.c")) + sorted((CSRC / "fixed").glob("*.c"))
PRECISIONS = {"float32": [], "float64": ["-DIMF_DOUBLE"]}
BINUTILS = {"host": "objdump", "m4f": "arm-none-eabi-objdump", "m0": "arm-none-eabi-objdump",
            "avr": "avr-objdump"}


@pytest.fixture(scope="session")
def toolchains():
    return mcu.ensure_toolchains(TARGETS)


def need(toolchains, target):
    if target in toolchains:
        pytest.skip(f"toolchain for {target} unavailable: {toolchains[target]}")


def _run(cmd, cwd=None, timeout=300):
    proc = subprocess.run([str(c) for c in cmd], cwd=cwd, capture_output=True, text=True,
                          timeout=timeout)
    assert proc.returncode == 0, f"{' '.join(map(str, cmd))}\n{proc.stdout[-3000:]}{proc.stderr[-3000:]}"
    return proc


def _compile(target, src, precision, out):
    tgt = mcu.TARGETS[target]
    cmd = [tgt.cc, *mcu.cflags(target), "-ffunction-sections", *PRECISIONS[precision],
           f"-I{CSRC}", f"-I{CSRC / 'fixed'}", "-c", src, "-o", out]
    return _run(cmd)


MAKE_ARCH = {
    "host": ("cc", "ar", ""),
    "m4f": ("arm-none-eabi-gcc", "arm-none-eabi-ar", " ".join(mcu.TARGETS["m4f"].arch_flags)),
    "m0": ("arm-none-eabi-gcc", "arm-none-eabi-ar", " ".join(mcu.TARGETS["m0"].arch_flags)),
    "avr": ("avr-gcc", "avr-ar", "-mmcu=atmega328p"),
}


@pytest.fixture(scope="module")
def libraries(toolchains, tmp_path_factory):
    """library(target, precision) -> (make's output, its build directory): csrc/Makefile run
    once per target and precision, for the tests that read the compiler's output and those
    that read the archive or the objects (the module's tests run on one worker:
    tests/conftest.py). The Makefile compiles with the contract's flags and warnings
    (mcu.cflags: -std=c99 -O2 -ffp-contract=off, -Wall -Wextra -pedantic -Wdouble-promotion
    -Werror), -ffunction-sections -fdata-sections and IMF_FIXED_PROFILE=32. float32 builds the
    whole library; float64 with FIXED=0 (csrc/*.c only: csrc/fixed compiles the same text in
    either precision, test_fixed_point_ignores_the_precision, and so the Makefile's FIXED=0 is
    tried too)."""
    if shutil.which("make") is None:
        pytest.skip("make not installed")
    d = tmp_path_factory.mktemp("make")
    made = {}

    def library(target, precision):
        need(toolchains, target)
        if (target, precision) not in made:
            cc, ar, arch = MAKE_ARCH[target]
            build = d / f"{target}-{precision}"
            proc = _run(["make", "-f", CSRC / "Makefile", f"CC={cc}", f"AR={ar}", f"ARCH={arch}",
                         f"PRECISION={precision}", f"BUILD={build}",
                         f"FIXED={int(precision == 'float32')}"], cwd=d)
            made[target, precision] = (proc, build)
        return made[target, precision]
    return library


def _build_params():
    out = []
    for src in SOURCES:
        for t in TARGETS:
            for p in PRECISIONS:
                if t == "avr" and p == "float64":
                    continue
                out.append(pytest.param(src, t, p, id=f"{src.relative_to(CSRC)}-{t}-{p}"))
    return out


def test_sources_found():
    assert any(s.name == "filters_1d.c" for s in SOURCES)


@pytest.mark.parametrize("src", [pytest.param(s, id=str(s.relative_to(CSRC)))
                                 for s in SOURCES if s.parent != CSRC])
def test_compiles_clean(toolchains, tmp_path, src):
    """No warning at all (-Werror) with the contract's flags, on every target (one item per
    fixed-point source, both profiles compiled: no IMF_FIXED_PROFILE); the compiler says
    nothing. The float32 compile stands for both precisions: csrc/fixed never reads the
    precision (test_fixed_point_ignores_the_precision), so -DIMF_DOUBLE compiles the same
    text. csrc/*.c: test_makefile_library (the Makefile compiles them with these flags, in
    both precisions; IMF_FIXED_PROFILE concerns csrc/fixed only)."""
    for p in _build_params():
        if p.values[0] != src or p.values[2] != "float32":
            continue
        _, target, precision = p.values
        need(toolchains, target)
        proc = _compile(target, src, precision, tmp_path / "x.o")
        assert proc.stderr.strip() == "", (target, precision, proc.stderr)


def test_only_fixed_point_reads_the_profile():
    """What lets test_compiles_clean leave csrc/*.c to the Makefile's build: only csrc/fixed
    reads IMF_FIXED_PROFILE (the Makefile defines it; the contract's compile does not)."""
    assert any("IMF_FIXED_PROFILE" in s.read_text() for s in (CSRC / "fixed").glob("*.[ch]"))
    assert not [s.name for s in CSRC.glob("*.[ch]") if "IMF_FIXED_PROFILE" in s.read_text()]


def test_fixed_point_ignores_the_precision():
    """What lets test_compiles_clean compile csrc/fixed in one precision: no fixed-point file
    names IMF_DOUBLE or imf_real, and they include no header outside csrc/fixed but the
    standard library's."""
    for f in sorted((CSRC / "fixed").glob("*.[ch]")):
        text = f.read_text()
        assert "IMF_DOUBLE" not in text and "imf_real" not in text, f.name
        for inc in re.findall(r'#\s*include\s*"([^"]+)"', text):
            assert (CSRC / "fixed" / inc).is_file(), (f.name, inc)


DOUBLE_ROUTINE = re.compile(r"^(__aeabi_d\w+|__aeabi_f2d|__aeabi_[il]2d|__\w*df\d?|sqrt|sin|cos|atan2|asin)$")


def _double_calls_in_updates(objdump, obj):
    """{function section: [double routines it references]} for the ..._update functions."""
    text = _run([objdump, "-r", obj]).stdout
    found = {}
    section = None
    for line in text.splitlines():
        m = re.match(r"RELOCATION RECORDS FOR \[(.*)\]:", line)
        if m:
            section = m.group(1)
            continue
        parts = line.split()
        if section and section.endswith("_update") and len(parts) >= 3 and DOUBLE_ROUTINE.match(parts[-1]):
            found.setdefault(section, []).append(parts[-1])
    return found


@pytest.mark.parametrize("target", ["m0", "m4f"])
@pytest.mark.parametrize("src", [s for s in SOURCES if s.parent == CSRC], ids=lambda s: s.name)
def test_float32_updates_use_no_double(libraries, src, target):
    """A float32 build never computes in double inside an update: no soft-double routine
    (__aeabi_d*, __*df*) and no double sqrt is referenced from any *_update function (the
    object of the Makefile's float32 build: -ffunction-sections)."""
    _, build = libraries(target, "float32")
    obj = build / f"{src.stem}.o"
    assert obj.is_file(), obj
    found = _double_calls_in_updates(BINUTILS[target], obj)
    assert not found, f"double arithmetic in float32 updates: {found}"


def test_double_check_can_fail(toolchains, tmp_path):
    need(toolchains, "m0")
    src = tmp_path / "bad.c"
    src.write_text("float imf_bad_update(float x);\n"
                   "float imf_bad_update(float x) { return (float)((double)x * 1.1); }\n")
    obj = tmp_path / "bad.o"
    _run(["arm-none-eabi-gcc", *mcu.cflags("m0"), "-ffunction-sections", "-c", src, "-o", obj])
    assert _double_calls_in_updates("arm-none-eabi-objdump", obj)


# --------------------------------------------------------------------------------------------
# the library builds


@pytest.mark.parametrize("target", TARGETS)
def test_makefile_library(libraries, target):
    """csrc/Makefile builds libimufuse.a for each target and precision, every source in it
    (float64: FIXED=0, csrc/*.c only, see libraries), and the compiler says nothing (no
    warning at all with the contract's flags: -Werror)."""
    _, ar, _ = MAKE_ARCH[target]
    for prec in ("float32", "float64") if target != "avr" else ("float32",):
        proc, build = libraries(target, prec)
        assert proc.stderr.strip() == "", (target, prec, proc.stderr)
        members = _run([ar, "t", build / "libimufuse.a"]).stdout.split()
        want = SOURCES if prec == "float32" else [s for s in SOURCES if s.parent == CSRC]
        assert sorted(members) == sorted(s.stem + ".o" for s in want)


def _reference_lines():
    """The example's expected output, from the Python reference and the recorded samples."""
    text = (EXAMPLE / "recorded_samples.h").read_text()
    vals = [float.fromhex(v) for v in re.findall(r"(-?0x[0-9a-f.]+p[-+]?\d+)f", text)]
    samples = np.array(vals, dtype=np.float32).reshape(-1, 2)
    assert len(samples) == int(re.search(r"RECORDED_N (\d+)u", text).group(1))
    f = reference.Mahony1DBias(dt=0.01, kp=2.0, ki=0.3, dtype="float32")
    states = f.run(samples[:, 0], samples[:, 1]).view(np.uint32)
    lines = [f"{a:08x} {b:08x}" for a, b in states]
    return lines + [f"skipped {f.skipped:08x}", "end"]


def test_example_make_host_and_avr(toolchains, tmp_path):
    """examples/firmware with plain make: the host program and the ATmega328P program (run in
    simavr) print the reference's states bit for bit; the Cortex-M ELFs link."""
    if shutil.which("make") is None:
        pytest.skip("make not installed")
    want = _reference_lines()
    # a copy of the tree's layout: the example's Makefile finds the library as ../../csrc
    work = tmp_path / "examples" / "firmware"
    shutil.copytree(EXAMPLE, work, ignore=shutil.ignore_patterns("build"))
    shutil.copytree(CSRC, tmp_path / "csrc", ignore=shutil.ignore_patterns("build"))
    make = ["make"]
    need(toolchains, "host")
    _run([*make, "TARGET=host"], cwd=work)
    host = _run([work / "build" / "host" / "example"]).stdout.splitlines()
    assert host == want
    for t in ("m4f", "m0"):
        if t not in toolchains:
            _run([*make, f"TARGET={t}"], cwd=work)
            assert (work / "build" / t / "example.elf").is_file()
    if "avr" not in toolchains:
        _run([*make, "TARGET=avr"], cwd=work)
        elf = work / "build" / "avr" / "example.elf"
        out = subprocess.run(["simavr", "-m", "atmega328p", "-f", "16000000", str(elf)],
                             capture_output=True, text=True, timeout=120)
        text = mcu._simavr_text(out.stdout + out.stderr)
        got = [ln for ln in text.splitlines() if re.fullmatch(r"[0-9a-f]{8} [0-9a-f]{8}|skipped \w+|end", ln)]
        assert got == want


@pytest.mark.parametrize("target", ["host", "m4f", "avr"])
def test_example_cmake(toolchains, tmp_path, target):
    """examples/firmware with CMake (csrc/ joins by add_subdirectory) for the host (run and
    compared with the reference) and, through the toolchain files, Cortex-M4F and ATmega328P."""
    if shutil.which("cmake") is None:
        pytest.skip("cmake not installed")
    need(toolchains, target)
    args = {"host": [], "m4f": [f"-DCMAKE_TOOLCHAIN_FILE={EXAMPLE / 'cmake' / 'arm-none-eabi.cmake'}",
                                "-DIMUFUSE_ARM_CORE=m4f"],
            "avr": [f"-DCMAKE_TOOLCHAIN_FILE={EXAMPLE / 'cmake' / 'avr.cmake'}"]}[target]
    build = tmp_path / "b"
    _run(["cmake", "-S", EXAMPLE, "-B", build, *args])
    _run(["cmake", "--build", build])
    if target == "host":
        assert _run([build / "example"]).stdout.splitlines() == _reference_lines()
    else:
        assert (build / "example.elf").is_file()


def test_cmake_rejects_double_on_avr(toolchains, tmp_path):
    if shutil.which("cmake") is None:
        pytest.skip("cmake not installed")
    need(toolchains, "avr")
    proc = subprocess.run(["cmake", "-S", str(EXAMPLE), "-B", str(tmp_path / "b"),
                           f"-DCMAKE_TOOLCHAIN_FILE={EXAMPLE / 'cmake' / 'avr.cmake'}", "-DIMF_DOUBLE=ON"],
                          capture_output=True, text=True)
    assert proc.returncode != 0 and "64-bit double" in proc.stderr
