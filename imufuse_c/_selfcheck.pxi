# Import-time self-check of a float build (included last by _f32.pyx and
# _f64.pyx). The module must be the precision it claims: the Cython side's
# imf_real must be DTYPE, and the C objects linked into the module must
# compute, for one filter of every csrc family (one object file each), the
# same bits as the pure-Python reference in DTYPE. A module linked with
# objects of the other precision (a racing parallel build) fails here with
# ImportError instead of giving wrong numbers.
import numpy as _np_check

# (class, constructor keywords, update() arguments applied twice)
_SELFCHECK = (
    ("Kalman1D", dict(dt=0.01, k0=0.02), (1.0, 0.5)),                       # filters_1d.c
    ("MahonyIMU", dict(dt=0.005, kp=1.0, ki=0.3), ((0.1, -0.2, 0.3), (0.1, 0.2, 0.9))),
    ("MadgwickIMU", dict(dt=0.01, beta=0.1), ((0.1, -0.2, 0.3), (0.1, 0.2, 0.9))),
    ("MultiWii", dict(dt=0.0025, acc_lpf_shift=1), ((0.1, -0.2, 0.3), (0.1, 0.2, 0.9))),
    ("KK", dict(dt=0.005, kp=0.01), ((0.1, -0.2, 0.3), (0.1, 0.2, 0.9))),
    ("Mahony2D", dict(dt=0.005, kp=2.0, ki=0.5), ((0.1, -0.2, 0.3), (0.1, 0.2, 0.9))),
    ("DCM", dict(dt=0.005, kp=2.0, ki=0.5), ((0.1, -0.2, 0.3), (0.1, 0.2, 0.9))),
    ("VarioKF", dict(z0=0.0, predict="model"), (120.0, 5.0, 0.02)),          # vario.c
)


def _selfcheck():
    where = f"{__name__} ({DTYPE})"
    if sizeof(imf_real) != _np_check.dtype(DTYPE).itemsize:
        raise ImportError(f"{where}: imf_real is {sizeof(imf_real)} bytes, not {DTYPE}; "
                          f"the module was built with the wrong precision macro")
    uint = _np_check.uint32 if DTYPE == "float32" else _np_check.uint64
    for name, params, args in _SELFCHECK:
        c = globals()[name](**params)
        r = getattr(_reference, name)(**params, dtype=DTYPE)
        for _ in range(2):
            c.update(*args)
            r.update(*args)
        got, want = c.state, r.state
        if c.skipped != 0 or r.skipped != 0 or \
                (got.view(uint) != want.view(uint)).any():
            raise ImportError(
                f"{where}: the C of {name} does not compute what the reference computes in "
                f"{DTYPE} (state {got.tolist()} vs {want.tolist()}, skipped {c.skipped}); "
                f"its objects were built for another precision (mixed or racing build). "
                f"Rebuild from a clean tree: rm -rf build && pip install .")


_selfcheck()
