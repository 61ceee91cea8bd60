"""The HIL examples as a user builds them, validated through the port of an emulated board:
examples/hil/baremetal with CMake for the Cortex-M4F (QEMU mps2-an386, whose DWT cycle counter
does not run: the runner says it has no counter) and the ATmega328P (simavr, Timer1 cycles),
and examples/hil/arduino/imufuse_hil compiled for the Uno by arduino-builder (the imufuse
library as `imufuse export arduino` makes it, tests/test_arduino.py's sketchbook) and run on
simavr at 115200 baud. Each is MadgwickAHRS float32 with its default settings (dt 0.01 s), so
`validate --port` must find it bit-exact. The bare-metal example's RobustAHRSQ (its default
settings, B6's code left out as the example builds it) sends all 89 state words, 356 bytes a
frame: bit-exact with the twin on both boards, through a lost and a corrupted byte.
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
from imufuse import reference
from imufuse.firmware import Board, Firmware, counts_for, csrc_firmware, validate
from imufuse.mcu import ensure_toolchains
from imufuse.reference.fixed_robust import MAG_LAYOUT
from hil_proxy import Proxy
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


N_Q = 300
#: RobustAHRSQ's default settings (imf_robust_ahrs_q_default_settings), as the example uses them
Q_PARAMS = dict(dt=0.01, gyr_scale=1.0642e-3)


def _robust_q_case(tmp_path):
    """The declaration of the example's RobustAHRSQ (a firmware around csrc/fixed/robust_q.c
    with the default settings: what the port path compares, every state word in
    reference.RobustAHRSQ's order) and N_Q samples of int16 counts."""
    (tmp_path / "att.h").write_text(
        '#include <stdint.h>\n#include "robust_q.h"\nextern imf_robust_ahrs_q_t att;\n'
        "void att_init(void);\n"
        "void att_update(const int16_t *g, const int16_t *a, const int16_t *m);\n")
    (tmp_path / "att.c").write_text(
        '#include "att.h"\nimf_robust_ahrs_q_t att;\nvoid att_init(void)\n{\n'
        "    imf_robust_ahrs_q_settings_t s;\n    imf_robust_ahrs_q_default_settings(&s);\n"
        "    (void)imf_robust_ahrs_q_init(&att, &s);\n}\n"
        "void att_update(const int16_t *g, const int16_t *a, const int16_t *m)\n{\n"
        "    imf_robust_ahrs_q_update_v(&att, g, a, m);\n}\n")
    arrays = {"q": 4, "s": 4, "c": 4, "f": 3, "v": 3, "p": 3, "b": 3, "lw": 3, "la": 3}
    exprs = [f"=att.x.imu.{k}[{i}]" for k, m in arrays.items() for i in range(m)]
    exprs += ["=att.x.imu.n", "=att.x.imu.n_rest"]
    for member, parts in MAG_LAYOUT:
        exprs += ([f"=att.x.{member}[{i}]" for i in range(len(parts))] if parts
                  else [f"=att.x.{member}"])
    names = reference.RobustAHRSQ.state_names
    assert len(names) == len(exprs) == 89
    fx = str(csrc_dir() / "fixed")
    fw = Firmware([str(tmp_path / "att.c"), str(csrc_dir() / "fixed" / "robust_q.c")],
                  headers=["att.h"], include_dirs=[str(tmp_path), fx], init="att_init",
                  update="att_update", state=dict(zip(names, exprs)),
                  cflags=["-O2", "-ffp-contract=off", "-DIMF_ROBUST_Q_B6=0"])
    d = sim.imu("fast", rate=100.0, duration=N_Q / 100.0, seed=7)
    return fw, counts_for("ahrs", Q_PARAMS, (d.gyr, d.acc, d.mag))


def _robust_q(fw, ins, port, target, baud=1_000_000):
    v = validate(fw, "RobustAHRSQ", Q_PARAMS, ins, target=target, port=port, baud=baud,
                 timeout=10)
    # every word of the twin's state after every sample, bit for bit
    assert v.bit_exact and v.got.shape == (N_Q, 89), v.text()
    assert np.array_equal(v.got, reference.RobustAHRSQ(**Q_PARAMS).run(*ins).astype(np.int64))
    assert "firmware 'example RobustAHRSQ' on the " in v.text()
    return v


def _links(v):
    return [n for n in v.notes if n.startswith("link:")]


@pytest.mark.parametrize("b6", ["OFF", "ON"])
def test_baremetal_robust_ahrs_q_full_state_on_the_m4f(tmp_path, b6):
    """356 state bytes a frame (longer than one COBS block) on QEMU, B6's code left out (as
    the example builds it) or compiled in: the same 89 words; clean and through a byte lost
    on the way to the board and one changed on the way back."""
    fw, ins = _robust_q_case(tmp_path)
    elf = _cmake(tmp_path, "arm-none-eabi.cmake", "-DHIL_FILTER=robust_ahrs_q",
                 "-DIMUFUSE_FIXED=ON", f"-DHIL_B6={b6}")
    defines = subprocess.run(["grep", "-rho", "IMF_ROBUST_Q_B6=0", str(tmp_path / "build")],
                             capture_output=True, text=True).stdout
    assert ("IMF_ROBUST_Q_B6=0" in defines) == (b6 == "OFF")
    with Board(elf=elf, target="cortex-m4f") as b:
        v = _robust_q(fw, ins, b.port, "cortex-m4f")
        assert _links(v) == []
        if b6 == "ON":
            return
        for fault, to_board, k, line in [
                ("drop", True, 57, "sample 57: the board received a corrupted frame (CRC or "
                                   "framing); sent again, recovered"),
                ("flip", False, 211, "sample 211: its answer came back corrupted (CRC); sent "
                                     "again, recovered")]:
            with Proxy(b.port, fault=fault, sample=k, to_board=to_board) as p:
                v = _robust_q(fw, ins, p.port, "cortex-m4f")
                assert p.done, "the fault was not injected"
            assert _links(v) == ["link: " + line], _links(v)


def test_baremetal_robust_ahrs_q_full_state_on_the_atmega328p(tmp_path):
    """The same on simavr's ATmega328P at 1 Mbaud: the firmware with the runner's two kept
    356-byte answers fits 2 KB of RAM with the stack the update reached; a byte of an answer
    lost on the way back is repaired."""
    fw, ins = _robust_q_case(tmp_path)
    elf = _cmake(tmp_path, "avr.cmake", "-DHIL_FILTER=robust_ahrs_q", "-DIMUFUSE_FIXED=ON")
    size = subprocess.run(["avr-size", str(elf)], capture_output=True, text=True,
                          check=True).stdout.splitlines()[-1].split()
    text, data, bss = (int(x) for x in size[:3])
    assert text + data <= 32 * 1024 - 512, (text, data)
    with Board(elf=elf, target="atmega328p") as b:
        v = _robust_q(fw, ins, b.port, "atmega328p")
        c = v.cost
        assert c.unit == "cycles" and 0 < c.min <= c.max < 131_072
        # static RAM, the deepest update's stack and the runner's frames below it
        assert c.stack is not None and data + bss + c.stack + 128 <= 2048, (data, bss, c.stack)
        with Proxy(b.port, fault="drop", sample=123, to_board=False) as p:
            v = _robust_q(fw, ins, p.port, "atmega328p")
            assert p.done, "the fault was not injected"
        assert _links(v) == ["link: sample 123: its answer came back corrupted (CRC); sent "
                             "again, recovered"], _links(v)


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
