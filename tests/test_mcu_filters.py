"""Every filter configuration of the registry on the emulated MCUs, bit for bit.

For each (configuration, precision) of imufuse.registry and each target, the state after every
sample on Cortex-M4F (qemu), Cortex-M0 (qemu, soft float) and ATmega328P (simavr; float32 and
fixed point only: its double is 32 bits) has the same bit patterns as the host build of the same
C and as the pure-Python reference; so do the `skipped` counters. Nothing here knows a filter by
name: the C calls come from the reference class (c_name, kind, state_names, _params) and the
headers (imufuse.mcu.library).

Inputs: a few hundred samples of simulated motion (imufuse.sim) and the corners (zero
accelerometer and magnetometer, NaN/Inf, overflow, tiny and subnormal values; for fixed point
full-scale counts). All filters of one precision and input set share one program per target.

test_arithmetic checks the elementary operations (+ - * / sqrt) of each target's float
implementation against correctly rounded results, so a filter mismatch can be traced to the
operation that differs and by how many ulp.
"""

import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from imufuse import registry
from bits import ulps

import imufuse.mcu as mcu
from imufuse.mcu import filters as mf

import imufuse.reference as reference  # noqa: E402

TARGETS = ["host", "m4f", "m0", "avr"]
N_MOTION = 300
# a filter whose program does not fit the AVR's flash with N_MOTION samples stored in it
# runs there alone on N_MOTION_SMALL samples (and the same corner cases), against the
# reference on those inputs, built with -Os where even that does not fit at -O2 (RobustAHRS
# float32 on the ATmega328P; imufuse.mcu.filters.run_fitting, as bench/mcu/measure.py)
N_MOTION_SMALL = mf.N_MOTION_SMALL

SPECS = mf.specs_from_cases([*registry.FLOAT_CASES, *getattr(registry, "FIXED_CASES", []),
                             *getattr(registry, "CASES_VARIO", [])], reference)
GROUPS = mf.groups(SPECS)


@pytest.fixture(scope="session")
def toolchains():
    """{target: reason} of targets that cannot run here, after trying to install."""
    return mcu.ensure_toolchains(TARGETS)


def need(toolchains, target):
    if target in toolchains:
        pytest.skip(f"toolchain for {target} unavailable: {toolchains[target]}")


# --------------------------------------------------------------------------------------------
# all programs, built and run once per session (in parallel: builds and emulators are processes)


class _Runs:
    """Every group of SPECS on every target of ``targets`` (tests/test_mcu_cores.py runs the
    same on the cores added later)."""

    def __init__(self, toolchains, targets=TARGETS, workers=8):
        self.inputs = {}
        self.out = {}
        self.ref = {}
        # the objects compiled for each target (programs.build): a source or port file is
        # compiled once per target, precision and flags, whichever program needs it first
        self.objects = {t: {} for t in targets}
        jobs = []
        for prec, grp in GROUPS:
            self.inputs[prec, grp] = mf.inputs_for(prec, grp, N_MOTION)
            for t in targets:
                if t not in toolchains and prec in mf.TARGET_PRECISIONS[t]:
                    jobs.append((t, prec, grp))
        t0 = time.perf_counter()
        with ThreadPoolExecutor(max_workers=workers) as ex:
            futs = {j: ex.submit(self._one, *j) for j in jobs}
            for s in SPECS:
                self.ref[s.label] = mf.reference_states(s, self.inputs[s.group])
            for j, f in futs.items():
                try:
                    self.out[j] = f.result()
                except Exception as e:  # reported by the tests that need it
                    self.out[j] = e
        self.seconds = time.perf_counter() - t0

    def _one(self, target, prec, grp):
        # the group in as few programs as fit (run_filters splits it); on the AVR a filter
        # whose program does not fit alone with N_MOTION samples stored runs alone, on fewer
        # samples where it must (run_fitting)
        unfit, objects, common = [], self.objects[target], self.inputs[prec, grp]
        r = mf.run_filters(target, GROUPS[prec, grp], common, timeout=600,
                           unfit=unfit if target == "avr" else None, objects=objects)
        if not unfit:
            return r
        out = {s.label: (st, sk, None) for s, st, sk in zip(r.specs, r.states, r.skipped)}
        for spec in unfit:
            one, used = mf.run_fitting(target, [spec], N_MOTION, N_MOTION_SMALL, inputs=common,
                                       timeout=600, objects=objects)
            out[spec.label] = (one.states[0], one.skipped[0], None if used is common else used)
        return out

    def get(self, target, spec):
        """(states, skipped, inputs): inputs None for the common N_MOTION inputs."""
        r = self.out[(target, *spec.group)]
        if isinstance(r, Exception):
            raise r
        if isinstance(r, dict):
            return r[spec.label]
        i = r.specs.index(spec)
        return r.states[i], r.skipped[i], None


