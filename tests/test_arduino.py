"""The Arduino library (`imufuse export arduino DIR --zip`), as a new user takes it: the zip
unpacked into a sketchbook's libraries/ (what the IDE's "Add .ZIP Library" does), every example
compiled for the Uno (arduino:avr:uno) by arduino-builder, run on simavr (ATmega328P at 16 MHz,
the UART captured), and every printed quaternion compared bit for bit with imufuse's
(imufuse_c, the same parameters and samples; for MadgwickAHRS also `imufuse run` on the
example's input.csv). The flash and RAM the Arduino build reports are the docs' table.

Debian 12's arduino-core-avr (1.8.7+dfsg-1~deb12u1) does not compile its own
cores/arduino/WString.cpp with Debian's avr-gcc 5.4 (DECIMAL_DIG is undeclared, and two array
bounds that depend on it are not constant). The tests build a copy of /usr/share/arduino/hardware
with DECIMAL_DIG replaced by 17 and the two bounds by 64, and never touch the system's files
(docs/firmware.md describes this patch for users of Debian's arduino-builder).
"""
import re
import shutil
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

import imufuse
from imufuse.tools.arduino import EXAMPLES, reference_states
from imufuse.mcu import INSTALL_SCRIPT

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs" / "firmware.md"
TOOLS = ("arduino-builder", "simavr", "avr-gcc")


