"""Bad input: parameters, shapes, dtypes and non-finite samples are handled
the same way by both backends (one validation path, imufuse.shared.checks)."""
import numpy as np
import pytest

import imufuse_c

from imufuse.registry import (FLOAT_CASES, case_params, each, each_backend, each_dtype)
from sequences import generate

BACKENDS = ("c", "ref")


def cls(case, backend):
    import imufuse.reference as reference
    import imufuse_c
    return getattr(imufuse_c if backend == "c" else reference, case.name)


@pytest.mark.parametrize("case", [pytest.param(c, id=c.id) for c in FLOAT_CASES])
@each("dt", [0.0, -0.01, float("nan"), float("inf"), "x"])
@each_backend
def test_bad_dt(case, backend, dt):
    with pytest.raises(ValueError, match=r"^dt: "):
        cls(case, backend)(**{**case.params, "dt": dt})


@pytest.mark.parametrize("case", [pytest.param(c, id=c.id) for c in FLOAT_CASES])
@each_backend
def test_bad_dtype(case, backend):
    with pytest.raises(ValueError, match=r"^dtype: "):
        cls(case, backend)(**case.params, dtype="float16")


@pytest.mark.parametrize("case", [pytest.param(c, id=c.id) for c in FLOAT_CASES])
@each_backend
def test_every_gain_rejects_nonfinite(case, backend):
    for name, value in case.params.items():
        if name == "dt" or isinstance(value, (bool, str)) or not isinstance(value, (int, float)):
            continue
        for bad in (float("nan"), float("inf")):
            with pytest.raises(ValueError, match=rf"^{name}\b"):
                cls(case, backend)(**{**case.params, name: bad})


# the stable ranges of the single-axis gains (both backends)
OUT_OF_RANGE = [
    ("Complementary1D", dict(dt=0.01, alpha=1.5), "alpha"),
    ("Complementary1D", dict(dt=0.01, alpha=-0.1), "alpha"),
    ("Complementary1D", dict(dt=0.01, T=-1.0), "T"),
    ("Complementary1D", dict(dt=0.01), "alpha, T"),
    ("Complementary1D", dict(dt=0.01, alpha=0.9, T=1.0), "alpha, T"),
    ("Kalman1D", dict(dt=0.01, k0=1.01), "k0"),
    ("Kalman1D", dict(dt=0.01, k0=-0.01), "k0"),
    ("Mahony1D", dict(dt=0.01, kp=-1.0), "kp"),
    ("Mahony1D", dict(dt=0.01, kp=200.0), r"kp\*dt"),
    ("Kalman1DBias", dict(dt=0.01, k0=0.0, k1=-0.5), "k0"),
    ("Kalman1DBias", dict(dt=0.01, k0=0.02, k1=0.5), "k1"),
    ("Kalman1DBias", dict(dt=0.01, k0=0.02, k1=-500.0), "k1"),
    ("Kalman1DBias", dict(dt=0.01, k0=0.02, k1=-0.5, bias_sign=2), "bias_sign"),
    # a complex number equal to -1 is no sign (it passed the check and int() dropped its
    # imaginary part; Python's complex raised a TypeError from the stability test)
    ("Kalman1DBias", dict(dt=0.01, k0=0.02, k1=-0.5, bias_sign=np.complex128(-1)), "bias_sign"),
    ("Kalman1DBias", dict(dt=0.01, k0=0.02, k1=0.5, bias_sign=1 + 0j), "bias_sign"),
    ("Mahony1DBias", dict(dt=0.01, kp=2.0, ki=-0.1), "ki"),
    ("Mahony1DBias", dict(dt=0.01, kp=300.0, ki=0.1), "kp, ki"),
    ("Mahony1DBias", dict(dt=0.01, kp=2.0, ki=0.1, integrate_first=1), "integrate_first"),
    ("Mahony1DBias", dict(dt=0.01, kp=0.0, ki=0.1), "kp, ki"),
    ("Complementary1DBias", dict(dt=0.01, kp=0.0, ki=0.1), "kp"),
    ("Complementary1DBias", dict(dt=0.01, kp=1.0), "kp, ki"),
    ("Complementary1DBias", dict(dt=0.01, omega0=1.0), "kp, ki, omega0, xi"),
    ("Complementary1DBias", dict(dt=0.01, omega0=-1.0, xi=1.0), "omega0"),
]


@pytest.mark.parametrize("case", [pytest.param(c, id=c.id) for c in FLOAT_CASES])
@each_backend
def test_every_setting_rejects_complex(case, backend):
    """A complex value with a zero imaginary part is no setting, whatever its check
    (a real, a choice such as mag_learn's True/False that 1+0j equals, or a filter's own):
    refused naming the keyword, never converted with its imaginary part dropped."""
    import inspect
    import warnings
    make = cls(case, backend)
    make(**case.params)     # the compiled constructor keeps what it checked: (0.6, 1.4) is
    #                         == (0.6+0j, 1.4+0j) with one hash, and must not be a hit
    defaults = {k: p.default for k, p in inspect.signature(make).parameters.items()}
    values = {**defaults, **case.params}
    tried = 0
    for name, value in values.items():
        if isinstance(value, (str, type(None))) or value is inspect.Parameter.empty:
            continue
        if name == "dtype":
            continue
        for kind in (complex, np.complex128, np.complex64):
            # acc_gate=(lo, hi): each bound complex in turn
            bad = (tuple(kind(v) for v in value) if isinstance(value, tuple)
                   else kind(value))
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                with pytest.raises(ValueError, match=rf"^{name}\b"):
                    make(**{**case.params, name: bad})
            tried += 1
    assert tried >= 3


