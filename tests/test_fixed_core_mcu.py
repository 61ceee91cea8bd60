"""The target-specific paths of the Q-format core (csrc/fixed/imf_fixed.h) on the emulated
MCUs against its Python mirror (imufuse.reference._cint).

On AVR the saturating add/sub, the qN -> q15 conversions (N = 29, 30, 31), the carry and the
rate saturation of the 8-bit profile and the shifts by a run-time count are inline assembly or out-of-line copies
that the host build (tests/test_fixed_core.py) never compiles; the filters exercise them only
on the values their inputs happen to produce.  Here every one of them runs over edge values
(the saturation bounds, the rounding ties, INT32_MIN/MAX) and random ones, on the ATmega328P
and the Cortex-M0 (and the generic C paths on the RV32IMAC, a second 32-bit compiler and ISA),
and each result must equal the reference.
"""
from __future__ import annotations

import numpy as np
import pytest

import imufuse.mcu as mcu
from imufuse.mcu.driver import Driver
from imufuse.reference import _cint as ci
from imufuse.reference import fixed_quat as fq

from imufuse.mcu.filters import CSRC

TARGETS = ["avr", "m0", "rv32imac"]
I32_MIN, I32_MAX = -(1 << 31), (1 << 31) - 1


@pytest.fixture(scope="module")
def toolchains():
    return mcu.ensure_toolchains(TARGETS)


def _edges():
    out = {I32_MIN, I32_MIN + 1, I32_MAX, I32_MAX - 1, 0, 1, -1}
    # the largest values a rounding shift by n takes without overflow (x + 2^(n-1) <= max):
    # the guards of the shortcuts for constant shifts (AVR: n == 8 by byte moves)
    for n in range(1, 32):
        for d in (-2, -1, 0, 1, 2):
            out.add(I32_MAX - (1 << (n - 1)) + d)
    for k in range(12, 32):
        for base in (1 << k, -(1 << k)):
            for d in (-2, -1, 0, 1, 2):
                out.add(base + d)
    # rounding ties and the range ends of qn_to_q15s for N = 29, 30, 31
    for n in (14, 15, 16):
        for m in (32766, 32767, 32768, -32767, -32768, -32769):
            for d in (-1, 0, 1):
                out.add(m * (1 << n) + d + (1 << (n - 1)))
                out.add(m * (1 << n) + d)
    return sorted(v for v in out if I32_MIN <= v <= I32_MAX)


def _operands(n_random=600, seed=11):
    rng = np.random.default_rng(seed)
    e = np.array(_edges(), dtype=np.int64)
    a = np.concatenate([e, np.roll(e, 7), rng.integers(I32_MIN, I32_MAX, n_random, endpoint=True)])
    b = np.concatenate([np.roll(e, 3), e[::-1], rng.integers(I32_MIN, I32_MAX, n_random, endpoint=True)])
    # random values of every magnitude, not only of the full range
    sh = rng.integers(0, 32, a.size)
    a = np.where(np.arange(a.size) % 3 == 2, a >> sh, a)
    b = np.where(np.arange(b.size) % 5 == 4, b >> np.roll(sh, 1), b)
    nsh = rng.integers(0, 32, a.size)          # run-time shift counts
    # imf_gain8_mul's left shifts at the int32 bounds: (a mod 2^16) b = 2^30 - 1, -2^30,
    # -(2^30 - 1), -(2^30 + 1), 2^30 + 32766 doubled once and twice (shift n - 15 = -1, -2)
    extra = [(32769, 32767), (32768, -32768), (32769, -32767), (33025, -32513), (32770, 32767)]
    a = np.concatenate([a, [x for x, _ in extra for _ in (0, 1)]])
    b = np.concatenate([b, [y for _, y in extra for _ in (0, 1)]])
    nsh = np.concatenate([nsh, [14, 13] * len(extra)])
    return a.astype(np.int32), b.astype(np.int32), nsh.astype(np.int32)


