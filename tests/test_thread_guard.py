"""One filter, one thread (docs/robustness.md): a compiled filter's run() updates its C
struct without the GIL, so while it runs every other use of the same object from another
thread (update, the state, reset, a copy or pickle, another run, run_filters, the setters
and getters) raises RuntimeError naming the class, instead of racing on the struct
(imufuse_c/_guard.pxi). The run itself is not disturbed: its trajectory and final state
are bit for bit a fresh filter's run over the same input, and the filter works again once
the run has returned. An exception raised inside the guarded region (bad input found after
the claim) leaves the filter free.

Each test starts a long run() in a thread, waits until the guard is visible (a state read
refused), then tries the other calls. If the run ends before that (a slow, loaded machine),
the attempt is repeated with a longer input: the outcome never depends on timing."""
import copy
import pickle
import threading
from dataclasses import dataclass, field
from typing import Callable, Dict

import numpy as np
import pytest

import imufuse_c

ATTEMPTS = 3        # input lengths n0, 2 n0, 4 n0


# ---- inputs -------------------------------------------------------------------------------
def _motion(n, dtype="float64", gyr_scale=1.0):
    """gyr, acc, mag (n, 3) of a slow wobble: every sample a little different."""
    k = np.arange(n, dtype=np.float64)
    gyr = np.stack([0.3 * np.sin(k * 1e-3), 0.2 * np.cos(k * 7e-4), 0.1 * np.sin(k * 3e-4)], 1)
    acc = np.stack([0.1 * np.sin(k * 2e-4), 0.1 * np.cos(k * 5e-4), np.full(n, 0.98)], 1)
    mag = np.stack([0.3 + 0.05 * np.sin(k * 1e-4), np.full(n, 0.05), np.full(n, -0.4)], 1)
    return tuple(np.ascontiguousarray(a * s, dtype=dtype)
                 for a, s in ((gyr, gyr_scale), (acc, 1.0), (mag, 1.0)))


def _counts(n, ahrs=False):
    """int16 gyr, acc (and mag) counts (n, 3) for the fixed-point filters."""
    k = np.arange(n)
    gyr = np.stack([(k % 41) - 20, (k % 29) - 14, (k % 17) - 8], 1)
    acc = np.stack([100 + (k % 13), 200 - (k % 11), np.full(n, 4000)], 1)
    mag = np.stack([300 + (k % 7), np.full(n, 100), np.full(n, -400)], 1)
    out = (gyr, acc, mag) if ahrs else (gyr, acc)
    return tuple(np.ascontiguousarray(a, dtype=np.int16) for a in out)


# ---- the filters under test ---------------------------------------------------------------
@dataclass
class Spec:
    id: str
    make: Callable                      # a fresh filter
    n0: int                             # samples of the first attempt (a run of ~50-100 ms)
    inputs: Callable                    # n -> (run args, run kwargs)
    probes: Dict[str, Callable] = field(default_factory=dict)   # each fine on an idle filter


def _common(spec, state_value, skipped=True):
    """The probes every filter has: the state, reset, copies, another run."""
    args, kwargs = spec.inputs(8)
    probes = {
        "state read": lambda f: f.state,
        "state write": lambda f: setattr(f, "state", state_value),
        "reset": lambda f: f.reset(),
        "copy.copy": lambda f: copy.copy(f),
        "copy.deepcopy": lambda f: copy.deepcopy(f),
        "pickle": lambda f: pickle.dumps(f),
        "another run": lambda f: f.run(*args, **kwargs),
        "another run in a thread": _in_thread(lambda f: f.run(*args, **kwargs)),
    }
    if skipped:
        probes["skipped"] = lambda f: f.skipped
    spec.probes = {**probes, **spec.probes}
    return spec


def _in_thread(call):
    """call(f) in a new thread; what it raised is raised here."""
    def probe(f):
        box = {}

        def work():
            try:
                call(f)
            except BaseException as e:      # noqa: B036 (handed back to the caller)
                box["e"] = e
        t = threading.Thread(target=work)
        t.start()
        t.join()
        if "e" in box:
            raise box["e"]
    return probe


