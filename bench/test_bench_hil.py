"""Hardware in the loop (`imufuse validate --port`) through the emulated boards' UARTs
(pytest-benchmark; `pytest bench/test_bench_hil.py -s`).

- Throughput: samples per second through the pseudo-terminal at 115 200 and 1 000 000 baud, on
  QEMU's Cortex-M4F (its UART's baud rate is nominal: bytes pass as fast as the host moves
  them) and simavr's ATmega328P (its UART runs at the baud rate in simulated time), for the
  example firmware (examples/firmware-tests/cf.c, Eq. 2.2) and imufuse's MadgwickIMU.
- A long log: 10 minutes at 200 Hz (120 000 samples) of MadgwickIMU through the ATmega328P at
  1 Mbaud, every sample compared.
- The runner's size on the ATmega328P: examples/hil/baremetal built by avr-gcc (-O2) with
  MadgwickAHRS float32 and with RobustAHRSQ (all 89 state words), with and without the runner.

extra_info holds the figures bench/RESULTS.md lists.
"""
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from imufuse import sim
from imufuse.shared.resources import csrc_dir
from imufuse.firmware import (DEFAULT_CFLAGS, Board, Firmware, build_board, csrc_firmware,
                              validate)
from imufuse.mcu import ensure_toolchains

ROOT = Path(__file__).resolve().parents[1]
FW = str(ROOT / "examples" / "firmware-tests")


@pytest.fixture(scope="module", autouse=True)
def _toolchains():
    missing = ensure_toolchains(("m4f", "avr"))
    assert not missing, f"MCU toolchains missing: {missing}"


def _cf(seconds):
    d = sim.axis1d("slow", rate=200.0, duration=seconds, seed=1)
    fw = Firmware([os.path.join(FW, "cf.c")], headers=["cf.h"], include_dirs=[FW], init="cf_init",
                  update="cf_update", state={"theta": "theta"}, cflags=list(DEFAULT_CFLAGS))
    return fw, "Complementary1D", dict(dt=d.dt, T=0.5), (d.gyr, d.acc_angle)


def _madgwick(seconds):
    d = sim.imu("slow", rate=200.0, duration=seconds, seed=1)
    fw = csrc_firmware("MadgwickIMU", str(csrc_dir()), "float32", cflags=list(DEFAULT_CFLAGS))
    return fw, "MadgwickIMU", dict(dt=d.dt, beta=0.1), (d.gyr, d.acc)


def _through(benchmark, case, target, baud, rounds=3):
    fw, name, params, inputs = case
    prog = build_board(fw, name, params, target, baud=baud)
    out = {}
    try:
        with Board(prog) as b:
            def go():
                out["v"] = validate(fw, name, params, inputs, target=target, port=b.port,
                                    baud=baud, timeout=30)
                out["best"] = min(out.get("best", float("inf")), out["v"].timing["board"])
            benchmark.pedantic(go, rounds=rounds, iterations=1)
    finally:
        shutil.rmtree(prog.workdir, ignore_errors=True)
    v = out["v"]
    n = len(inputs[0])
    assert v.bit_exact and len(v.got) == n, v.text()
    benchmark.extra_info.update(
        samples=n, samples_per_s=round(n / out["best"]),
        repeats=int(v.timing["repeats"]), cost=f"{v.cost.median:.0f} {v.cost.unit}")
    print(f"\n{target} {name} {baud} baud: {n / out['best']:.0f} samples/s (best round) "
          f"({v.cost.median:.0f} {v.cost.unit} per update)")
    return v


@pytest.mark.parametrize("baud", [115_200, 1_000_000])
@pytest.mark.parametrize("target", ["cortex-m4f", "atmega328p"])
@pytest.mark.parametrize("case", [_cf, _madgwick], ids=["cf", "MadgwickIMU"])
def test_throughput(benchmark, case, target, baud):
    _through(benchmark, case(10.0), target, baud)


def test_10min_log_atmega328p(benchmark):
    v = _through(benchmark, _madgwick(600.0), "atmega328p", 1_000_000, rounds=1)
    assert len(v.got) == 120_000


def _size(tmp, fltr, runner):
    build = tmp / f"{fltr}-{runner}"
    for cmd in (["cmake", "-S", str(ROOT / "examples" / "hil" / "baremetal"), "-B", str(build),
                 f"-DCMAKE_TOOLCHAIN_FILE={ROOT / 'examples' / 'firmware' / 'cmake' / 'avr.cmake'}",
                 f"-DHIL_FILTER={fltr}", f"-DHIL_RUNNER={runner}"],
                ["cmake", "--build", str(build)]):
        p = subprocess.run(cmd, capture_output=True, text=True)
        assert p.returncode == 0, p.stdout[-2000:] + p.stderr[-2000:]
    out = subprocess.run(["avr-size", str(build / "hil_example.elf")], capture_output=True,
                         text=True).stdout.splitlines()[-1].split()
    text, data, bss = (int(v) for v in out[:3])
    return text + data, data + bss


@pytest.mark.parametrize("fltr", ["madgwick_ahrs", "robust_ahrs_q"])
def test_runner_size_atmega328p(benchmark, tmp_path, fltr):
    got = {}

    def go():
        got["on"] = _size(tmp_path, fltr, "ON")
        got["off"] = _size(tmp_path, fltr, "OFF")

    benchmark.pedantic(go, rounds=1, iterations=1)
    (f_on, r_on), (f_off, r_off) = got["on"], got["off"]
    assert f_on <= 32 * 1024 - 512 and r_on <= 2048 - 512     # a boot loader, a stack
    benchmark.extra_info.update(flash=f_on, ram=r_on, runner_flash=f_on - f_off,
                                runner_ram=r_on - r_off)
    print(f"\n{fltr}: {f_on} B flash, {r_on} B static RAM with the runner; the runner "
          f"{f_on - f_off} B flash, {r_on - r_off} B RAM")
