"""The emulated-MCU harness (imufuse.mcu): bit-identical results on Cortex-M4F, Cortex-M0 and
ATmega328P against the host build, exact cycle/instruction counters, size and stack figures.

The kernels are the harness's own examples (python/imufuse/mcu/examples), not library filters.
Missing toolchains are installed with tools/install-toolchains.sh; the tests skip, with the
reason, only when that is impossible.
"""

from pathlib import Path

import numpy as np
import pytest

import imufuse.mcu as mcu

EX = Path(mcu.__file__).resolve().parent / "examples"
MCU_TARGETS = ["m4f", "m0", "avr"]
N = 1000


@pytest.fixture(scope="session")
def toolchains():
    """{target: reason} of targets that cannot run here, after trying to install."""
    return mcu.ensure_toolchains(MCU_TARGETS + ["host"])


def need(toolchains, target):
    if target in toolchains:
        pytest.skip(f"toolchain for {target} unavailable: {toolchains[target]}")


# --------------------------------------------------------------------------------------------
# kernels


def quat_inputs(n=N, seed=7):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 512.0
    gyr = np.stack([0.8 * np.sin(3 * t), 0.5 * np.cos(2 * t), 0.3 * np.ones(n)], axis=1)
    gyr = (gyr + rng.normal(0, 0.05, (n, 3))).astype(np.float32)
    acc = (rng.normal(0, 0.05, (n, 3)) + [0.1, -0.2, 1.0]).astype(np.float32)
    acc[n // 3] = 0.0  # the kernel's zero-norm branch
    return {"gyr": gyr, "acc": acc}


QUAT_DRIVER = mcu.Driver(
    prelude='#include "imk_quat.h"\nstatic imk_quat_t k;',
    init="imk_quat_init(&k, 1.0f / 512.0f, 2.0f);",
    step="imk_quat_update(&k, gyr, acc);",
    state=mcu.state_words("k.q", "f32", 4) + mcu.state_words("k.e", "f32", 3) + [("k.anorm", "f32")],
)


def int_inputs(n=N, seed=11):
    rng = np.random.default_rng(seed)
    rate = rng.integers(-32768, 32768, n).astype(np.int16)
    angle = rng.integers(-32768, 32768, n).astype(np.int16)
    rate[:300] = 32767  # drive the integral into saturation
    angle[:300] = 32767
    rate[300:310] = -32768
    return {"rate": rate, "angle": angle}


INT_DRIVER = mcu.Driver(
    prelude='#include "imk_int.h"\nstatic imk_int_t k;',
    init="imk_int_init(&k);",
    step="imk_int_update(&k, rate, angle);",
    state=[("k.angle", "i32"), ("k.rate_i", "i32"), ("k.err", "i32"), ("k.mean", "i32")],
)

KERNELS = {
    "quat_f32": (["imk_quat.c"], QUAT_DRIVER, quat_inputs),
    "int16_i32": (["imk_int.c"], INT_DRIVER, int_inputs),
}


def run_kernel(target, name, **kw):
    srcs, drv, make_inputs = KERNELS[name]
    return mcu.run(target, sources=[EX / s for s in srcs], include_dirs=[EX], driver=drv,
                   inputs=make_inputs(), **kw)


@pytest.fixture(scope="session")
def host_results(toolchains):
    need(toolchains, "host")
    return {name: run_kernel("host", name) for name in KERNELS}


# --------------------------------------------------------------------------------------------
# bit-exactness


@pytest.mark.parametrize("target", MCU_TARGETS)
@pytest.mark.parametrize("kernel", sorted(KERNELS))
def test_target_bits_equal_host(toolchains, host_results, target, kernel):
    need(toolchains, target)
    res = run_kernel(target, kernel)
    host = host_results[kernel]
    assert res.state.dtype == np.uint32
    assert res.state.shape == host.state.shape == (N, len(KERNELS[kernel][1].state))
    diff = np.argwhere(res.state != host.state)
    assert diff.size == 0, f"first differing (sample, word): {diff[:5].tolist()}"


def quat_reference(gyr, acc, dt=np.float32(1 / 512), kp=np.float32(2.0)):
    """numpy float32 mirror of imk_quat_update (each operation rounded to float32)."""
    f = np.float32
    q = [f(1), f(0), f(0), f(0)]
    e = [f(0)] * 3
    dt = f(1.0) / f(512.0)
    out = np.empty((len(gyr), 8), dtype=np.float32)
    for i in range(len(gyr)):
        ax, ay, az = (f(v) for v in acc[i])
        gx, gy, gz = (f(v) for v in gyr[i])
        n = np.sqrt(ax * ax + ay * ay + az * az, dtype=np.float32)
        anorm = n
        if n > f(0):
            ax, ay, az = ax / n, ay / n, az / n
            vx = f(2) * (q[1] * q[3] - q[0] * q[2])
            vy = f(2) * (q[0] * q[1] + q[2] * q[3])
            vz = q[0] * q[0] - q[1] * q[1] - q[2] * q[2] + q[3] * q[3]
            e = [ay * vz - az * vy, az * vx - ax * vz, ax * vy - ay * vx]
            gx, gy, gz = gx + kp * e[0], gy + kp * e[1], gz + kp * e[2]
        hdt = f(0.5) * dt
        q0, q1, q2, q3 = q
        q = [
            q0 + (-q1 * gx - q2 * gy - q3 * gz) * hdt,
            q1 + (q0 * gx + q2 * gz - q3 * gy) * hdt,
            q2 + (q0 * gy - q1 * gz + q3 * gx) * hdt,
            q3 + (q0 * gz + q1 * gy - q2 * gx) * hdt,
        ]
        r = f(1) / np.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3], dtype=np.float32)
        q = [v * r for v in q]
        out[i] = q + e + [anorm]
    return out


