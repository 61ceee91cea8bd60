"""The Q-format core (csrc/fixed/imf_fixed.h) against its Python mirror
(imufuse.reference._cint), compiled with gcc + UBSan, over hypothesis values."""
from __future__ import annotations

import math
import struct

import pytest
from hypothesis import given, settings, strategies as st, HealthCheck

import cbuild  # noqa: E402

from imufuse.reference import _cint as ci  # noqa: E402
from imufuse.reference import fixed_quat as fq  # noqa: E402

pytestmark = pytest.mark.skipif(not cbuild.have_gcc(), reason="needs gcc")

i16 = st.integers(-32768, 32767)
i32 = st.integers(ci.INT32_MIN, ci.INT32_MAX)
u32 = st.integers(0, 0xFFFFFFFF)
edge32 = st.sampled_from([ci.INT32_MIN, ci.INT32_MIN + 1, -65536, -32769, -32768, -1, 0, 1,
                          32767, 32768, 65535, ci.INT32_MAX - 1, ci.INT32_MAX])
edge16 = st.sampled_from([-32768, -32767, -1, 0, 1, 32767])
any32 = st.one_of(i32, edge32)
any16 = st.one_of(i16, edge16)
shift = st.integers(0, 31)


def py_op(op, a, b, n):
    if op == "invsqrt_u32":
        return ci.invsqrt_u32(a)
    if op == "qscale":
        v = struct.unpack("<d", struct.pack("<q", a))[0]
        try:
            c = ci.qscale(v)
            return c.m, c.s
        except ValueError:
            return 0, 16
    if op == "q_mul_hq_p32":
        return fq.mul_hq_p32(a, b), 0
    f = getattr(ci, op)
    args = {"rshr32": (a, n), "asr32": (a, n), "shl_sat32": (a, n), "rshift_sat32": (a, n),
            "sat_q15": (a,), "sat_q15s": (a,), "add_sat32": (a, b), "sub_sat32": (a, b),
            "add_sat_q15": (a, b), "sub_sat_q15": (a, b), "mul_q15": (a, b),
            "mul_q15_q30": (a, b), "mul_32x16": (a, b, n), "mul_32x16_s": (a, b, n), "isqrt_u32": (a,),
            "q30_to_q15": (a,), "q15_to_q30": (a,), "qn_to_q15s": (a, n)}[op]
    return f(*args), 0


def check(cases):
    text = "".join(f"{op} {a} {b} {n}\n" for op, a, b, n in cases)
    out = cbuild.run("core_driver", text).split("\n")
    for (op, a, b, n), line in zip(cases, out):
        got = tuple(int(v) for v in line.split())
        assert got == tuple(py_op(op, a, b, n)), (op, a, b, n, got)


CASES = st.one_of(
    st.tuples(st.just("rshr32"), any32, st.just(0), shift),
    st.tuples(st.just("asr32"), any32, st.just(0), shift),
    st.tuples(st.just("shl_sat32"), any32, st.just(0), shift),
    st.tuples(st.just("rshift_sat32"), any32, st.just(0), st.integers(-31, 31)),
    st.tuples(st.just("sat_q15"), any32, st.just(0), st.just(0)),
    st.tuples(st.just("sat_q15s"), any32, st.just(0), st.just(0)),
    st.tuples(st.sampled_from(["add_sat32", "sub_sat32"]), any32, any32, st.just(0)),
    st.tuples(st.sampled_from(["add_sat_q15", "sub_sat_q15", "mul_q15", "mul_q15_q30"]),
              any16, any16, st.just(0)),
    st.tuples(st.sampled_from(["mul_32x16", "mul_32x16_s"]), any32, any16, st.integers(0, 47)),
    st.tuples(st.just("q_mul_hq_p32"), any32, st.integers(-32767, 32767), st.just(0)),
    st.tuples(st.sampled_from(["isqrt_u32", "invsqrt_u32"]), st.one_of(u32, st.integers(0, 4096)),
              st.just(0), st.just(0)),
    st.tuples(st.just("q30_to_q15"), any32, st.just(0), st.just(0)),
    st.tuples(st.just("q15_to_q30"), any16, st.just(0), st.just(0)),
    st.tuples(st.just("qn_to_q15s"), any32, st.just(0), st.integers(15, 46)),
    st.tuples(st.just("qscale"),
              st.floats(0, 1e12, allow_nan=False).map(
                  lambda v: struct.unpack("<q", struct.pack("<d", v))[0]),
              st.just(0), st.just(0)),
)


@settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck))
@given(st.lists(CASES, min_size=50, max_size=400))
def test_core_c_equals_python(cases):
    check(cases)