@pytest.fixture(scope="session")
def runs(toolchains):
    return _Runs(toolchains)


def _describe(got_bits, want_bits, spec, what):
    """None if equal; else the first differing sample and variable, values and ulp."""
    if got_bits.shape != want_bits.shape:
        return f"{what}: shapes differ {got_bits.shape} vs {want_bits.shape}"
    diff = got_bits != want_bits
    if not diff.any():
        return None
    k, j = (int(v) for v in np.argwhere(diff)[0])
    sdt = spec.state_dtype()
    g = mf.bits_as_values(got_bits, sdt)
    w = mf.bits_as_values(want_bits, sdt)
    name = spec.ref_class.state_names[j]
    msg = (f"{spec.label} {what}: first difference at sample {k}, {name}: {g[k, j]!r} vs "
           f"{w[k, j]!r}; {int(diff.sum())} values in {int(diff.any(axis=1).sum())} samples differ")
    if sdt.kind == "f":
        msg += f", max {ulps(g[diff], w[diff]).max():.0f} ulp"
    else:
        msg += f", max {int(np.abs(g[diff].astype(np.int64) - w[diff].astype(np.int64)).max())} LSB"
    return msg + " (see test_arithmetic for the elementary operations of the target)"


@pytest.mark.parametrize("spec", [pytest.param(s, id=s.label) for s in SPECS])
def test_state_bits(runs, toolchains, spec):
    """The target's trajectory equals the host build's and the reference's, bit for bit, on
    every target that runs the spec's precision (one item per spec)."""
    problems = []
    for target in TARGETS:
        if spec.precision in mf.TARGET_PRECISIONS[target]:
            problems += _state_bits(runs, toolchains, spec, target)
    assert not problems, "\n".join(problems)


def _state_bits(runs, toolchains, spec, target):
    need(toolchains, target)
    got, got_sk, small = runs.get(target, spec)
    want, want_sk = runs.ref[spec.label] if small is None else mf.reference_states(spec, small)
    problems = [_describe(got, want, spec, f"{target} vs Python reference")]
    if target != "host" and ("host", *spec.group) in runs.out and small is None:
        host, host_sk, _ = runs.get("host", spec)
        problems.append(_describe(got, host, spec, f"{target} vs host C"))
        if got_sk is not None and not np.array_equal(got_sk, host_sk):
            k = int(np.argmax(got_sk != host_sk))
            problems.append(f"{target} skipped counter differs from host at sample {k}")
    if got_sk is not None and want_sk >= 0 and int(got_sk[-1]) != want_sk:
        problems.append(f"{target} skipped = {int(got_sk[-1])}, reference {want_sk}")
    return [p for p in problems if p]


def test_inputs_reach_the_corners():
    """The input sets hold what the docstring promises (and fit AVR flash with the code)."""
    for (prec, grp) in GROUPS:
        ins = mf.inputs_for(prec, grp, N_MOTION)
        n = len(next(iter(ins.values())))
        assert N_MOTION < n < 400
        if prec.startswith("float"):
            flat = np.concatenate([np.asarray(v, float).reshape(n, -1) for v in ins.values()], axis=1)
            assert np.isnan(flat).any() and np.isinf(flat).any()
            rows3 = [v for v in ins.values() if np.ndim(v) == 2]
            for v in rows3:  # zero vectors: the normalisation guards
                assert (np.abs(np.asarray(v, float)).sum(axis=1) == 0).any()
        else:
            flat = np.concatenate([v.reshape(n, -1) for v in ins.values()], axis=1)
            assert flat.min() == -32768 and flat.max() == 32767


def test_every_registry_configuration_runs(runs, toolchains):
    """No configuration of the registry is left out, and every program ran on every target."""
    assert len(SPECS) >= 2 * len(registry.FLOAT_CASES)
    for key, r in runs.out.items():
        if isinstance(r, Exception):
            raise AssertionError(f"{key}: {r}") from r
    for t in TARGETS:
        if t in toolchains:
            continue
        for s in SPECS:
            if s.precision in mf.TARGET_PRECISIONS[t]:
                assert (t, *s.group) in runs.out