def test_host_matches_numpy_float32_mirror(host_results):
    """The host reference itself is right: an independent float32 model gives the same bits."""
    inp = quat_inputs()
    ref = quat_reference(inp["gyr"], inp["acc"])
    assert np.array_equal(host_results["quat_f32"].state, ref.view(np.uint32))
    q = host_results["quat_f32"].values()[:4]
    norm = np.sqrt(sum(c.astype(np.float64) ** 2 for c in q))
    assert np.all(np.abs(norm - 1) < 1e-6)
    assert len(np.unique(host_results["quat_f32"].state[:, 0])) > 10  # it moves


def test_int_kernel_saturates(host_results):
    rate_i = host_results["int16_i32"].values()[1]
    assert rate_i.dtype == np.int32
    assert rate_i.max() == 2**31 - 1


@pytest.mark.parametrize("target", ["m4f", "m0"])
def test_float64_words_on_arm(toolchains, target):
    """Soft double on ARM gives the host's bits; 64-bit state words come back as uint64."""
    need(toolchains, target)
    x = np.linspace(-3.0, 7.0, 50)
    drv = mcu.Driver(
        prelude="static double acc64;\nstatic float acc32;",
        step="acc64 = acc64 * 0.999 + x / 3.0; acc32 = (float)acc64;",
        state=[("acc64", "f64"), ("acc32", "f32")],
    )
    got = mcu.run(target, driver=drv, inputs={"x": x})
    host = mcu.run("host", driver=drv, inputs={"x": x})
    assert got.state.dtype == np.uint64
    assert np.array_equal(got.state, host.state)
    expect = 0.0
    for v in x:
        expect = expect * 0.999 + v / 3.0
    assert got.values()[0][-1] == expect


# --------------------------------------------------------------------------------------------
# counters


def test_avr_timer1_counts_exact_cycles(toolchains):
    """_delay_loop_2(k) takes 4k - 1 cycles (sbiw 2 + brne 2, last brne 1) and loading k
    from RAM 4 (two lds): the step costs 4k + 3 cycles over an empty call, overflows or not."""
    need(toolchains, "avr")
    k = np.array([1, 2, 10, 1000, 16383, 16384, 20000, 40000, 65535, 7], dtype=np.uint16)
    drv = mcu.Driver(prelude="#include <util/delay_basic.h>", step="_delay_loop_2(k);", state=[])
    res = mcu.run("avr", driver=drv, inputs={"k": k}, count=True)
    assert (res.raw_counts >> 16).max() >= 4  # several Timer1 overflows were counted
    assert res.counts.tolist() == (4 * k.astype(np.int64) + 3).tolist()


