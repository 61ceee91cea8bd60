"""The wrapper's fast paths change nothing but the time they take.

- update() reads a contiguous float64/float32 row of three in place
  (imufuse_c/_base.pxi, _row3); every other 3-vector goes through the shared
  validation. Whatever the layout, dtype or container of the rows, the C
  filter accepts and rejects what the reference does, with the same message,
  and ends in the same state bit for bit.
- A `state` read returns a new copy every time; the filter refills an array
  it returned before only when nothing else can see it any more
  (imufuse_c/_stateout.pxi). Every array a caller still holds, directly or
  through a view, a buffer or a weak reference, keeps the values it was read
  with, and every read is a writeable, C-contiguous (n,) array of the
  filter's dtype, whatever was done to the arrays returned before.
"""
import gc
import operator
import warnings
import weakref

import numpy as np
import pytest

import imufuse.reference as reference
import imufuse_c
from bits import assert_same_bits
from imufuse.registry import (CASES_VARIO, DTYPES, FIXED_CASES, FLOAT_CASES, FUSION_CASES, each_dtype, representatives)
from sequences import generate

N = 12
read_state = operator.attrgetter("state")      # a read whose result nobody keeps
# the row reading is _base.pxi's (_row3): one filter of each 3-D base class runs it
# (test_no_class_overrides_the_wrapper_paths keeps that true)
CASES_3D = representatives([c for c in FLOAT_CASES if c.kind in ("imu", "ahrs")])


class _Sub(np.ndarray):
    """A plain ndarray subclass (rows of it take the fast path too)."""


def _rows(kind):
    """N samples of a filter kind as float64 (N, 3) arrays (or 1-D for 1d)."""
    return [np.ascontiguousarray(x, dtype=np.float64) for x in generate(kind, "random", n=N)]


# every way a caller may hand update() one row; name -> (array -> per-sample rows)
ROW_FORMS = {
    "float64 rows": lambda x: list(x),
    "float32 rows": lambda x: list(x.astype(np.float32)),
    "float16 rows": lambda x: list(x.astype(np.float16)),
    "int64 rows": lambda x: list(np.round(x).astype(np.int64)),
    "bool rows": lambda x: list(x > 0),
    "byte-swapped rows": lambda x: list(x.astype(">f8")),
    "byte-swapped float32 rows": lambda x: list(x.astype(">f4")),
    "column-major rows (strided)": lambda x: list(np.asfortranarray(x)),
    "every other element": lambda x: [np.repeat(r, 2)[::2] for r in x],
    "read-only rows": lambda x: [np.frombuffer(r.tobytes(), dtype=np.float64) for r in x],
    "unaligned rows": lambda x: [np.frombuffer(b"\0" + r.tobytes(), dtype=np.float64,
                                               offset=1) for r in x],
    "subclass rows": lambda x: list(x.view(_Sub)),
    "masked rows": lambda x: list(np.ma.masked_array(x)),
    "lists": lambda x: x.tolist(),
    "tuples": lambda x: [tuple(r) for r in x.tolist()],
    "float32 scalars in lists": lambda x: [list(r) for r in x.astype(np.float32)],
}

BAD_ROWS = {
    "(1, 3) array": lambda r: r.reshape(1, 3),
    "length 2": lambda r: r[:2],
    "length 4": lambda r: np.append(r, 0.0),
    "0-d array": lambda r: np.float64(r[0]),
    "complex": lambda r: r.astype(complex),
    "strings": lambda r: r.astype(str),
    "objects, one a string": lambda r: np.array([r[0], "x", r[2]], dtype=object),
    "nested": lambda r: np.array([r, r]),
}


def _outcome(f, args):
    try:
        f.update(*args)
        return "ok"
    except (TypeError, ValueError) as e:
        return f"{type(e).__name__}: {e}"


@pytest.mark.parametrize("case", [pytest.param(c, id=c.id) for c in CASES_3D])
@each_dtype
def test_update_rows_of_any_form_agree(case, dtype):
    """The same samples in every form give both backends the same outcome and
    the same state bits after every sample; the C filter given float64 rows
    (the fast path) agrees with itself given lists (the generic path)."""
    data = _rows(case.kind)
    for form, make_rows in ROW_FORMS.items():
        rows = [make_rows(x) for x in data]
        c, r, generic = (case.make("c", dtype), case.make("ref", dtype), case.make("c", dtype))
        for k in range(N):
            args = [x[k] for x in rows]
            out = [_outcome(c, args), _outcome(r, args)]
            assert out[0] == out[1], (form, k, out)
            # the same values as Python lists: the generic path
            assert _outcome(generic, [np.asarray(a).tolist() for a in args]) == out[0], form
            assert_same_bits(c.state, r.state, c.state_names)
            assert_same_bits(c.state, generic.state, c.state_names)
            assert c.skipped == r.skipped == generic.skipped, form


