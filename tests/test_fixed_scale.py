"""csrc/fixed/imf_fixed_scale.h: its AVR code (selected on the host with
IMF_SCALE_SHORT, gcc + UBSan) returns the values of the imf_fixed.h helpers
it replaces, and the Python twins (imufuse.reference.fixed_scale) return the
same, over every shift, edge values and hypothesis values. The emulated
ATmega328P runs (tests/test_mcu_filters.py) check the filters built on it."""
from __future__ import annotations

import functools
import math

import pytest
from hypothesis import given, settings, strategies as st, HealthCheck

import cbuild  # noqa: E402

from imufuse.reference import _cint as ci  # noqa: E402
from imufuse.reference import fixed_scale as fs  # noqa: E402

pytestmark = pytest.mark.skipif(not cbuild.have_gcc(), reason="needs gcc")

EDGE32 = [ci.INT32_MIN, ci.INT32_MIN + 1, -(1 << 30) - 1, -(1 << 30), -65537, -65536, -32769,
          -32768, -2, -1, 0, 1, 2, 32767, 32768, 65535, 65536, (1 << 30) - 1, 1 << 30,
          ci.INT32_MAX - 1, ci.INT32_MAX]
EDGE16 = [-32768, -32767, -16384, -1, 0, 1, 16383, 16384, 32767]
MANT = [0, 16384, 16385, 24576, 32767]   # q-scale mantissas: 0 or [2^14, 2^15)


def py(op, a, b, n):
    c = ci.QScale(b, n) if op in ("mulk16", "mulk32", "gain16_mul") else None
    return {"rshrk": lambda: fs.rshrk(a, n), "shl_satk": lambda: fs.shl_satk(a, n),
            "mul32x16k": lambda: fs.mul32x16k(a, b, n), "mulk16": lambda: fs.mulk16(a, c, 0),
            "mulk32": lambda: fs.mulk32(a, c, 0, 0), "i16_to_q15": lambda: fs.i16_to_q15(a),
            "cross16": lambda: fs.cross16(a, n >> 16, b, ((n & 0xFFFF) ^ 0x8000) - 0x8000),
            "shl_exact32": lambda: fs.shl_exact32(a, n),
            "gain16_mul": lambda: fs.gain16_mul(a, fs.gain16(c, 0, 0))}[op]()


def check(cases):
    out = cbuild.run("scale_driver", "".join(f"{op} {a} {b} {n}\n" for op, a, b, n in cases))
    for case, line in zip(cases, out.split("\n")):
        short, general = (int(v) for v in line.split())
        assert short == general == py(*case), (case, short, general, py(*case))


def test_scale_edges_every_shift():
    cases = []
    for a in EDGE32:
        cases += [("rshrk", a, 0, n) for n in range(32)]
        cases += [("shl_satk", a, 0, n) for n in range(32)]
        cases += [("mul32x16k", a, b, n) for b in EDGE16 for n in range(48)]
        cases += [("mulk32", a, m, n) for m in MANT for n in range(48)]
    for a in EDGE16:
        cases += [("mulk16", a, m, n) for m in MANT for n in range(-31, 32)]
        cases.append(("i16_to_q15", a, 0, 0))
    check(cases)


i32 = st.one_of(st.integers(ci.INT32_MIN, ci.INT32_MAX), st.sampled_from(EDGE32))
i16 = st.one_of(st.integers(-32768, 32767), st.sampled_from(EDGE16))
mant = st.one_of(st.integers(16384, 32767), st.just(0))
CASES = st.one_of(
    st.tuples(st.just("rshrk"), i32, st.just(0), st.integers(0, 31)),
    st.tuples(st.just("shl_satk"), i32, st.just(0), st.integers(0, 31)),
    st.tuples(st.just("mul32x16k"), i32, i16, st.integers(0, 47)),
    st.tuples(st.just("mulk32"), i32, mant, st.integers(0, 47)),
    st.tuples(st.just("mulk16"), i16, mant, st.integers(-31, 31)),
)


