"""The HIL examples as a user builds them, validated through the port of an emulated board:
examples/hil/baremetal with CMake for the Cortex-M4F (QEMU mps2-an386, whose DWT cycle counter
does not run: the runner says it has no counter) and the ATmega328P (simavr, Timer1 cycles),
and examples/hil/arduino/imufuse_hil compiled for the Uno by arduino-builder (the imufuse
library as `imufuse export arduino` makes it, tests/test_arduino.py's sketchbook) and run on
simavr at 115200 baud. Each is MadgwickAHRS float32 with its default settings (dt 0.01 s), so
`validate --port` must find it bit-exact.
"""
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from imufuse import sim
from imufuse.shared.resources import csrc_dir
from imufuse.catalogue import inputs_for
from imufuse.firmware import Board, csrc_firmware, validate
from imufuse.mcu import ensure_toolchains
from test_arduino import sketchbook  # noqa: F401 - the fixture

pytest.importorskip("serial")
pytestmark = pytest.mark.xdist_group("hil")

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "hil"
TOOLCHAINS = ROOT / "examples" / "firmware" / "cmake"
N = 200


@pytest.fixture(scope="module", autouse=True)
def _toolchains():
    missing = ensure_toolchains(("m4f", "avr"))
    assert not missing, f"MCU toolchains missing: {missing}"
    assert shutil.which("cmake"), "cmake (the test extra) is missing"


def _madgwick(elf, target, baud=1_000_000):
    d = sim.imu("slow", rate=100.0, duration=N / 100.0, seed=4)
    fw = csrc_firmware("MadgwickAHRS", csrc_dir(), cflags=["-O2", "-ffp-contract=off"])
    with Board(elf=elf, target=target) as b:
        return validate(fw, "MadgwickAHRS", dict(dt=0.01), inputs_for("ahrs", d), target=target,
                        port=b.port, baud=baud, timeout=10)


def _cmake(tmp_path, toolchain, *options):
    build = tmp_path / "build"
    for cmd in (["cmake", "-S", str(EXAMPLE / "baremetal"), "-B", str(build),
                 f"-DCMAKE_TOOLCHAIN_FILE={TOOLCHAINS / toolchain}", "-DIMUFUSE_FIXED=OFF",
                 *options], ["cmake", "--build", str(build)]):
        p = subprocess.run(cmd, capture_output=True, text=True)
        assert p.returncode == 0, p.stdout[-2000:] + p.stderr[-2000:]
    return build / "hil_example.elf"


def test_baremetal_example_on_the_m4f(tmp_path):
    v = _madgwick(_cmake(tmp_path, "arm-none-eabi.cmake"), "cortex-m4f")
    assert v.bit_exact and len(v.got) == N, v.text()
    assert "firmware 'example MadgwickAHRS' on the " in v.text()
    # QEMU's DWT counter does not count: no cost, said so
    assert v.cost is None and "the board's runner has no counter" in v.text()


def test_baremetal_example_on_the_atmega328p(tmp_path):
    v = _madgwick(_cmake(tmp_path, "avr.cmake", "-DHIL_BAUD=115200"), "atmega328p", 115_200)
    assert v.bit_exact and len(v.got) == N, v.text()
    c = v.cost
    assert c.unit == "cycles" and 20_000 < c.min <= c.median <= c.max < 131_072
    assert c.stack is not None and 50 < c.stack < 1024


def test_arduino_sketch_on_the_uno(sketchbook, tmp_path):  # noqa: F811 - the fixture
    base, hw, libs = sketchbook
    sketch = tmp_path / "imufuse_hil"
    shutil.copytree(EXAMPLE / "arduino" / "imufuse_hil", sketch)
    for f in ("imf_hil.c", "imf_hil.h"):            # as the sketch's comment tells users
        shutil.copy(csrc_dir() / "hil" / f, sketch / f)
    build = tmp_path / "build"
    build.mkdir()
    p = subprocess.run(["arduino-builder", "-compile", "-hardware", str(hw), "-hardware",
                        "/usr/share/arduino-builder", "-tools", "/usr/bin",
                        "-prefs=tools.ctags.path=/usr/bin", "-libraries", str(libs),
                        "-fqbn", "arduino:avr:uno", "-build-path", str(build),
                        str(sketch / "imufuse_hil.ino")], capture_output=True, text=True,
                       timeout=600)
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-3000:]
    flash = int(re.search(r"Sketch uses (\d+) bytes", p.stdout).group(1))
    ram = int(re.search(r"Global variables use (\d+) bytes", p.stdout).group(1))
    assert flash < 32_256 and ram < 2048 - 512, (flash, ram)
    v = _madgwick(build / "imufuse_hil.ino.elf", "atmega328p", 115_200)
    assert v.bit_exact and len(v.got) == N, v.text()
    assert "firmware 'MadgwickAHRS sketch' on the " in v.text() and v.cost.unit == "cycles"
    assert np.all(v.cost.counts > 0)