@pytest.mark.parametrize("case", [pytest.param(c, id=c.id) for c in CASES_3D])
@each_dtype
def test_bad_rows_rejected_alike(case, dtype):
    """A bad row in any slot: the same error from both backends, state untouched."""
    data = _rows(case.kind)
    good = [x[0] for x in data]
    for bad, make_bad in BAD_ROWS.items():
        for slot in range(len(good)):
            args = list(good)
            args[slot] = make_bad(good[slot])
            fs = [case.make(b, dtype) for b in ("c", "ref")]
            out = [_outcome(f, args) for f in fs]
            assert out[0] == out[1], (bad, slot, out)
            assert out[0].startswith("ValueError: update(): "), (bad, out[0])
            assert_same_bits(fs[0].state, fs[1].state, fs[0].state_names)
            assert fs[0].skipped == fs[1].skipped == 0, bad


# ---- state reads ---------------------------------------------------------------

def _filters():
    """(constructor, kind) of one compiled filter of each base class (the state snapshots
    are _stateout.pxi's, reached through the base class), in every precision."""
    for c in representatives(FLOAT_CASES):
        for d in DTYPES:
            yield pytest.param(lambda c=c, d=d: c.make("c", d), c.kind, id=f"{c.id}-{d}")
    for c in CASES_VARIO[:1]:
        for d in DTYPES:
            yield pytest.param(lambda c=c, d=d: c.make("c", d), "vario", id=f"{c.id}-{d}")
    for c in representatives(FUSION_CASES):
        for d in DTYPES:
            yield pytest.param(lambda c=c, d=d: getattr(imufuse_c, c.name)(**c.params, dtype=d),
                               c.name, id=f"{c.id}-{d}")
    for c in representatives(FIXED_CASES, fixed=True):
        for p in c.profiles:
            yield pytest.param(lambda c=c, p=p: c.make_fixed("c", p), "fixed-" + c.kind,
                               id=f"{c.id}-q{p}")


FILTERS = list(_filters())


def _feed(kind):
    """A function f -> None that moves f's state on by one sample."""
    rng = np.random.default_rng(7)
    if kind in ("FusionAHRS", "FusionAHRS13"):       # Fusion 1.2.3 and 1.3: dt with the update
        return lambda f: f.update(rng.normal(0, 20, 3), rng.normal(0, 0.1, 3) + [0, 0, 1],
                                  rng.normal(0, 0.1, 3) + [0.4, 0, -0.9], 0.01)
    if kind in ("FusionOffset", "FusionBias"):
        return lambda f: f.update(rng.normal(0, 0.1, 3))
    if kind == "vario":
        return lambda f: f.update(float(rng.normal()), float(rng.normal(100, 1)), 0.01)
    if kind == "fixed-1d":
        return lambda f: f.update(*(int(v) for v in rng.integers(-300, 300, 2)))
    if kind == "fixed-ahrs":
        return lambda f: f.update(rng.integers(-300, 300, 3),
                                  rng.integers(-300, 300, 3) + [0, 0, 1000],
                                  rng.integers(-30, 30, 3) + [300, 0, -500])
    if kind.startswith("fixed-"):
        return lambda f: f.update(rng.integers(-300, 300, 3),
                                  rng.integers(-300, 300, 3) + [0, 0, 1000])
    data = _rows(kind)
    count = iter(range(10 ** 9))

    def feed(f):
        k = next(count) % N
        f.update(*(x[k] for x in data))
    return feed


def _expect_fresh(f, a):
    n = len(f.state_names)
    assert type(a) is np.ndarray
    assert a.shape == (n,) and a.strides == (a.itemsize,)
    assert a.dtype == np.dtype(f.dtype)
    assert a.flags.writeable and a.flags.owndata and a.flags.c_contiguous
    assert a.base is None


def _holders():
    """Ways of keeping a state array alive or in sight without the name it was
    read into: name -> (array -> holder, holder -> values it shows)."""
    return {
        "view": (lambda a: a[:], lambda h: h),
        "reshaped view": (lambda a: a.reshape(1, -1), lambda h: h[0]),
        "memoryview": (lambda a: memoryview(a), lambda h: np.asarray(h)),
        "frombuffer": (lambda a: np.frombuffer(a, dtype=a.dtype), lambda h: h),
        "list": (lambda a: [a], lambda h: h[0]),
        "weakref": (lambda a: (weakref.ref(a), a.copy()),
                    lambda h: h[0]() if h[0]() is not None else h[1]),
    }