@pytest.fixture(scope="module")
def sketchbook(tmp_path_factory):
    if any(shutil.which(t) is None for t in TOOLS) or not Path("/usr/share/arduino/hardware").is_dir():
        subprocess.run(["sh", str(INSTALL_SCRIPT)], capture_output=True, text=True)
    missing = [t for t in TOOLS if shutil.which(t) is None]
    assert not missing, f"missing {missing}: tools/install-toolchains.sh installs them"
    base = tmp_path_factory.mktemp("arduino")
    hw = base / "hardware"
    shutil.copytree("/usr/share/arduino/hardware", hw)
    ws = hw / "arduino" / "avr" / "cores" / "arduino" / "WString.cpp"
    text = ws.read_text()
    assert "DECIMAL_DIG" in text, "arduino-core-avr changed: check whether the patch is needed"
    ws.write_text(text.replace("DECIMAL_DIG", "17").replace("char buf[FLOAT_BUF_SIZE];", "char buf[64];")
                  .replace("char buf[DOUBLE_BUF_SIZE];", "char buf[64];"))
    out = base / "out"
    p = subprocess.run([sys.executable, "-m", "imufuse", "export", "arduino", str(out), "--zip"],
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    libs = base / "sketchbook" / "libraries"
    libs.mkdir(parents=True)
    with zipfile.ZipFile(out / f"imufuse-{imufuse.__version__}.zip") as z:
        assert {n.split("/")[0] for n in z.namelist()} == {"imufuse"}
        z.extractall(libs)
    return base, hw, libs


def test_docs_describe_the_core_patch():
    """The patch of the fixture above, as docs/firmware.md's Arduino section tells users."""
    text = DOCS.read_text()
    section = text[text.index("## The C library in an Arduino sketch"):]
    for words in ("WString.cpp", "`DECIMAL_DIG` by 17", "`char buf[64]`", "char buf[FLOAT_BUF_SIZE]",
                  "char buf[DOUBLE_BUF_SIZE]", "-hardware"):
        assert words in section, words


def _build(sketchbook, name):
    base, hw, libs = sketchbook
    build = base / f"build-{name}"
    build.mkdir(exist_ok=True)
    p = subprocess.run(["arduino-builder", "-compile", "-hardware", str(hw), "-hardware",
                        "/usr/share/arduino-builder", "-tools", "/usr/bin",
                        "-prefs=tools.ctags.path=/usr/bin", "-libraries", str(libs),
                        "-fqbn", "arduino:avr:uno", "-build-path", str(build),
                        str(libs / "imufuse" / "examples" / name / f"{name}.ino")],
                       capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-3000:]
    flash = int(re.search(r"Sketch uses (\d+) bytes", p.stdout).group(1))
    ram = int(re.search(r"Global variables use (\d+) bytes", p.stdout).group(1))
    return build / f"{name}.ino.elf", flash, ram


def _simavr(elf, timeout=120.0):
    """simavr's UART lines until the sketch prints 'end' (a sketch never exits)."""
    proc = subprocess.Popen(["simavr", "-m", "atmega328p", "-f", "16000000", str(elf)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    lines, t0 = [], time.monotonic()
    try:
        for raw in proc.stdout:
            line = re.sub(r"\x1b\[[0-9;]*m", "", raw.decode(errors="replace")).strip().rstrip(".")
            if line:
                lines.append(line)
            if line == "end" or time.monotonic() - t0 > timeout:
                break
    finally:
        proc.kill()
        proc.wait()
    return lines


def _doc_row(name):
    m = re.search(rf"^\| `{name}` \| (\d+) \| (\d+) \| (\d+) \|", DOCS.read_text(), re.M)
    assert m, f"docs/firmware.md has no Arduino table row for {name}"
    return tuple(int(v) for v in m.groups())


@pytest.mark.parametrize("name", list(EXAMPLES))
def test_example_on_the_uno(sketchbook, name):
    elf, flash, ram = _build(sketchbook, name)
    out = _simavr(elf)
    assert out and out[-1] == "end", out[-5:]
    got = [ln for ln in out if re.fullmatch(r"q( [0-9a-f]{8}){4}", ln)]
    want = [f"q {' '.join(f'{v:08x}' for v in row)}" for row in reference_states(name)]
    assert got == want
    us = int(next(ln for ln in out if ln.startswith("us/update")).split()[1])
    assert us > 0
    assert _doc_row(name) == (flash, ram, us)


def test_madgwick_example_equals_imufuse_run(sketchbook, tmp_path):
    """The README path of a new user: the sketch's input.csv through `imufuse run`."""
    _, _, libs = sketchbook
    csv = libs / "imufuse" / "examples" / "MadgwickAHRS" / "input.csv"
    p = subprocess.run([sys.executable, "-m", "imufuse", "run", str(csv), "-f", "MadgwickAHRS",
                        "--dtype", "float32", "--init", "identity", "--fixed-rate", "-o",
                        str(tmp_path / "out.npz")], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    d = np.load(tmp_path / "out.npz")
    q = np.column_stack([d[k] for k in ("q0", "q1", "q2", "q3")])
    assert q.dtype == np.float32
    assert np.array_equal(q.view(np.uint32), reference_states("MadgwickAHRS"))


def test_library_layout(sketchbook):
    _, _, libs = sketchbook
    lib = libs / "imufuse"
    props = dict(ln.split("=", 1) for ln in (lib / "library.properties").read_text().splitlines() if ln)
    assert props["name"] == "imufuse" and props["version"] == imufuse.__version__
    assert {"sentence", "paragraph", "category", "url", "architectures", "author",
            "maintainer"} <= set(props)
    kw = (lib / "keywords.txt").read_text()
    assert "imf_madgwick_t\tKEYWORD1" in kw and "imf_madgwick_update\tKEYWORD2" in kw
    assert (lib / "src" / "imufuse.h").is_file() and (lib / "src" / "fixed" / "mahony_q.c").is_file()
    for name in EXAMPLES:
        for f in (f"{name}.ino", "example_data.h", "input.csv"):
            assert (lib / "examples" / name / f).is_file()


def test_export_never_overwrites(tmp_path):
    (tmp_path / "imufuse").mkdir()
    p = subprocess.run([sys.executable, "-m", "imufuse", "export", "arduino", str(tmp_path)],
                       capture_output=True, text=True)
    assert p.returncode == 3 and "exists" in p.stderr