@pytest.mark.parametrize("name,params,param", OUT_OF_RANGE)
@each_backend
def test_gain_out_of_range(name, params, param, backend):
    import imufuse.reference as reference
    import imufuse_c
    with pytest.raises(ValueError, match=rf"^{param}: "):
        getattr(imufuse_c if backend == "c" else reference, name)(**params)


@pytest.mark.parametrize("case", case_params(FLOAT_CASES))
@each_dtype
@each_backend
def test_run_shapes(case, dtype, backend):
    f = case.make(backend, dtype)
    good = generate(case.kind, "random", n=10)
    for i in range(len(good)):
        for bad in (good[i][:-1], good[i][..., None], good[i].ravel()[:1].reshape(())):
            args = list(good)
            args[i] = bad
            with pytest.raises(ValueError, match=r"^run\(\): expected .*got shapes .*\(") as e:
                f.run(*args)
            assert str(bad.shape) in str(e.value)
    with pytest.raises(TypeError):      # wrong number of arguments, as for any call
        f.run(*good[:-1])


@pytest.mark.parametrize("case", case_params(FLOAT_CASES))
@each_dtype
@each_backend
def test_update_and_state_bad_values(case, dtype, backend):
    f = case.make(backend, dtype)
    args = [x[0] for x in generate(case.kind, "random", n=1)]
    bad = "x" if case.kind == "1d" else [1.0, 2.0]
    for i in range(len(args)):
        a = list(args)
        a[i] = bad
        with pytest.raises(ValueError, match=r"^update\(\): "):
            f.update(*a)
    n = len(f.state_names)
    with pytest.raises(ValueError, match=r"^state: expected shape"):
        f.state = np.zeros(n + 1)
    s = f.state.copy()
    s[0] = np.nan
    with pytest.raises(ValueError, match=r"^state: must be finite"):
        f.state = s


@pytest.mark.parametrize("case", case_params(FLOAT_CASES))
@each_dtype
@each_backend
def test_nonfinite_samples_are_skipped_and_counted(case, dtype, backend):
    """The documented policy: a sample with any NaN/Inf input leaves the state
    unchanged and increments `skipped`; the state never becomes non-finite."""
    f = case.make(backend, dtype)
    inputs = generate(case.kind, "random", n=200)
    bad_rows = [5, 6, 50, 199]
    values = [np.nan, np.inf, -np.inf, np.nan]
    inputs = tuple(np.array(x, dtype=float) for x in inputs)
    for k, v in zip(bad_rows, values):
        inputs[k % len(inputs)][k] = v
    traj = f.run(*inputs)
    assert np.isfinite(traj).all()
    assert f.skipped == len(bad_rows)
    for k in bad_rows:
        assert (traj[k].view(np.uint8) == traj[k - 1].view(np.uint8)).all()
    # non-finite at every sample: state stays at its initial value
    f.reset()
    init = f.state
    all_bad = tuple(np.full_like(x, np.nan) for x in inputs)
    traj = f.run(*all_bad)
    assert f.skipped == 200 and (traj == init).all()


@pytest.mark.parametrize("name,params", [
    ("Mahony1DBias", dict(dt=0.01, kp=0.5, ki=0.0)),          # frozen integrator
    ("Mahony1DBias", dict(dt=0.01, kp=0.5, ki=0.0, integrate_first=True)),
    ("Mahony1DBias", dict(dt=0.001, kp=1999.0, ki=0.0)),
    ("Kalman1DBias", dict(dt=0.01, k0=0.02, k1=0.0)),
    ("Complementary1DBias", dict(dt=0.01, kp=2.0, ki=0.0)),
])
@each_backend
def test_edge_of_range_accepted(name, params, backend):
    import imufuse.reference as reference
    import imufuse_c
    f = getattr(imufuse_c if backend == "c" else reference, name)(**params)
    assert np.isfinite(f.run(np.ones(100), np.ones(100))).all()


@each_backend
def test_overflowing_update_is_rejected(backend):
    """Finite inputs whose update would overflow the state are rejected too."""
    import imufuse.reference as reference
    import imufuse_c
    f = (imufuse_c if backend == "c" else reference).Kalman1D(1.0, k0=0.0, dtype="float32")
    f.update(3e38, 0.0)
    assert f.skipped == 0 and f.state[0] == np.float32(3e38)
    f.update(3e38, 0.0)          # 6e38 overflows float32: rejected
    assert f.skipped == 1 and f.state[0] == np.float32(3e38)


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_arguments_checked_once_are_checked_as_themselves(dtype):
    """The compiled constructor keeps the checked values of arguments it has seen (a filter
    built again with the same arguments skips the Python checks): a value of another type
    that compares equal (3.0 or True for 3 or 1) is checked as itself, a refused argument is
    refused every time, and a filter built from remembered arguments runs as the first did."""
    g = np.tile([0.1, -0.2, 0.3], (50, 1))
    a = np.tile([0.0, 0.0, 9.81], (50, 1))
    for shift in (3, 1):
        first = imufuse_c.MultiWii(dt=0.01, acc_lpf_shift=shift, dtype=dtype)
        again = imufuse_c.MultiWii(dt=0.01, acc_lpf_shift=shift, dtype=dtype)
        assert np.array_equal(first.run(g, a), again.run(g, a))
    for _ in range(2):
        for bad in (3.0, True, -1):
            with pytest.raises(ValueError, match="acc_lpf_shift"):
                imufuse_c.MultiWii(dt=0.01, acc_lpf_shift=bad, dtype=dtype)
