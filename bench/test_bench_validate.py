"""Speed of `imufuse validate --target` (pytest-benchmark; `pytest bench/test_bench_validate.py`).

A 20 s log at 200 Hz (4000 samples) validated on each emulated target, for the example firmware
(examples/firmware-tests/cf.c, Eq. 2.2) and for imufuse's own MadgwickIMU (csrc), with the
contract's flags (bit-exact, so no diagnosis rebuilds); and a 10-minute log (120 000 samples) of
the example on each target. Each cold (every round builds: a program cache of its own) and
warm (the program built once before the rounds: every round a cache hit). extra_info: samples
per second over the whole validation, and
where the time goes: the build (compiles side by side, two links), the emulator runs (chunks),
decoding the records (parse); host_s is the rest: the imufuse reference run and the
comparison.

    pytest bench/test_bench_validate.py --benchmark-columns=min,max
"""
import os
import shutil
import tempfile
import time

import pytest

from imufuse import sim
from imufuse.shared.resources import csrc_dir
from imufuse.firmware import DEFAULT_CFLAGS, Firmware, csrc_firmware, validate
from imufuse.mcu import ensure_toolchains

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FW = os.path.join(ROOT, "examples", "firmware-tests")
TARGETS = ("cortex-m4f", "cortex-m0", "atmega328p")


@pytest.fixture(scope="module", autouse=True)
def _toolchains():
    missing = ensure_toolchains(("m4f", "m0", "avr"))
    assert not missing, f"MCU toolchains missing: {missing}"


def _one(benchmark, fw, name, params, inputs, target, cache, rounds=3):
    """cache "cold": every round builds (an empty program cache of its own); "warm": the
    program built once before the rounds, every round a cache hit."""
    out = {}
    root = tempfile.mkdtemp(prefix="imf_bench_cache_")
    fw.cache_dir = root
    if cache == "warm":
        assert validate(fw, name, params, inputs, target=target).bit_exact

    def go():
        if cache == "cold":
            fw.cache_dir = tempfile.mkdtemp(dir=root)
        t0 = time.perf_counter()
        out["v"] = validate(fw, name, params, inputs, target=target)
        out["s"] = time.perf_counter() - t0

    try:
        benchmark.pedantic(go, rounds=rounds, iterations=1)
    finally:
        shutil.rmtree(root, ignore_errors=True)
    assert out["v"].timing["build_cached"] == (1.0 if cache == "warm" else 0.0)
    v = out["v"]
    assert v.bit_exact, v.text()
    n = len(inputs[0])
    assert len(v.got) == n
    _info(benchmark, v, n, out["s"])


def _info(benchmark, v, n, total):
    t = v.timing
    benchmark.extra_info.update(
        samples=n, samples_per_s=round(n / benchmark.stats.stats.min),
        build_s=round(t["build"], 3), emulator_s=round(t["emulator"], 3),
        parse_s=round(t["parse"], 3),
        host_s=round(total - t["build"] - t["emulator"] - t["parse"], 3),
        chunks=int(t["chunks"]))


CACHE = ("cold", "warm")


@pytest.mark.parametrize("cache", CACHE)
@pytest.mark.parametrize("target", TARGETS)
def test_example_20s(benchmark, target, cache):
    d = sim.axis1d("slow", rate=200.0, duration=20.0, seed=1)
    fw = Firmware([os.path.join(FW, "cf.c")], headers=["cf.h"], include_dirs=[FW], init="cf_init",
                  update="cf_update", state={"theta": "theta"}, cflags=list(DEFAULT_CFLAGS))
    _one(benchmark, fw, "Complementary1D", dict(dt=d.dt, T=0.5), (d.gyr, d.acc_angle), target,
         cache)


@pytest.mark.parametrize("cache", CACHE)
@pytest.mark.parametrize("target", TARGETS)
def test_madgwick_20s(benchmark, target, cache):
    d = sim.imu("slow", rate=200.0, duration=20.0, seed=1)
    fw = csrc_firmware("MadgwickIMU", str(csrc_dir()), "float32", cflags=list(DEFAULT_CFLAGS))
    _one(benchmark, fw, "MadgwickIMU", dict(dt=d.dt, beta=0.1), (d.gyr, d.acc), target,
         cache)


@pytest.mark.parametrize("cache", CACHE)
@pytest.mark.parametrize("target", TARGETS)
def test_example_10min(benchmark, target, cache):
    d = sim.axis1d("slow", rate=200.0, duration=600.0, seed=1)
    fw = Firmware([os.path.join(FW, "cf.c")], headers=["cf.h"], include_dirs=[FW], init="cf_init",
                  update="cf_update", state={"theta": "theta"}, cflags=list(DEFAULT_CFLAGS))
    _one(benchmark, fw, "Complementary1D", dict(dt=d.dt, T=0.5), (d.gyr, d.acc_angle), target,
         cache, rounds=1)