def _1d():
    def make():
        return imufuse_c.Mahony1DBias(dt=0.01, kp=2.0, ki=0.3)

    def inputs(n):
        k = np.arange(n)
        return (0.1 * np.sin(k * 1e-3), 0.5 * np.cos(k * 4e-4)), {}
    small = inputs(8)[0]
    spec = Spec("Mahony1DBias", make, 2_000_000, inputs, {
        "update": lambda f: f.update(0.1, 0.2),
        "update dt=": lambda f: f.update(0.1, 0.2, dt=0.02),
        "run dt=": lambda f: f.run(*small, dt=np.full(8, 0.02)),
    })
    return _common(spec, make().state)


def _ahrs(name, dtype, n0, **params):
    def make():
        return getattr(imufuse_c, name)(dt=0.01, dtype=dtype, **params)

    def inputs(n):
        return _motion(n, dtype), {}
    g, a, m = _motion(8, dtype)
    probes = {
        "update": lambda f: f.update(g[1], a[1], m[1]),
        "update tuples": lambda f: f.update(tuple(g[1]), tuple(a[1]), tuple(m[1])),
        "update dt=": lambda f: f.update(g[1], a[1], m[1], dt=0.02),
        "run outputs=q": lambda f: f.run(g, a, m, outputs="q"),
        "run dt=": lambda f: f.run(g, a, m, dt=np.full(8, 0.02)),
        "run_filters": lambda f: imufuse_c.run_filters([f], g, a, m),
        "run_filters lanes=0": lambda f: imufuse_c.run_filters([f], g, a, m, lanes=0),
        "run_filters outputs=q": lambda f: imufuse_c.run_filters([f], g, a, m, outputs="q"),
    }
    if name == "RobustAHRS":
        probes["set_mag_offset"] = lambda f: f.set_mag_offset((0.01, 0.0, 0.0))
        probes["get_mag_offset"] = lambda f: f.get_mag_offset()
    label = "-".join([name, dtype, *(f"{k}={v}" for k, v in params.items())])
    return _common(Spec(label, make, n0, inputs, probes), make().state)


def _fusion_ahrs():
    def make():
        return imufuse_c.FusionAHRS()

    def inputs(n):
        g, a, m = _motion(n, gyr_scale=57.3)
        return (g, a, m), {"dt": 0.01}
    (g, a, m), _ = inputs(8)
    states = make().run(g, a, m, dt=0.01)
    spec = Spec("FusionAHRS", make, 500_000, inputs, {
        "update": lambda f: f.update(g[1], a[1], m[1], 0.01),
        "update_no_magnetometer": lambda f: f.update_no_magnetometer(g[1], a[1], 0.01),
        "update_external_heading": lambda f: f.update_external_heading(g[1], a[1], 10.0, 0.01),
        "set_heading": lambda f: f.set_heading(10.0),
        "set_settings": lambda f: f.set_settings(gain=0.4),
        "quaternion read": lambda f: f.quaternion,
        "quaternion write": lambda f: setattr(f, "quaternion", (1.0, 0.0, 0.0, 0.0)),
        "outputs": lambda f: f.outputs(),
        "outputs_batch": lambda f: f.outputs_batch(states),
        "run heading=": lambda f: f.run(g, a, heading=np.zeros(8), dt=0.01),
        "run no mag": lambda f: f.run(g, a, dt=0.01),
    })
    return _common(spec, make().state)


def _fusion_offset():
    def make():
        return imufuse_c.FusionOffset(100)

    def inputs(n):
        return (_motion(n, gyr_scale=57.3)[0],), {}
    g = inputs(8)[0][0]
    spec = Spec("FusionOffset", make, 1_000_000, inputs, {"update": lambda f: f.update(g[1])})
    return _common(spec, make().state)


def _vario():
    def make():
        return imufuse_c.VarioKF()

    def inputs(n):
        k = np.arange(n)
        return (10.0 * np.sin(k * 1e-3), 100.0 + 5.0 * np.cos(k * 1e-4), 0.02), {}
    spec = Spec("VarioKF", make, 1_000_000, inputs, {
        "update": lambda f: f.update(10.0, 100.0, 0.02),
    })
    return _common(spec, make().state)