@settings(max_examples=40, deadline=None, suppress_health_check=list(HealthCheck))
@given(st.lists(CASES, min_size=50, max_size=400))
def test_scale_random(cases):
    check(cases)


def test_invsqrt16_accuracy_exhaustive_mantissa():
    """imf_invsqrt16_u32 (chord and two Newton steps): relative error < 6e-5, and no u
    (y depends on u = x / 2^16 alone) takes u y^2 above 3 2^30 or y out of uint16 (the twin
    raises OverflowError there; the C has neither a clamp nor a saturation)."""
    worst = 0.0
    for u in range(16384, 65536):
        for x in (u << 16, (u << 16) | 0xFFFF):
            y = fs.invsqrt16_u32(x)
            worst = max(worst, abs(y * 2.0 ** -31 * math.sqrt(x) - 1.0))
    assert worst < 6e-5


def test_invsqrt8_accuracy_exhaustive_mantissa():
    """imf_invsqrt8_u32 (the chord and one Newton step, shared with imf_invsqrt16_u32):
    relative error < 1.2e-3 for every u = x / 2^16 in both ranges (x < 2^30 is scaled by
    4), no bound of the step fails (the twin raises)."""
    worst = 0.0
    for u in range(16384, 65536):
        for x in (u << 16, (u << 16) | 0xFFFF, u << 14):
            y, e = ci.invsqrt8_u32(x)
            worst = max(worst, abs(y * 2.0 ** (e - 31) * math.sqrt(x) - 1.0))
    assert worst < 1.2e-3


V16 = st.integers(-32768, 32767)
VEC = st.one_of(st.tuples(V16, V16, V16),
                st.tuples(*[st.sampled_from([-32768, -32767, -1, 0, 1, 2, 4095, 4096, 32767])] * 3),
                st.tuples(*[st.integers(-8, 8)] * 3))


@settings(max_examples=30, deadline=None, suppress_health_check=list(HealthCheck))
@given(st.lists(VEC, min_size=50, max_size=300))
def test_unit_xy_c_equals_python_and_is_the_unit_vector(vs):
    out = cbuild.run("scale_driver", "".join(f"unit_xy_k {a} {b} {c}\n" for a, b, c in vs))
    for v, line in zip(vs, out.split("\n")):
        ok, *u = (int(x) for x in line.split())
        want = fs.unit_xy_k(list(v))
        assert (want is None) == (ok == 0), v
        if want is None:
            continue
        assert u == want, (v, u, want)
        n = math.sqrt(sum(x * x for x in v))
        # the direction within the inverse square root's error and the q15 rounding
        assert max(abs(ui / 32768.0 - x / n) for ui, x in zip(u, v)) < 6e-5 + 2.0 ** -15


def cross_case(a1, b1, a2, b2):
    return ("cross16", a1, a2, (b1 << 16) | (b2 & 0xFFFF))


def test_cross16_is_the_rounded_saturated_difference():
    """imf_cross16 (C, Python) = round((a1 b1 - a2 b2) / 2^16) saturated, exactly."""
    import random
    rnd = random.Random(3)
    edges = EDGE32
    cases = [cross_case(a1, b1, a2, b2) for a1 in edges for a2 in edges[::3]
             for b1 in EDGE16[::2] for b2 in EDGE16[::3]]
    for _ in range(3000):
        cases.append(cross_case(rnd.randint(ci.INT32_MIN, ci.INT32_MAX), rnd.randint(-32768, 32767),
                                rnd.randint(ci.INT32_MIN, ci.INT32_MAX), rnd.randint(-32768, 32767)))
    check(cases)
    for _, a1, a2, packed in cases:
        b1, b2 = packed >> 16, ((packed & 0xFFFF) ^ 0x8000) - 0x8000
        exact = (a1 * b1 - a2 * b2 + 32768) >> 16
        assert fs.cross16(a1, b1, a2, b2) == max(ci.INT32_MIN, min(ci.INT32_MAX, exact))


