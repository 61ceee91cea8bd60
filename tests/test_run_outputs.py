"""run(..., outputs="q") keeps only the state words the quaternion is read from while the
filter runs (imufuse.shared.estimate.output_columns): the same quaternions, to the bit, as
imufuse.shared.estimate.run_outputs reads from the whole trajectory, for every 3-D float filter of
the catalogue (quaternion, matrix, gravity and Euler states), both precisions, at the fixed
dt, with per-sample dt and from init="first"; the filter's state afterwards is the one run()
leaves; a hostile burst changes nothing of that."""
import numpy as np
import pytest

import imufuse_c
from imufuse import catalogue, io, sim
from imufuse.shared import estimate
from imufuse.session import RunOptions, Session

ENTRIES = [e.name for e in catalogue.FLOAT
           if catalogue.reference_class(e.name).kind in ("imu", "ahrs")]


@pytest.fixture(scope="module")
def data():
    d = sim.imu("fast", rate=200.0, duration=10.0, seed=11)
    gyr, acc, mag = d.gyr.copy(), d.acc.copy(), d.mag.copy()
    gyr[300] = np.nan                      # rejected samples: the state is kept, so is q
    acc[400:420] = 0.0
    mag[500] = 1e300
    dts = np.full(len(gyr), d.dt)
    dts[::5] *= 1.3
    return d.dt, (gyr, acc, mag), dts


def _bits(a):
    return np.ascontiguousarray(a).view(np.uint64)


@pytest.mark.parametrize("dtype", ["float32", "float64"])
@pytest.mark.parametrize("name", ENTRIES)
def test_outputs_q_is_the_trajectory_read(name, dtype, data):
    dt, ins, dts = data
    cls = getattr(imufuse_c, name)
    ins = ins if cls.kind == "ahrs" else ins[:2]
    p = catalogue.resolve_params(name, dt, {}, None)
    for kw, start in ((dict(), {}), (dict(dt=dts), {}), (dict(), dict(init="first"))):
        f = cls(**p, **start, dtype=dtype)
        full = f.run(*ins, **kw)
        after_full = f.state.copy()
        f.reset()
        q = f.run(*ins, **kw, outputs="q")
        assert q.shape == (len(ins[0]), 4) and q.dtype == np.float64
        assert np.array_equal(_bits(q), _bits(estimate.run_outputs(f, full, "q"))), (name, kw)
        assert np.array_equal(f.state, after_full, equal_nan=True)


def test_what_is_kept_follows_the_state_names():
    """The words kept per adapter: a quaternion's four, a matrix's nine, a gravity vector's
    three, the Euler angles by name; anything else is refused as run_outputs refuses it."""
    class F:
        kind = "imu"

        def __init__(self, names):
            self.state_names = names
    assert estimate.output_columns(F(("q0", "q1", "q2", "q3", "b")), "q") == \
        ("quaternion", (0, 1, 2, 3))
    m = tuple(f"r{i}{j}" for i in range(3) for j in range(3)) + ("x",)
    assert estimate.output_columns(F(m), "q") == ("matrix", tuple(range(9)))
    assert estimate.output_columns(F(("gx", "gy", "gz", "w")), "q") == ("gravity", (0, 1, 2))
    assert estimate.output_columns(F(("a", "roll", "b", "pitch")), "q") == ("euler", (1, 3))
    with pytest.raises(ValueError, match="outputs: must be one of"):
        estimate.output_columns(F(("q0", "q1", "q2", "q3")), "quat")
    with pytest.raises(ValueError, match="no orientation"):
        estimate.output_columns(F(("a", "b")), "q")
    f = imufuse_c.MadgwickIMU(dt=0.01)
    with pytest.raises(ValueError, match="outputs: must be one of"):
        f.run(np.zeros((3, 3)), np.ones((3, 3)), outputs="euler")


@pytest.mark.parametrize("name", ENTRIES)
def test_the_session_streams_the_same_estimate(name):
    """Session.run(keep_states=False), what compare and tune run: the compiled filter keeps
    only its quaternion's words while it runs, block by block; the estimate is the one read
    from the whole trajectory (keep_states=True), bit for bit, with its heading and source."""
    s = Session(io.example_log())
    a = s.run(name, {}, RunOptions(), keep_states=False)
    b = s.run(name, {}, RunOptions(), keep_states=True)
    assert a.estimate is not None and b.estimate is not None
    assert np.array_equal(_bits(a.estimate.q), _bits(b.estimate.q))
    assert (a.estimate.heading, a.estimate.source) == (b.estimate.heading, b.estimate.source)
    assert a.rejected == b.rejected and len(a.states) == 0


def test_the_quaternion_adapter_is_unit_and_the_norm_within_an_ulp():
    """The adapter's |q| (summed in a fixed order, as the compiled outputs="q" sums it) is the
    norm numpy's linalg gives within an ulp, and each quaternion unit within 2 ulp."""
    rng = np.random.default_rng(5)
    S = rng.normal(size=(20_000, 4)) * rng.uniform(0.5, 2.0, size=(20_000, 1))
    q = estimate.ADAPTERS["quaternion"](("q0", "q1", "q2", "q3"), "ahrs", S).q
    ref = S / np.linalg.norm(S, axis=1, keepdims=True)
    assert np.abs(q - ref).max() <= 2 * np.finfo(float).eps
    assert np.abs(np.linalg.norm(q, axis=1) - 1.0).max() <= 4 * np.finfo(float).eps