def test_a_difference_is_caught(toolchains):
    """The comparison can fail: a filter built with one wrong constant differs from its
    reference, and the message names sample, variable and ulp."""
    need(toolchains, "m0")
    s = next(s for s in SPECS if s.precision == "float32")
    ins = mf.inputs_for("float32", s.group[1], 40)
    good = mf.run_filters("m0", [s], ins)
    bad_spec = mf.FilterSpec.make(s.ref_class, s.params, "float32", s.label)
    bad_spec._init_args = lambda: [a + "*1.0000001f" if a.endswith("f") else a
                                   for a in mf.FilterSpec._init_args(s)]
    bad = mf.run_filters("m0", [bad_spec], ins)
    want, _ = mf.reference_states(s, ins)
    assert _describe(good.states[0], want, s, "m0") is None
    msg = _describe(bad.states[0], want, s, "m0")
    assert msg is not None and "first difference at sample" in msg and "ulp" in msg


def test_a_fixed_point_difference_is_caught(toolchains):
    """The integer comparison can fail too: one constant off by one LSB of its mantissa makes
    the trajectory differ, and the message names sample, variable and LSB."""
    need(toolchains, "avr")
    s = next(s for s in SPECS if s.fixed and s.ref_class.__name__ == "MahonyIMUQ")
    ins = mf.inputs_for(s.precision, s.group[1], 40)
    bad_spec = mf.FilterSpec.make(s.ref_class, s.params, s.precision, s.label)
    args = mf.FilterSpec._init_args(s)
    bad_spec._init_args = lambda: [args[0].replace("(int16_t)", "(int16_t)1+", 1), *args[1:]]
    bad = mf.run_filters("avr", [bad_spec], ins)
    want, _ = mf.reference_states(s, ins)
    msg = _describe(bad.states[0], want, s, "avr")
    assert msg is not None and "first difference at sample" in msg and "LSB" in msg


def _init_codes(target, specs):
    """{label: code} of each fixed filter's double init against its constants init, run on
    target in one program: bit 2 the double init failed, bit 1 the constants init, bit 0
    the two structs differ."""
    pre, body, state = ["#include <string.h>"], [], []
    for i, s in enumerate(specs):
        c = s.c
        v = f"imf_a{i}"
        # the settings filled on the stack (static=False), as the constants: static structs
        # for every filter would not fit the ATmega328P's 2 KB of RAM
        fa, ca = mf.init_call(c.c_name + "_init", v, c.init_struct, c.init, s.double_init_args(),
                              static=False)
        fb, cb = mf.init_call(s.init_function, v + "b", c.init_consts_struct, c.init_consts,
                              s._init_args(), static=False)
        # the pair of filters on the stack, in a block of its own: the compiler reuses the
        # space for the next pair
        pre.append(f'#include "{c.header.name}"\nstatic int32_t imf_r{i};')
        body.append(f"{{ {c.c_name}_t {v}, {v}b;\n"
                    f"memset(&{v}, 0, sizeof {v}); memset(&{v}b, 0, sizeof {v}b);\n"
                    f"{{ {fa} {fb}\n"
                    f"imf_r{i} = {ca} * 4\n"
                    f"    + {cb} * 2\n"
                    f"    + (memcmp(&{v}, &{v}b, sizeof {v}) != 0); }} }}")
        state.append((f"imf_r{i}", "i32"))
    drv = mcu.Driver(prelude="\n".join(pre), step="\n".join(body), state=state)
    res = mcu.run(target, sources=sorted({str(s.c.source) for s in specs}),
                  include_dirs=[mf.CSRC, mf.CSRC / "fixed"], driver=drv,
                  inputs={"k": np.zeros(1, np.int16)})
    return {s.label: int(col[0]) for s, col in zip(specs, res.values())}


@pytest.mark.parametrize("target", ["host", "avr"])
def test_fixed_init_from_double_and_from_constants(toolchains, target):
    """imf_<f>_init (double parameters) and imf_<f>_init_consts (the reference's integer
    constants) build the same struct, byte for byte, on the host; on AVR, whose double is 32
    bits, the double init may differ (that is why the MCU runs use _init_consts), and the
    constants path matches the host there by construction (test_state_bits)."""
    need(toolchains, target)
    fixed = [s for s in SPECS if s.fixed]
    # one program for all (the ATmega328P's 32 KB: one per source file)
    groups = ([[s for s in fixed if s.c.source == src]
               for src in sorted({s.c.source for s in fixed})] if target == "avr" else [fixed])
    codes = {}
    for specs in groups:
        codes.update(_init_codes(target, specs))
    # bit 2: double init failed, bit 1: constants init failed, bit 0: structs differ
    assert all(c & 6 == 0 for c in codes.values()), codes
    if target == "host":
        assert all(c == 0 for c in codes.values()), codes