def test_cross3_16_is_the_cross_product_rounded_per_component():
    """cross3_16 (the twin of imf_cross3_16: a loop on AVR, straight-line elsewhere; the
    filters' AVR and host runs compare the C forms bit for bit) = a x b, each component
    round(/ 2^16) saturated."""
    import random
    rnd = random.Random(5)
    for _ in range(2000):
        a = [rnd.choice((rnd.randint(ci.INT32_MIN, ci.INT32_MAX), rnd.choice(EDGE32))) for _ in range(3)]
        b = [rnd.choice((rnd.randint(-32768, 32767), rnd.choice(EDGE16))) for _ in range(3)]
        exact = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
        want = [max(ci.INT32_MIN, min(ci.INT32_MAX, (e + 32768) >> 16)) for e in exact]
        assert fs.cross3_16(a, b) == want, (a, b)


def test_shl_exact32_in_its_range():
    cases = [("shl_exact32", x, 0, k) for k in range(31) for x in
             (0, 1, -1, (1 << (30 - k)) - 1, -(1 << (30 - k)), 12345 >> min(k, 13), -(12345 >> min(k, 13)))]
    check(cases)


GAINS = [(16384, 14), (20000, 14)] + [(m, sh) for sh in range(15, 48) for m in (16384, 16385, 20000, 24575, 32767)]


def test_gain16_product_c_equals_python_and_is_the_rounded_product():
    """imf_gain16_mul = round(x m 2^-(16 + 8 j)) exactly, for every shift of the gain."""
    cases = [("gain16_mul", x, m, sh) for m, sh in GAINS if sh >= 15 for x in EDGE32]
    check(cases)
    for _, x, m, sh in cases:
        gm, j = fs.gain16(ci.QScale(m, sh), 0, 0)
        assert fs.gain16_mul(x, (gm, j)) == (x * gm + (1 << (15 + 8 * j))) >> (16 + 8 * j)


def test_gain16_relative_error():
    """m 2^-(16 + 8 j) against the q-scale: exact for d <= 1, else below 2^(d - 16) <= 2^-9."""
    for m, sh in GAINS:
        gm, j = fs.gain16(ci.QScale(m, sh), 0, 0)
        if j < 0:
            assert sh < 15 and (j == -2) == ((m, sh) == (16384, 14))
            continue
        d = sh - 15 - 8 * j
        assert 0 <= d <= 7 and 256 <= gm < 65536
        assert gm == (2 * m * 2 + (1 << d)) >> (d + 1)  # round(2 m 2^-d), ties up
        rel = abs(gm * 2.0 ** -(16 + 8 * j) / (m * 2.0 ** -sh) - 1.0)
        assert rel == 0.0 if d <= 1 else rel < 2.0 ** (d - 16)


# ---- KKQ's AVR-only code (csrc/fixed/gravity_q.c under IMF_SCALE_SHORT) ----

KK_DRIVER = r"""
#include <stdio.h>
#include "gravity_q.h"
int main(void)
{
    long t0, t1;
    int v[6], km, ks, pm, pj, i;
    imf_kk_q_t f;
    while (scanf("%ld %ld %d %d %d %d %d %d %d %d %d %d", &t0, &t1, &v[0], &v[1], &v[2],
                 &v[3], &v[4], &v[5], &km, &ks, &pm, &pj) == 12) {
        imf_qscale_t kw;
        int16_t g[3], a[3];
        kw.m = (int16_t)km;
        kw.s = (int16_t)ks;
        if (imf_kk_q_init_consts(&f, kw, (uint16_t)pm, pj) != 0) {
            return 3;
        }
        for (i = 0; i < 3; ++i) {
            g[i] = (int16_t)v[i];
            a[i] = (int16_t)v[3 + i];
        }
        f.x.t[0] = (int32_t)t0;
        f.x.t[1] = (int32_t)t1;
        imf_kk_q_update_v(&f, g, a);
        printf("%ld %ld\n", (long)f.x.t[0], (long)f.x.t[1]);
    }
    return 0;
}
"""
KK_PARAMS = [(0.002, 0.002, 1.0642e-3), (0.005, 1.0, 1.0642e-3), (0.01, 0.5, 1e-2),
             (1e-5, 0.0, 1e-7), (0.1, 0.9, 1.2e-3)]