def test_core_edges_exhaustive():
    edges32 = [ci.INT32_MIN, ci.INT32_MIN + 1, -(1 << 30), -65537, -65536, -32769, -32768,
               -2, -1, 0, 1, 2, 32767, 32768, 65535, 65536, 1 << 30, ci.INT32_MAX - 1, ci.INT32_MAX]
    edges16 = [-32768, -32767, -16384, -1, 0, 1, 16384, 32767]
    cases = []
    for a in edges32:
        for n in range(32):
            cases += [("rshr32", a, 0, n), ("shl_sat32", a, 0, n), ("asr32", a, 0, n)]
        for n in range(48):
            cases += [(op, a, b, n) for b in edges16 for op in ("mul_32x16", "mul_32x16_s")]
        cases += [("q_mul_hq_p32", a, b, 0) for b in edges16 if b != -32768]
        cases += [("add_sat32", a, b, 0) for b in edges32]
        cases += [("sub_sat32", a, b, 0) for b in edges32]
    for a in edges16:
        cases += [(op, a, b, 0) for b in edges16
                  for op in ("mul_q15", "add_sat_q15", "sub_sat_q15", "mul_q15_q30")]
    check(cases)


def test_mul_32x16_is_exactly_rounded():
    """The split 32x16 product equals the rounded exact product (pure Python)."""
    import random
    rnd = random.Random(1)
    for _ in range(20000):
        a, b, n = rnd.randint(ci.INT32_MIN, ci.INT32_MAX), rnd.randint(-32768, 32767), rnd.randint(0, 47)
        assert ci.mul_32x16(a, b, n) == ci.mul_32x16_exact(a, b, n)


def test_q_mul_hq_p32_is_mul_32x16():
    """imf_q_mul_hq_p32 (2 m + the rounded low part, no range tests) is
    imf_mul_32x16(h, qs, 15) for every int32 h and symmetric q15 qs: the
    int32 edges against every |qs| edge, and random pairs (pure Python; the
    C equals this twin in the tests above)."""
    import random
    rnd = random.Random(2)
    hs = [ci.INT32_MIN, ci.INT32_MIN + 1, -(1 << 30) - 1, -(1 << 30), -65537, -65536, -1, 0, 1,
          65535, 65536, (1 << 30) - 1, 1 << 30, ci.INT32_MAX - 1, ci.INT32_MAX]
    qss = [-32767, -32766, -16385, -16384, -1, 0, 1, 16384, 32766, 32767]
    pairs = [(h, q) for h in hs for q in qss]
    pairs += [(rnd.randint(ci.INT32_MIN, ci.INT32_MAX), rnd.randint(-32767, 32767))
              for _ in range(20000)]
    for h, q in pairs:
        assert fq.mul_hq_p32(h, q) == ci.mul_32x16(h, q, 15) == ci.mul_32x16_exact(h, q, 15), (h, q)


def test_invsqrt_accuracy_exhaustive_mantissa():
    worst = 0.0
    for u in range(16384, 65536):
        for x in (u << 16, (u << 16) | 0xFFFF):
            y, s = ci.invsqrt_u32(x)
            worst = max(worst, abs(math.ldexp(y, -s) * math.sqrt(x) - 1.0))
    assert worst < 1e-4
    for x in range(1, 5000):
        y, s = ci.invsqrt_u32(x)
        assert abs(math.ldexp(y, -s) * math.sqrt(x) - 1.0) < 1e-4


@given(u32)
def test_isqrt_is_floor_sqrt(x):
    r = ci.isqrt_u32(x)
    assert r * r <= x < (r + 1) * (r + 1)


def test_rounding_has_no_bias():
    """Round-to-nearest: the mean error of q15 products over a grid is ~0
    (truncation would give -0.5 LSB)."""
    err = 0.0
    count = 0
    for a in range(-32768, 32768, 97):
        for b in range(-32768, 32768, 1013):
            err += ci.mul_q15(a, b) - a * b / 32768.0
            count += 1
    assert abs(err / count) < 0.01


def test_ubsan_build_reports_undefined_behaviour(tmp_path):
    """The sanitizer flags of the drivers do catch a signed overflow and a
    left shift of a negative value (so a clean run means something)."""
    import subprocess
    if not cbuild.USE_UBSAN:
        pytest.skip("IMF_FIXED_UBSAN=0")
    for body in ("int32_t x = INT32_MAX; x += (int32_t)argc; return (int)(x & 1);",
                 "int32_t x = -argc; return (int)(x << 3);"):
        src = tmp_path / "ub.c"
        src.write_text("#include <stdint.h>\nint main(int argc, char **argv)\n"
                       "{ (void)argv; " + body + " }\n")
        exe = tmp_path / "ub"
        subprocess.run(["gcc", "-std=c99", "-O0", *cbuild.UBSAN, str(src), "-o", str(exe)],
                       check=True)
        p = subprocess.run([str(exe)], capture_output=True, text=True)
        assert p.returncode != 0 and "runtime error" in p.stderr