def test_the_harness_init_call_compiles_for_every_filter(tmp_path):
    """Every configuration's init as the harness writes it (FilterSpec.c_parts: a settings
    struct as a static const initialiser, the form whose flash bench/mcu/measure.py reports;
    fixed point by its constants, and by its double init) compiles with the harness's flags,
    warnings as errors, in C99 and in C++ (the Arduino sketches are C++), one translation
    unit per build (precision, profile)."""
    import subprocess
    builds = {}
    for s in SPECS:
        builds.setdefault(tuple(sorted(s.defines.items())), []).append(s)
    assert len(builds) >= 3
    for key, specs in builds.items():
        pre, body = ["void imf_port_write(const char *s);"], []
        for i, s in enumerate(specs):
            for dbl in (False, True) if s.fixed else (False,):
                v = f"imf_f{i}{'d' if dbl else ''}"
                p, init, _, _ = s.c_parts(v, double_init=dbl)
                pre.append(p)
                body.append(init)
                if s.c.init_struct and (dbl or not s.fixed):
                    assert f"static const {s.c.init_struct} {v}_set = {{" in init, init
        src = tmp_path / f"init_{len(body)}.c"
        src.write_text("\n".join(pre) + "\nvoid imf_init_all(void)\n{\n" + "\n".join(body) + "\n}\n")
        defs = [f"-D{k}" if v is None else f"-D{k}={v}" for k, v in key]
        inc = [f"-I{mf.CSRC}", f"-I{mf.CSRC / 'fixed'}"]
        for cmd in ([mcu.TARGETS["host"].cc, *mcu.cflags("host")],
                    ["c++", "-x", "c++", "-std=gnu++11", "-O2", "-Wall", "-Wextra", "-Werror"]):
            r = subprocess.run([*cmd, *defs, *inc, "-c", str(src), "-o", str(tmp_path / "init.o")],
                               capture_output=True, text=True)
            assert r.returncode == 0, f"{' '.join(cmd[:2])} {key}:\n{r.stderr[-3000:]}"


def _host_codes(calls, struct, unit):
    """Return values of C calls (expressions of imf_f, a static ``struct``) on the host, built
    with csrc/fixed/``unit``.c."""
    body = "\n".join(f"imf_r{i} = {c};" for i, c in enumerate(calls))
    pre = f'#include "{unit}.h"\nstatic {struct} imf_f;\n' + "".join(
        f"static int32_t imf_r{i};\n" for i in range(len(calls)))
    drv = mcu.Driver(prelude=pre, step=body, state=[(f"imf_r{i}", "i32") for i in range(len(calls))])
    res = mcu.run("host", sources=[str(mf.CSRC / "fixed" / f"{unit}.c")],
                  include_dirs=[mf.CSRC, mf.CSRC / "fixed"], driver=drv,
                  inputs={"k": np.zeros(1, np.int16)})
    return [int(col[0]) for col in res.values()]


def test_complementary1d_q_init_consts_checks_the_gain(toolchains):
    """imf_complementary1d_q_init_consts stores the 16-bit gain ka16 (m, j) as given: it
    accepts the reference's constants for alpha 0, 1 and in between, and rejects a gain
    imf_gain16 cannot give for 1 - alpha in [0, 1]."""
    need(toolchains, "host")
    from imufuse.reference import Complementary1DQ
    good = [Complementary1DQ(0.002, a, gyr_scale=1e-3, angle_scale=1e-4).c_init_args()
            for a in (0.0, 1.0, 0.5, 0.995, 1.0 - 2.0 ** -30)]
    kr = good[0]["kr"]
    bad = [(0, -1), (16384, -1), (1, -2), (0, -3), (300, 5), (255, 0), (1, 4)]
    cases = [(g["kr"], g["ka16_m"], g["ka16_j"]) for g in good] + [(kr, m, j) for m, j in bad]
    calls = [f"imf_complementary1d_q_init_consts(&imf_f, (imf_qscale_t){{{k.m}, {k.s}}}, {m}u, {j})"
             for k, m, j in cases]
    codes = _host_codes(calls, "imf_complementary1d_q_t", "filters_1d_q")
    assert codes == [0] * len(good) + [-1] * len(bad), (cases, codes)