@pytest.mark.parametrize("target", ["m4f", "m0"])
def test_arm_icount_counts_exact_instructions(toolchains, target):
    """A subs/bne loop runs 2k instructions, plus two loads of k: 2k + 2 over an empty call."""
    need(toolchains, target)
    k = np.array([1, 2, 10, 1000, 65535, 40000, 7], dtype=np.uint16)
    drv = mcu.Driver(
        step=(
            "uint32_t c = k;\n"
            '__asm__ volatile(".syntax unified\\n1: subs %0, %0, #1\\n\\tbne 1b\\n.syntax divided"'
            ' : "+l"(c) : : "cc");'
        ),
        state=[],
    )
    res = mcu.run(target, driver=drv, inputs={"k": k}, count=True)
    assert res.counts.tolist() == (2 * k.astype(np.int64) + 2).tolist()


@pytest.mark.parametrize("target", MCU_TARGETS)
def test_kernel_counts_repeatable(toolchains, target):
    need(toolchains, target)
    a = run_kernel(target, "quat_f32", count=True)
    b = run_kernel(target, "quat_f32", count=True)
    assert np.array_equal(a.counts, b.counts)
    assert a.counts.min() > 20
    assert np.array_equal(a.state, run_kernel(target, "quat_f32").state)  # counting changes nothing


def test_callgrind_instructions(toolchains):
    need(toolchains, "host")
    srcs, drv, make_inputs = KERNELS["quat_f32"]
    kw = dict(sources=[EX / s for s in srcs], include_dirs=[EX], driver=drv, inputs=make_inputs(200))
    a = mcu.callgrind_instructions(**kw)
    b = mcu.callgrind_instructions(**kw)
    assert a == b
    assert a["samples"] == 200 and 30 < a["per_update"] < 2000


# --------------------------------------------------------------------------------------------
# size and stack


@pytest.mark.parametrize("target", MCU_TARGETS + ["host"])
def test_code_size_and_stack(toolchains, target):
    need(toolchains, target)
    srcs = [EX / "imk_quat.c", EX / "imk_int.c"]
    size = mcu.code_size(target, srcs, [EX])
    assert set(size) == {"imk_quat.c", "imk_int.c", "total"}
    assert size["imk_quat.c"]["text"] > 100
    assert size["total"]["text"] == size["imk_quat.c"]["text"] + size["imk_int.c"]["text"]
    stack = mcu.stack_usage(target, srcs, [EX])
    assert stack["imk_quat_update"]["kind"] == "static"
    assert 0 <= stack["imk_quat_update"]["bytes"] < 256


@pytest.mark.parametrize("target", MCU_TARGETS)
def test_measured_stack(toolchains, target):
    need(toolchains, target)
    res = run_kernel(target, "quat_f32")
    assert res.stack_bytes is not None and 0 < res.stack_bytes < 1024


# --------------------------------------------------------------------------------------------
# failures are reported, runs end by themselves


def test_timeout_is_reported(toolchains):
    need(toolchains, "m4f")
    drv = mcu.Driver(step="for (;;) { __asm__ volatile(\"\"); }", state=[])
    with pytest.raises(mcu.HarnessError, match="timeout"):
        mcu.run("m4f", driver=drv, n=1, timeout=3)


def test_compile_error_is_reported(toolchains):
    need(toolchains, "m0")
    drv = mcu.Driver(step="float f = 1.5f; volatile double d = f * 2.0; (void)d;", state=[])
    with pytest.raises(mcu.HarnessError, match="double-promotion"):
        mcu.run("m0", driver=drv, n=1)


def test_bad_inputs_rejected():
    drv = mcu.Driver(step=";", state=[])
    with pytest.raises(ValueError, match="dtype"):
        mcu.build("host", driver=drv, inputs={"x": np.zeros(3, dtype=np.complex64)})
    with pytest.raises(ValueError, match="length"):
        mcu.build("host", driver=drv, inputs={"x": np.zeros(3, np.float32), "y": np.zeros(4, np.float32)})
    with pytest.raises(ValueError, match="avr"):
        mcu.build("avr", driver=drv, inputs={"x": np.zeros(3)})
    with pytest.raises(ValueError, match="flash"):
        mcu.build("avr", driver=drv, inputs={"x": np.zeros((3000, 3), np.float32)})
    with pytest.raises(ValueError, match="kind"):
        mcu.Driver(step=";", state=[("x", "f16")])


def test_fault_is_reported(toolchains):
    need(toolchains, "m0")
    drv = mcu.Driver(step="*(volatile uint32_t *)0x30000001u = 1u;", state=[])
    with pytest.raises(mcu.HarnessError):
        mcu.run("m0", driver=drv, n=1, timeout=10)