def _fixed(name, n0, ahrs=False, **params):
    def make():
        return getattr(imufuse_c, name)(dt=1 / 512, gyr_scale=1.0642e-3, **params)

    def inputs(n):
        return _counts(n, ahrs), {}
    one = [v[1].tolist() for v in _counts(8, ahrs)]
    probes = {
        "update": lambda f: f.update(*one),
        "state_float": lambda f: f.state_float,
    }
    if ahrs:
        probes["set_mag_offset"] = lambda f: f.set_mag_offset((10, 0, 0))
    return _common(Spec(name, make, n0, inputs, probes), make().state, skipped=False)


SPECS = [
    _1d(),
    _ahrs("MadgwickAHRS", "float64", 500_000, beta=0.1),
    _ahrs("MadgwickAHRS", "float32", 500_000, beta=0.1),
    _ahrs("MadgwickAHRS", "float64", 500_000, beta=0.1, init="first", init_window=50),
    _ahrs("RobustAHRS", "float64", 50_000),
    _fusion_ahrs(),
    _fusion_offset(),
    _vario(),
    _fixed("MadgwickIMUQ", 500_000, beta=0.1),
    _fixed("RobustAHRSQ", 300_000, ahrs=True),
]


# ---- the harness --------------------------------------------------------------------------
class _Ended(Exception):
    """The run ended before a call could be tried while it ran: try a longer input."""


def _refused(f, what, call):
    """call(f) while another thread's run() holds f: a RuntimeError naming the class."""
    name = type(f).__name__
    try:
        call(f)
    except RuntimeError as e:
        msg = str(e)
        assert msg.startswith(f"{name}: in use by another thread"), (what, msg)
        assert "\n" not in msg, (what, msg)
        return
    if _busy(f):
        pytest.fail(f"{name}: {what} ran while another thread's run() held the filter")
    raise _Ended


def _busy(f):
    """Whether f is held by a run() (a state read, which changes nothing, is refused)."""
    try:
        _ = f.state
    except RuntimeError:
        return True
    return False


def _all_work(spec, f):
    """Every probe of spec on the idle filter f: none refused, none failing."""
    for what, call in spec.probes.items():
        try:
            call(f)
        except Exception as e:
            pytest.fail(f"{spec.id}: {what} fails on an idle filter: {e!r}")