# states around the q15 saturation of the cross terms (|theta| = 1 rad = 2^28) and the ends
KK_EDGE = EDGE32 + [s * ((1 << 28) + d) for s in (1, -1)
                    for d in (-69633, -65536 - 4096, -65536, -61441, -24576, -12288, -8193, -4097,
                              -4096, -4095, -1, 0, 4095, 4096, 8191, 8192)]


@functools.lru_cache(maxsize=None)
def _kk_short_exe():
    import subprocess
    d = cbuild.scratch_dir("imf_kk_short_")
    (d / "kk.c").write_text(KK_DRIVER)
    exe = d / "kk"
    subprocess.run(["gcc", *cbuild.CFLAGS, *(cbuild.UBSAN if cbuild.USE_UBSAN else []),
                    "-DIMF_SCALE_SHORT=1", f"-I{cbuild.FIXED}", str(d / "kk.c"),
                    str(cbuild.FIXED / "gravity_q.c"), "-o", str(exe), "-lm"],
                   check=True, capture_output=True, text=True)
    return exe


def _kk_check(cases):
    import subprocess

    import numpy as np

    from imufuse.reference import KKQ
    lines, want = [], []
    for p, t0, t1, g, a in cases:
        r = KKQ(*KK_PARAMS[p][:2], gyr_scale=KK_PARAMS[p][2])
        c = r.c_init_args()
        lines.append(f"{t0} {t1} {' '.join(map(str, g))} {' '.join(map(str, a))} "
                     f"{c['kw'].m} {c['kw'].s} {c['kp16_m']} {c['kp16_j']}\n")
        r.state = np.array([t0, t1], dtype=np.int64)
        want.append([int(x) for x in r.run(np.array([g], np.int16), np.array([a], np.int16))[0]])
    p = subprocess.run([str(_kk_short_exe())], input="".join(lines), capture_output=True, text=True)
    assert p.returncode == 0 and "runtime error" not in p.stderr, p.stderr[-2000:]
    got = [[int(x) for x in ln.split()] for ln in p.stdout.strip().split("\n")]
    assert got == want


def test_kk_q_avr_code_on_host_edges():
    """KKQ's update as built for AVR (imf_kk_q_q15 in 16-bit steps), on the host with
    UBSan: the reference's states after one update, for every pair of edge states (the q15
    saturation of the cross terms at |theta| = 1 rad, the int32 ends) and edge inputs."""
    ins = [((0, 0, 0), (0, 0, 0)), ((32767, -32768, 32767), (-32768, 32767, 1)),
           ((-32768, 32767, -32768), (4096, -4096, 0)), ((100, -200, 300), (0, 0, 4096))]
    check_cases = [(p, t0, t1, g, a) for p in range(len(KK_PARAMS)) for t0 in KK_EDGE
                   for t1 in KK_EDGE[::3] for g, a in ins]
    _kk_check(check_cases)


@settings(max_examples=30, deadline=None, suppress_health_check=list(HealthCheck))
@given(st.lists(st.tuples(st.integers(0, len(KK_PARAMS) - 1), i32, i32,
                          st.tuples(i16, i16, i16), st.tuples(i16, i16, i16)),
                min_size=20, max_size=200))
def test_kk_q_avr_code_on_host_random(cases):
    _kk_check(cases)