OPS = [
    # (C expression, kind, reference)
    ("imf_add_sat32(ab[0], ab[1])", "i32", lambda a, b, n: ci.add_sat32(a, b)),
    ("imf_sub_sat32(ab[0], ab[1])", "i32", lambda a, b, n: ci.sub_sat32(a, b)),
    ("imf_qn_to_q15s(ab[0], 29)", "i16", lambda a, b, n: ci.qn_to_q15s(a, 29)),
    ("imf_qn_to_q15s(ab[0], 30)", "i16", lambda a, b, n: ci.qn_to_q15s(a, 30)),
    ("imf_qn_to_q15s(ab[0], 31)", "i16", lambda a, b, n: ci.qn_to_q15s(a, 31)),
    ("imf_rshr32(ab[0], ab[2])", "i32", lambda a, b, n: ci.rshr32(a, n)),
    # constant shift counts: the inlined shortcuts (AVR: 8 by byte moves, 15 and 16 by words)
    ("imf_rshr32(ab[0], 8)", "i32", lambda a, b, n: ci.rshr32(a, 8)),
    ("imf_rshr32(ab[0], 15)", "i32", lambda a, b, n: ci.rshr32(a, 15)),
    ("imf_rshr32(ab[0], 16)", "i32", lambda a, b, n: ci.rshr32(a, 16)),
    ("imf_shl_sat32(ab[0], ab[2])", "i32", lambda a, b, n: ci.shl_sat32(a, n)),
    ("imf_rshift_sat32(ab[0], ab[2] - 15)", "i32", lambda a, b, n: ci.rshift_sat32(a, n - 15)),
    ("imf_mul_32x16(ab[0], (int16_t)ab[3], ab[2] + 16)", "i32",
     lambda a, b, n: ci.mul_32x16(a, _i16(b), n + 16)),
    ("imf_mul_32x16(ab[0], (int16_t)ab[3], ab[2] / 2)", "i32",
     lambda a, b, n: ci.mul_32x16(a, _i16(b), n // 2)),
    # imf_mul_32x16_s (outside AVR: n <= 16 out of line) over n = 0..31 and 16..47
    ("imf_mul_32x16_s(ab[0], (int16_t)ab[3], ab[2])", "i32",
     lambda a, b, n: ci.mul_32x16_s(a, _i16(b), n)),
    ("imf_mul_32x16_s(ab[0], (int16_t)ab[3], ab[2] + 16)", "i32",
     lambda a, b, n: ci.mul_32x16_s(a, _i16(b), n + 16)),
    # imf_q_mul_hq_p32 (no range tests) with a symmetric q15 operand
    ("imf_q_mul_hq_p32(ab[0], (int16_t)(ab[3] == -32768 ? -32767 : ab[3]))", "i32",
     lambda a, b, n: fq.mul_hq_p32(a, max(_i16(b), -32767))),
    # imf_invsqrt8_u32 (chord and Newton step shared with imf_invsqrt16_u32): y + e 2^16,
    # x in [2^30, 2^32) and in [2^28, 2^30)
    ("imf_test_invsqrt8((uint32_t)ab[0] | 0x40000000u)", "i32",
     lambda a, b, n: _inv8((a & 0xFFFFFFFF) | 0x40000000)),
    ("imf_test_invsqrt8(((uint32_t)ab[0] >> 2) | 0x10000000u)", "i32",
     lambda a, b, n: _inv8(((a & 0xFFFFFFFF) >> 2) | 0x10000000)),
    # imf_invsqrt_u32 (its Newton steps are imf_invsqrt_newton16's): y + shift 2^16
    ("imf_test_invsqrt((uint32_t)ab[0])", "i32",
     lambda a, b, n: _inv(a & 0xFFFFFFFF)),
    # imf_gain8_mul's general path (out of line on AVR), shifts -15..16 (the left shifts of a
    # gain ki >= 2^-9 by doublings on AVR)
    ("imf_gain8_mul((int16_t)ab[3], imf_test_gain8((uint16_t)ab[0], ab[2] - 15))", "i32",
     lambda a, b, n: ci.gain8_mul(_i16(b), (a & 0xFFFF, n - 15))),
    ("imf_q_sat_q15_p8(ab[0])", "i32", lambda a, b, n: ci.sat_q15(a)),
    ("imf_q_carry_p8(ab[0], &cc)", "i32", None),   # checked with its state below
    ("cc", "i32", None),
]


def _inv(x):
    y, sh = ci.invsqrt_u32(x)
    return y + (sh << 16)


def _inv8(x):
    y, e = ci.invsqrt8_u32(x)
    return y + (e << 16)


def _i16(v):
    v &= 0xFFFF
    return v - 0x10000 if v >= 0x8000 else v


@pytest.mark.parametrize("target", TARGETS)
def test_core_paths_on_target(toolchains, target):
    if target in toolchains:
        pytest.skip(f"toolchain for {target} unavailable: {toolchains[target]}")
    a, b, n = _operands()
    b16 = np.array([_i16(int(v)) for v in b], dtype=np.int32)   # b as an int16 operand
    ab = np.stack([a, b, n, b16], axis=1)
    state = [(f"out[{k}]", "i32") for k in range(len(OPS))]
    step = "\n".join(f"out[{k}] = (int32_t)({expr});" for k, (expr, _, _) in enumerate(OPS[:-1]))
    step += f"\nout[{len(OPS) - 1}] = cc;"
    drv = Driver(prelude='#include "imf_fixed_quat.h"\nstatic int32_t out[%d];\n'
                         "static int32_t cc;\n"
                         "static imf_gain8_t imf_test_gain8(uint16_t m, int n)\n"
                         "{ imf_gain8_t g; g.m = m; g.n = (int16_t)n; return g; }\n"
                         "static int32_t imf_test_invsqrt(uint32_t x)\n"
                         "{ int sh; uint16_t y = imf_invsqrt_u32(x, &sh);"
                         " return (int32_t)y + (int32_t)sh * 65536L; }\n"
                         "static int32_t imf_test_invsqrt8(uint32_t x)\n"
                         "{ int e; uint16_t y = imf_invsqrt8_u32(x, &e);"
                         " return (int32_t)y + (int32_t)e * 65536L; }" % len(OPS),
                 init="cc = 0;", step=step, state=state)
    res = mcu.run(target, include_dirs=[CSRC, CSRC / "fixed"], driver=drv, inputs={"ab": ab})
    got = res.state.astype(np.uint32).view(np.int32)
    c = [0]
    for i in range(len(a)):
        ai, bi, ni = int(a[i]), int(b[i]), int(n[i])
        want = [f(ai, bi, ni) for _, _, f in OPS[:-2]]
        want.append(fq.carry_p8(ai, c, 0))
        want.append(c[0])
        assert list(got[i]) == want, (target, i, ai, bi, ni, list(got[i]), want)