def _same(a, b):
    if isinstance(a, tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    a, b = np.ascontiguousarray(a), np.ascontiguousarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and \
        np.array_equal(a.view(np.uint8), b.view(np.uint8))


def while_running(spec, during):
    """Start spec's filter's run() in a thread; once the run holds the filter, call
    during(f) from this thread; check that the run was not disturbed. Returns the filter
    (idle again) and the run's arguments."""
    for attempt in range(ATTEMPTS):
        args, kwargs = spec.inputs(spec.n0 << attempt)
        f = spec.make()
        started, box = threading.Event(), {}

        def work():
            started.set()
            try:
                box["out"] = f.run(*args, **kwargs)
            except BaseException as e:      # noqa: B036 (reported below)
                box["err"] = e
        t = threading.Thread(target=work)
        t.start()
        try:
            started.wait()
            while t.is_alive() and not _busy(f):
                pass
            if not t.is_alive():
                continue                    # ended before it was seen: a longer input
            during(f)
        except _Ended:
            continue
        finally:
            t.join()
        assert "err" not in box, box.get("err")
        fresh = spec.make()
        want = fresh.run(*args, **kwargs)
        assert _same(box["out"], want), f"{spec.id}: the run was disturbed"
        assert _same(f.state, fresh.state), f"{spec.id}: the final state was disturbed"
        if hasattr(fresh, "skipped"):
            assert f.skipped == fresh.skipped
        return f, args, kwargs
    pytest.fail(f"{spec.id}: never saw the filter held by its run() (a RuntimeError for a "
                f"state read) in {ATTEMPTS} runs of up to {spec.n0 << (ATTEMPTS - 1)} samples")


# ---- the tests ----------------------------------------------------------------------------
@pytest.mark.parametrize("spec", SPECS, ids=[s.id for s in SPECS])
def test_every_entry_point_refuses_while_another_thread_runs(spec):
    """While another thread's run() holds the filter, every call that touches its C state
    raises RuntimeError naming the class; the run ends exactly as a fresh filter's run over
    the same input, and afterwards every call works again."""
    def during(f):
        for what, call in spec.probes.items():
            _refused(f, what, call)
    f, _, _ = while_running(spec, during)
    assert not _busy(f)
    _all_work(spec, f)                       # idle again: nothing is refused


@pytest.mark.parametrize("spec", [s for s in SPECS if s.id in ("MadgwickAHRS-float64-beta=0.1",
                                                               "MadgwickAHRS-float32-beta=0.1")],
                         ids=lambda s: s.id)
def test_run_filters_releases_the_filters_it_claimed(spec):
    """run_filters claims every filter before it starts: one of them held by another thread's
    run() refuses the whole call, and the filters claimed before it are released."""
    g, a, m = _motion(8, spec.make().dtype)
    spares = []

    def during(f):
        spares[:] = [spec.make() for _ in range(3)]
        for order in ([spares[0], f], [spares[0], spares[1], f, spares[2]]):
            _refused(f, "run_filters", lambda f: imufuse_c.run_filters(order, g, a, m))
            for s in spares:
                assert not _busy(s)
    while_running(spec, during)
    want = spec.make().run(g, a, m)
    for s in spares:
        assert _same(s.run(g, a, m), want)   # never touched, free again


class _Hostile:
    """An input whose conversion (np.asarray, inside the guarded region of run() and
    run_filters) records whether the filter is held, then fails."""

    def __init__(self, f):
        self.f, self.held = f, None

    def __array__(self, dtype=None, copy=None):
        self.held = _busy(self.f)
        raise ValueError("not an array")


@pytest.mark.parametrize("spec", SPECS, ids=[s.id for s in SPECS])
def test_an_exception_in_run_leaves_the_filter_free(spec):
    """run() claims the filter before it converts its inputs: bad input raises its own error
    from inside the guarded region, and the filter is free (and unchanged) afterwards."""
    args, kwargs = spec.inputs(16)
    f = spec.make()
    bad = _Hostile(f)
    with pytest.raises(ValueError, match="not an array"):
        f.run(bad, *args[1:], **kwargs)
    assert bad.held is True                  # raised while the filter was held
    assert not _busy(f)
    fresh = spec.make()
    assert _same(f.run(*args, **kwargs), fresh.run(*args, **kwargs))
    _all_work(spec, f)


@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_an_exception_in_run_filters_releases_every_filter(dtype):
    filters = [imufuse_c.MadgwickAHRS(dt=0.01, beta=b, dtype=dtype) for b in (0.05, 0.1, 0.2)]
    g, a, m = _motion(16, dtype)
    bad = _Hostile(filters[1])
    with pytest.raises(ValueError, match="not an array"):
        imufuse_c.run_filters(filters, bad, a, m)
    assert bad.held is True
    with pytest.raises(ValueError, match="lanes"):
        imufuse_c.run_filters(filters, g, a, m, lanes=3)
    for f in filters:
        assert not _busy(f)
    assert _same(imufuse_c.run_filters(filters, g, a, m)[0],
                 imufuse_c.MadgwickAHRS(dt=0.01, beta=0.05, dtype=dtype).run(g, a, m))


def test_one_filter_per_thread_runs_side_by_side():
    """The remedy the error names: copy.copy(f) per thread; both runs at once, each bit for
    bit the run of its own filter."""
    g, a, m = _motion(300_000)
    f = imufuse_c.MadgwickAHRS(dt=0.01, beta=0.1)
    f.update(g[0], a[0], m[0])
    copies = [copy.copy(f) for _ in range(2)]
    out = [None, None]

    def work(i):
        out[i] = copies[i].run(g, a, m)
    threads = [threading.Thread(target=work, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    want = f.run(g, a, m)
    assert _same(out[0], want) and _same(out[1], want)