@pytest.mark.parametrize("make,kind", FILTERS)
def test_state_reads_are_snapshots(make, kind):
    """Reads kept, reads dropped, reads overwritten in a loop: every array still
    held shows the state it was read with, after any number of later updates
    and reads."""
    f, feed = make(), _feed(kind)
    kept, want = [], []
    for k in range(8):
        feed(f)
        q = f.state                         # overwritten each time (q = f.state)
        read_state(f)                       # dropped at once
        _expect_fresh(f, q)
        if k % 3 == 0:
            kept.append(q)
            want.append(q.tobytes())
        w = f.state
        w[:] = 0                            # writing into a read never reaches the filter
        assert f.state.tobytes() == q.tobytes()
        del w
    for _ in range(8):
        feed(f)
        read_state(f)
    assert [a.tobytes() for a in kept] == want


@pytest.mark.parametrize("make,kind", FILTERS)
def test_state_held_elsewhere_keeps_its_values(make, kind):
    for holder, (keep, show) in _holders().items():
        f, feed = make(), _feed(kind)
        feed(f)
        a = f.state
        snapshot = a.tobytes()
        h = keep(a)
        del a
        gc.collect()
        for _ in range(5):
            feed(f)
            b = f.state
            _expect_fresh(f, b)
            del b
        assert np.asarray(show(h)).tobytes() == snapshot, holder


CHANGES = ["read-only", "reshaped", "dtype", "dtype of the same size", "strides", "resized"]


@pytest.mark.parametrize("make,kind", FILTERS)
def test_state_read_after_a_returned_array_was_changed(make, kind):
    for change in CHANGES:
        _changed_then_read(make, kind, change)


def _changed_then_read(make, kind, change):
    """A caller may change the shape, dtype or flags of an array it was given and
    then drop it: the next reads are still plain (n,) arrays of the state."""
    f, feed = make(), _feed(kind)
    for _ in range(3):                      # both of the filter's arrays in turn
        a = f.state
        n = a.shape[0]
        if change == "read-only":
            a.flags.writeable = False
        elif change == "reshaped":
            a.shape = (1, n)
        elif change == "dtype":
            a.dtype = np.uint8
        elif change == "dtype of the same size":
            a.dtype = np.dtype(f"u{a.itemsize}")
        elif change == "strides":
            with warnings.catch_warnings():     # deprecated in numpy 2.4, still possible
                warnings.simplefilter("ignore", DeprecationWarning)
                a.strides = (0,)
        elif change == "resized":
            a.resize(2 * n, refcheck=False)
        del a
        feed(f)
        b = f.state
        _expect_fresh(f, b)
        c = f.state
        _expect_fresh(f, c)
        assert b.tobytes() == c.tobytes()
        del b, c


def test_state_reads_are_the_trajectory():
    """update() + state read per sample equals run() bit for bit (MadgwickIMU,
    both precisions; the generic per-filter check is tests/test_bitexact.py)."""
    g, a = _rows("imu")
    for dtype in DTYPES:
        f = imufuse_c.MadgwickIMU(dt=0.01, dtype=dtype)
        want = imufuse_c.MadgwickIMU(dt=0.01, dtype=dtype).run(g, a)
        got = []
        for k in range(N):
            f.update(g[k], a[k])
            q = f.state
            got.append(q)
        assert_same_bits(np.array(got), want, f.state_names)
        assert reference.MadgwickIMU(dt=0.01, dtype=dtype).run(g, a).tobytes() == want.tobytes()


def test_no_class_overrides_the_wrapper_paths():
    """The representatives above stand for every filter only while every compiled class takes
    update(), run(), state and reset from its base class, or is a representative itself: a
    class that defines its own must be added to the representatives (imufuse.registry)."""
    reps = {c.name for c in CASES_3D}
    reps |= {p.id.rsplit("-", 1)[0].split("-")[0] for p in FILTERS}
    families = [(c, d, False) for c in FLOAT_CASES for d in DTYPES]
    families += [(c, "float64", False) for c in FUSION_CASES + CASES_VARIO]
    families += [(c, p, True) for c in FIXED_CASES for p in c.profiles]
    checked = set()
    for c, d, fixed in families:
        f = c.make_fixed("c", d) if fixed else (
            getattr(imufuse_c, c.name)(**c.params, dtype=d) if c in FUSION_CASES
            else c.make("c", d))
        cls = type(f)
        own = [a for a in ("update", "run", "state", "reset") if a in vars(cls)]
        assert not own or c.name in reps, f"{cls.__module__}.{cls.__name__} defines {own}"
        checked.add(cls)
    assert len(checked) >= 2 * 15, len(checked)