def test_kk_q_init_checks_kp(toolchains):
    """KKQ takes kp in [0, 1] (kp > 1 corrects more than the whole error in one sample):
    imf_kk_q_init rejects kp = 1.5 and accepts kp = 1, the reference raises a ValueError
    naming kp; imf_kk_q_init_consts stores the 16-bit gain kp16 (m, j) as given: it accepts
    the reference's constants for kp 0, 1 and in between, and rejects a gain imf_gain16
    cannot give for kp in [0, 1]."""
    need(toolchains, "host")
    from imufuse.reference import KKQ
    with pytest.raises(ValueError, match="kp"):
        KKQ(0.002, 1.5, gyr_scale=1e-3)
    good = [KKQ(0.002, k, gyr_scale=1e-3).c_init_args() for k in (0.0, 1.0, 0.5, 0.002, 1.0 - 2.0 ** -30)]
    kw = good[0]["kw"]
    bad = [(0, -1), (16384, -1), (1, -2), (0, -3), (300, 5), (255, 0), (1, 4)]
    calls = [f"imf_kk_q_init_consts(&imf_f, (imf_qscale_t){{{g['kw'].m}, {g['kw'].s}}}, "
             f"{g['kp16_m']}u, {g['kp16_j']})" for g in good]
    calls += [f"imf_kk_q_init_consts(&imf_f, (imf_qscale_t){{{kw.m}, {kw.s}}}, {m}u, {j})"
              for m, j in bad]
    calls += [f"imf_kk_q_init(&imf_f, &(imf_kk_q_settings_t){{0.002, {kp!r}, 1e-3}})"
              for kp in (1.0, 1.5)]
    want = [0] * len(good) + [-1] * len(bad) + [0, -1]
    assert _host_codes(calls, "imf_kk_q_t", "gravity_q") == want, calls


def test_mahony1d_bias_q_gain_range(toolchains):
    """Mahony1DBiasQ takes Kp dt < 1 and Ki dt^2 < 2^-8 (the 16-bit gains of its update):
    imf_mahony1d_bias_q_init returns -1 at and above those bounds, where the reference raises
    ValueError naming kp or ki; imf_mahony1d_bias_q_init_consts accepts the reference's
    constants and rejects 16-bit gains imf_gain16 cannot give below 1."""
    need(toolchains, "host")
    from imufuse.reference import Mahony1DBiasQ
    sc = dict(gyr_scale=1e-3, angle_scale=1e-4)
    ok = [(0.01, 99.9, 0.3), (0.01, 1e-3, 0.0), (0.01, 2.0, 0.0), (0.01, 2.0, 39.0),
          (0.002, 2.0, 0.2), (1e-5, 1e-3, 100.0), (0.1, 9.99, 0.39)]
    bad = [(0.01, 100.0, 0.3), (0.01, 150.0, 0.3), (0.01, 99.99999, 0.3), (0.01, 2.0, 39.0625),
           (0.01, 2.0, 100.0), (0.1, 2.0, 0.5)]
    for dt, kp, ki in bad:
        with pytest.raises(ValueError, match=r"^kp[:*]" if kp * dt >= 0.9999 else r"^ki[:*]"):
            Mahony1DBiasQ(dt, kp, ki, **sc)
    good = [Mahony1DBiasQ(dt, kp, ki, **sc).c_init_args() for dt, kp, ki in ok]
    dbl = [f"imf_mahony1d_bias_q_init(&imf_f, &(imf_mahony1d_bias_q_settings_t)"
           f"{{{dt!r}, {kp!r}, {ki!r}, 0, 1e-3, 1e-4}})" for dt, kp, ki in ok + bad]
    kr = good[0]["kr"]
    consts = [(g["kr"], g["kp16_m"], g["kp16_j"], g["ki16_m"], g["ki16_j"]) for g in good]
    wrong = [(0, -1), (16384, -1), (0, -2), (300, 5), (255, 0), (1, 4)]
    consts += [(kr, m, j, 300, 0) for m, j in wrong] + [(kr, 300, 0, m, j) for m, j in wrong]
    calls = dbl + [f"imf_mahony1d_bias_q_init_consts(&imf_f, &(imf_mahony1d_bias_q_consts_t)"
                   f"{{{{{k.m}, {k.s}}}, {pm}u, {pj}, {im}u, {ij}, 1}})"
                   for k, pm, pj, im, ij in consts]
    codes = _host_codes(calls, "imf_mahony1d_bias_q_t", "filters_1d_q")
    want = [0] * len(ok) + [-1] * len(bad) + [0] * len(good) + [-1] * (2 * len(wrong))
    assert codes == want, list(zip(calls, codes))


