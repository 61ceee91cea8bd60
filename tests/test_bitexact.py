"""The C builds equal the pure-Python references bit for bit: every state
variable after every sample, for every filter in the registry, both
precisions, on every input sequence of its kind."""
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from bits import assert_same_bits, first_difference
from imufuse.registry import (DTYPES, FLOAT_CASES, case_params, each_dtype)
from sequences import SEQUENCES, generate

@pytest.mark.parametrize("case", case_params(FLOAT_CASES))
@each_dtype
def test_run_matches_reference(case, dtype):
    """Every input sequence of the filter's kind (tests/sequences.py), one item per
    configuration; a failure names the sequence."""
    for seq in SEQUENCES[case.kind]:
        try:
            _run_matches_reference(case, dtype, seq)
        except AssertionError as e:
            raise AssertionError(f"sequence {seq!r}: {e}") from e


def _run_matches_reference(case, dtype, seq):
    inputs = generate(case.kind, seq)
    c, r = case.make("c", dtype), case.make("ref", dtype)
    got, want = c.run(*inputs), r.run(*inputs)
    assert_same_bits(got, want, c.state_names)
    assert c.skipped == r.skipped
    assert_same_bits(c.state, r.state, c.state_names)
    assert np.isfinite(got).all()


@pytest.mark.parametrize("case", case_params(FLOAT_CASES))
@each_dtype
def test_update_matches_run(case, dtype):
    """update() sample by sample gives the trajectory run() gives, on both
    backends; the sequence includes non-finite samples."""
    inputs = generate(case.kind, "nonfinite", seed=1, n=300)
    for backend in ("c", "ref"):
        f = case.make(backend, dtype)
        traj = f.run(*inputs)
        f.reset()
        steps = []
        for row in zip(*inputs):
            f.update(*row)
            steps.append(f.state)
        assert_same_bits(np.array(steps), traj, f.state_names)


@pytest.mark.parametrize("case", case_params(FLOAT_CASES))
@each_dtype
def test_state_set_and_reset(case, dtype):
    inputs = generate(case.kind, "random", n=50)
    c, r = case.make("c", dtype), case.make("ref", dtype)
    init = c.state.copy()
    c.run(*inputs)
    snapshot = c.state
    r.state = snapshot
    tail = generate(case.kind, "random", seed=7, n=50)
    assert_same_bits(c.run(*tail), r.run(*tail), c.state_names)
    c.reset()
    assert_same_bits(c.state, init)
    assert c.skipped == 0


def _hyp_inputs(kind, width):
    x = st.floats(width=width, allow_nan=True, allow_infinity=True)
    if kind == "1d":
        row = st.tuples(x, x)
        return st.lists(row, min_size=1, max_size=60).map(
            lambda rows: tuple(np.array(col) for col in zip(*rows)))
    vec = st.tuples(x, x, x)
    nvec = 2 if kind == "imu" else 3
    return st.lists(st.tuples(*[vec] * nvec), min_size=1, max_size=40).map(
        lambda rows: tuple(np.array(col, dtype=float) for col in zip(*rows)))


@pytest.mark.parametrize("case", case_params(FLOAT_CASES))
@each_dtype
def test_hypothesis_sequences(case, dtype):
    width = 32 if dtype == "float32" else 64

    @settings(max_examples=40, deadline=None, suppress_health_check=list(HealthCheck),
              derandomize=True)
    @given(_hyp_inputs(case.kind, width))
    def check(inputs):
        c, r = case.make("c", dtype), case.make("ref", dtype)
        assert_same_bits(c.run(*inputs), r.run(*inputs), c.state_names)
        assert c.skipped == r.skipped

    check()


# ---- the harness sees one ulp ------------------------------------------------

def test_harness_sees_one_ulp():
    a = np.linspace(-1, 1, 12, dtype=np.float32).reshape(4, 3)
    b = a.copy()
    b[2, 1] = np.nextafter(b[2, 1], np.float32(np.inf))
    msg = first_difference(b, a, ("x", "y", "z"))
    assert msg is not None and "sample 2, variable y" in msg and "max 1 ulp" in msg
    assert first_difference(a, a.copy()) is None
    z = np.zeros(3)
    assert first_difference(z, -z) is not None      # +0 and -0 differ in bits


@pytest.mark.parametrize("dtype", DTYPES)
def test_harness_catches_reassociation(dtype):
    """A reference with one expression re-associated, (Kp e + I) + w turned into
    Kp e + (I + w), must fail the comparison with the C build."""
    import imufuse.reference as reference
    from imufuse.registry import Case

    class Reassociated(reference.Mahony1DBias):
        def _update(self, rate, angle):
            e = angle - self.theta
            i = self.i + self.ki_dt * e
            self.theta = self.theta + (self.kp * e + (i + rate)) * self.dt
            self.i = i

    case = Case("Mahony1DBias", dict(dt=0.01, kp=2.0, ki=0.3))
    inputs = generate("1d", "random")
    got = case.make("c", dtype).run(*inputs)
    bad = Reassociated(**case.params, dtype=dtype).run(*inputs)
    msg = first_difference(got, bad, ("theta", "i"))
    assert msg is not None, "re-association went unnoticed"
    print(msg)
