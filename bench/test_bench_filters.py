"""Speed of every filter in the registry (pytest-benchmark; run with
`pytest bench/`, kept out of the default test run).

  run        imufuse_c run() on 10^6 samples            -> ns per sample
  plain      a plain C loop over the same update (cffi)   -> run / plain ratio
  update     imufuse_c update() per call from Python      -> ns per call
  reference  the pure-Python reference, per sample

Both run() and plain allocate their output array per call (a fresh array of
N x len(state) values, as run() returns). run and plain are timed side by side, interleaved, in the same test (min of
several repeats each), so their ratio is robust on a shared, noisy machine;
it is stored in the benchmark's extra_info and printed by bench/report.py.
"""

import numpy as np
import pytest

import imufuse.reference as reference
from plain_loop import build
from timing import best_of
from imufuse.registry import DTYPES, FLOAT_CASES
from sequences import generate

N_RUN = 10 ** 6
N_REF = 2000

_plain = {}


def plain_lib(dtype):
    if dtype not in _plain:
        classes = sorted({getattr(reference, c.name) for c in FLOAT_CASES}, key=lambda c: c.__name__)
        _plain[dtype] = build(dtype, classes)
    return _plain[dtype]


def big_inputs(kind, dtype):
    reps = N_RUN // 1000
    return tuple(np.ascontiguousarray(np.concatenate([x] * reps), dtype=dtype)
                 for x in generate(kind, "random"))


def plain_runner(case, dtype, inputs):
    """The plain C loop as a callable returning its (N, len(state)) output,
    allocated per call exactly as run() allocates its result."""
    ffi, lib = plain_lib(dtype)
    ref = getattr(reference, case.name)
    fn = getattr(lib, f"plain_{ref.c_update}")
    p = np.array(ref._params(**case.params), dtype=float)
    shape = (len(inputs[0]), len(ref.state_names))
    ctype = "float *" if dtype == "float32" else "double *"
    args = [ffi.cast(ctype, ffi.from_buffer(x)) for x in inputs]
    pp = ffi.cast("double *", ffi.from_buffer(p))

    def call():
        out = np.empty(shape, dtype=dtype)
        fn(shape[0], *args, ffi.cast(ctype, ffi.from_buffer(out)), pp, len(p))
        return out
    return call


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("case", [pytest.param(c, id=c.id) for c in FLOAT_CASES])
def test_run(benchmark, case, dtype):
    inputs = big_inputs(case.kind, dtype)
    f = case.make("c", dtype)
    plain = plain_runner(case, dtype, inputs)
    # side by side: alternate run() and the plain loop, keep the best of each
    t_run, t_plain = [], []
    for _ in range(5):
        f.reset()
        t_run.append(best_of(lambda: f.run(*inputs), 1))
        t_plain.append(best_of(plain, 1))
    f.reset()
    traj = f.run(*inputs)
    assert (traj.view(np.uint8) == plain().view(np.uint8)).all()   # same work, same bits
    benchmark.extra_info.update(
        samples=N_RUN, ns_per_sample=min(t_run) / N_RUN * 1e9,
        plain_ns_per_sample=min(t_plain) / N_RUN * 1e9, run_over_plain=min(t_run) / min(t_plain))
    benchmark.pedantic(lambda: f.run(*inputs), setup=f.reset, rounds=3, iterations=1)


@pytest.mark.parametrize("case", [pytest.param(c, id=c.id) for c in FLOAT_CASES])
def test_update(benchmark, case):
    f = case.make("c", "float64")
    args = [x[0] for x in generate(case.kind, "random", n=1)]
    if case.kind == "1d":
        args = [float(a) for a in args]
    benchmark(f.update, *args)


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("case", [pytest.param(c, id=c.id) for c in FLOAT_CASES])
def test_reference(benchmark, case, dtype):
    inputs = generate(case.kind, "random", n=N_REF)
    f = case.make("ref", dtype)
    benchmark.extra_info.update(samples=N_REF)
    benchmark.pedantic(lambda: f.run(*inputs), setup=f.reset, rounds=2, iterations=1)


# ---- per-sample time steps (docs/time-and-init.md) -----------------------------
# run(..., dt=array) recomputes the dt-derived constants before every sample;
# compare ns_per_sample with test_run's (the fixed-step path, which must not
# change), and update(..., dt=...) with test_update.

@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("case", [pytest.param(c, id=c.id) for c in FLOAT_CASES])
def test_run_dt(benchmark, case, dtype):
    inputs = big_inputs(case.kind, dtype)
    g = np.random.default_rng(0)
    dt = case.params["dt"] * g.uniform(0.76, 3.0, len(inputs[0]))   # x-io log: 7.6-30.2 ms
    f = case.make("c", dtype)
    t = best_of(lambda: f.run(*inputs, dt=dt), 3)
    benchmark.extra_info.update(samples=N_RUN, ns_per_sample=t / N_RUN * 1e9)
    benchmark.pedantic(lambda: f.run(*inputs, dt=dt), setup=f.reset, rounds=3, iterations=1)


@pytest.mark.parametrize("case", [pytest.param(c, id=c.id) for c in FLOAT_CASES])
def test_update_dt(benchmark, case):
    f = case.make("c", "float64")
    args = [x[0] for x in generate(case.kind, "random", n=1)]
    if case.kind == "1d":
        args = [float(a) for a in args]
    dt = case.params["dt"] * 1.25
    benchmark(lambda: f.update(*args, dt=dt))