# --------------------------------------------------------------------------------------------
# elementary operations


OPS = ("add", "sub", "mul", "div", "sqrt")


def _operands(dtype, n=400, seed=3):
    """Pairs covering random bit patterns (subnormals included), close exponents (rounding
    of sums), products and quotients near the overflow and underflow thresholds."""
    rng = np.random.default_rng(seed)
    u = np.uint32 if dtype == np.float32 else np.uint64
    bits = 32 if dtype == np.float32 else 64
    finfo = np.finfo(dtype)

    def rand_bits(k):
        v = rng.integers(0, 2 ** bits - 1, k, dtype=np.uint64, endpoint=True).astype(u).view(dtype)
        v[~np.isfinite(v)] = dtype(1.5)
        return v

    q = n // 4
    a = [rand_bits(q), rng.uniform(-4, 4, q).astype(dtype)]
    b = [rand_bits(q), (rng.uniform(-4, 4, q) * np.exp2(rng.integers(-3, 4, q))).astype(dtype)]
    # products/quotients near the subnormal range and near overflow
    e = rng.integers(finfo.minexp - finfo.nmant, finfo.minexp + 4, q)
    a.append((rng.uniform(1, 2, q) * np.exp2(e // 2)).astype(dtype))
    b.append((rng.uniform(1, 2, q) * np.exp2(e - e // 2)).astype(dtype))
    m = rng.integers(finfo.maxexp - 4, finfo.maxexp, n - 3 * q)
    a.append((rng.uniform(1, 2, n - 3 * q) * np.exp2(m // 2)).astype(dtype))
    b.append((rng.uniform(1, 2, n - 3 * q) * np.exp2(m - m // 2)).astype(dtype))
    a, b = np.concatenate(a), np.concatenate(b)
    b[b == 0] = dtype(1)
    return a, b


def _expected(a, b):
    with np.errstate(all="ignore"):
        return {"add": a + b, "sub": a - b, "mul": a * b, "div": a / b, "sqrt": np.sqrt(np.abs(a))}


def _arith_params():
    return [pytest.param(t, p, id=f"{t}-{p}") for t in TARGETS
            for p in ("float32", "float64") if p in mf.TARGET_PRECISIONS[t]]


@pytest.mark.parametrize("target, precision", _arith_params())
def test_arithmetic(toolchains, target, precision):
    """+ - * / sqrt on the target are correctly rounded (IEEE 754 round to nearest, even),
    subnormals included: what the filters' bit-exactness rests on. A failure lists each
    operation that differs, how often, by how many ulp, with an example."""
    need(toolchains, target)
    dtype = np.float32 if precision == "float32" else np.float64
    t, sq, k = ("float", "sqrtf", "f32") if dtype == np.float32 else ("double", "sqrt", "f64")
    a, b = _operands(dtype)
    drv = mcu.Driver(
        prelude=f"#include <math.h>\nstatic volatile {t} r[5];",
        step=(f"r[0] = a + b; r[1] = a - b; r[2] = a * b; r[3] = a / b; "
              f"r[4] = {sq}({'fabsf' if t == 'float' else 'fabs'}(a));"),
        state=[(f"r[{i}]", k) for i in range(5)],
    )
    res = mcu.run(target, driver=drv, inputs={"a": a, "b": b}, timeout=300)
    got = res.values()
    want = _expected(a, b)
    problems = []
    for i, op in enumerate(OPS):
        g, w = got[i], want[op]
        nan = np.isnan(w)
        # NaN payloads are not specified by IEEE 754; only a NaN-ness mismatch is an error
        bad = np.where(nan, ~np.isnan(g),
                       g.view(g.dtype.str.replace("f", "u")) != w.view(w.dtype.str.replace("f", "u")))
        if bad.any():
            j = int(np.argmax(bad))
            d = ulps(g[bad & ~nan], w[bad & ~nan]) if (bad & ~nan).any() else np.array([np.inf])
            problems.append(
                f"{target} {precision} {op}: {int(bad.sum())} of {len(a)} differ, max {d.max():.0f} "
                f"ulp; e.g. a={float(a[j]).hex()} b={float(b[j]).hex()}: got {float(g[j]).hex()}, "
                f"correctly rounded {float(w[j]).hex()}")
    assert not problems, "\n".join(problems)
