"""Bit-pattern comparison of state trajectories: the meaning of "equal" in
imufuse (DESIGN.md, numerical contract 4)."""
import numpy as np

UINT = {np.dtype("float32"): np.uint32, np.dtype("float64"): np.uint64}


def ulps(a, b):
    """Distance in units in the last place between same-dtype float arrays
    (the number of representable values between them)."""
    a = np.asarray(a)
    b = np.asarray(b)
    u = UINT[a.dtype]
    bits = a.dtype.itemsize * 8
    sign = u(1) << u(bits - 1)

    def ordered(x):
        v = x.view(u).astype(object)
        # map the sign-magnitude bit patterns onto a monotonic integer line
        return np.where(v >= int(sign), int(sign) - v, v)

    return np.abs(ordered(a) - ordered(b)).astype(float)


def first_difference(got, want, names=None):
    """None if got and want have identical shape, dtype and bit patterns;
    otherwise a message naming the first differing sample and variable."""
    got = np.asarray(got)
    want = np.asarray(want)
    if got.dtype != want.dtype or got.shape != want.shape:
        return f"dtype/shape differ: {got.dtype}{got.shape} vs {want.dtype}{want.shape}"
    u = UINT[got.dtype] if got.dtype in UINT else None
    g = got.view(u) if u else got
    w = want.view(u) if u else want
    diff = g != w
    if not diff.any():
        return None
    idx = np.argwhere(diff)[0]
    k = int(idx[0])
    j = int(idx[1]) if got.ndim > 1 else 0
    name = names[j] if names else j
    extra = ""
    if u:
        extra = (f"; {int(diff.sum())} values differ, max "
                 f"{ulps(got[diff], want[diff]).max():.0f} ulp")
    return (f"first difference at sample {k}, variable {name}: "
            f"{got[tuple(idx)]!r} vs {want[tuple(idx)]!r}{extra}")


def assert_same_bits(got, want, names=None):
    msg = first_difference(got, want, names)
    assert msg is None, msg
