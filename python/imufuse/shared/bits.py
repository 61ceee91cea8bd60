"""Bit-pattern comparison of state trajectories: the meaning of "equal" in
imufuse (docs/internals.md, numerical contract 4). One module, used by the demo, the
firmware and MCU harnesses and the tests.

  ulps(a, b)                  distance in units in the last place
  compare_states(got, want)   a Comparison: bit-exact or where and by how much not
  first_difference(got, want) None, or a one-line message naming the first difference

and the conversions between numbers and their bit patterns the C harnesses need:

  as_bits(a), bits_as_values(bits, dtype)   float/integer arrays <-> uint32/uint64 patterns
  words_as_values(words, size, ...)         state words a target printed -> values
  f32_hex(v)                                the float32 bit pattern of v in hex
  c_double_literal(v), c_float_literal(v)   exact C literals (hexadecimal floating point)
"""
from __future__ import annotations

import math
import struct
from dataclasses import dataclass, field
from typing import Dict, Optional, Sequence, Tuple

import numpy as np

#: the unsigned integer type with the bit pattern of each float dtype
UINT = {np.dtype("float32"): np.uint32, np.dtype("float64"): np.uint64}


def ulps(a, b) -> np.ndarray:
    """|a - b| in units in the last place: the number of representable values
    between same-dtype float arrays (+0 and -0 are 0 apart); NaN against a
    number counts as the largest distance, 2**bits."""
    a = np.asarray(a)
    b = np.asarray(b)
    u = UINT[a.dtype]
    bits = a.dtype.itemsize * 8
    sign = 1 << (bits - 1)

    def ordered(x):
        # map the sign-magnitude bit patterns onto a monotonic integer line
        v = x.view(u).astype(object)
        return np.where(v >= sign, sign - v, v)

    d = np.asarray(np.abs(ordered(a) - ordered(b)), dtype=float)
    nan = np.isnan(a) != np.isnan(b)
    d[nan] = float(2 ** bits)
    return d


@dataclass
class Comparison:
    """Result of comparing two state trajectories bit for bit."""
    names: Tuple[str, ...]
    dtype: str
    n_samples: int
    bit_exact: bool
    first_sample: Optional[int] = None
    first_variable: Optional[str] = None
    first_values: Optional[tuple] = None          # (got, want) at the first difference
    n_different: int = 0                          # samples with any difference
    max_abs: Dict[str, float] = field(default_factory=dict)    # name -> max |got - want|
    max_ulps: Dict[str, float] = field(default_factory=dict)   # name -> max ulps (floats)

    def text(self, got_label: str = "firmware", want_label: str = "imufuse") -> str:
        if self.bit_exact:
            return (f"bit-exact: {self.n_samples} samples x {len(self.names)} state variables "
                    f"({self.dtype}) have equal bit patterns")
        assert self.first_values is not None
        g, w = self.first_values
        lines = [f"NOT bit-exact ({self.dtype}): first divergence at sample {self.first_sample}, "
                 f"variable {self.first_variable}: {got_label} {g!r} vs {want_label} {w!r}",
                 f"{self.n_different} of {self.n_samples} samples differ",
                 f"{'variable':12s} {'max |diff|':>12s}"
                 + (f" {'max ulps':>12s}" if self.max_ulps else "")]
        # ulps of floats only (an integer state differs in counts: max |diff|)
        for n in self.names:
            lines.append(f"{n:12s} {self.max_abs[n]:12.4g}"
                         + (f" {self.max_ulps.get(n, 0.0):12.0f}" if self.max_ulps else ""))
        return "\n".join(lines)

    def summary(self) -> Optional[str]:
        """None when bit-exact; else one line: first sample, variable, values, worst ulps."""
        if self.bit_exact:
            return None
        assert self.first_values is not None
        g, w = self.first_values
        worst = max(self.max_ulps.values(), default=0.0)
        extra = f", max {worst:.0f} ulp" if self.max_ulps else ""
        return (f"first difference at sample {self.first_sample}, variable "
                f"{self.first_variable}: {g!r} vs {w!r}; {self.n_different} samples "
                f"differ{extra}")


def integer_label(types: Sequence[Tuple[int, bool]]) -> str:
    """The C integer type of state words, from (bytes, signed) each: "int32"; words of
    different types "int16/int32"."""
    return "/".join(sorted({f"{'' if signed else 'u'}int{8 * size}" for size, signed in types},
                           key=lambda t: (int(t.lstrip("uint")), t)))


def compare_states(got, want, names: Optional[Sequence[str]] = None,
                   label: Optional[str] = None) -> Comparison:
    """Compare (N, n) (or (N,)) trajectories of one dtype by bit pattern
    (floats) or value (integers). ValueError when dtypes or shapes differ. label: the state's
    type as reported (default the arrays' dtype; integers widened to int64 for the comparison
    are reported in the firmware's own type, e.g. "int32")."""
    got = np.asarray(got)
    want = np.asarray(want)
    if got.ndim == 1:
        got, want = got[:, None], want[:, None]
    if got.shape != want.shape or got.dtype != want.dtype:
        raise ValueError(f"cannot compare {got.dtype}{got.shape} with {want.dtype}{want.shape}")
    names = tuple(names) if names else tuple(f"s{j}" for j in range(got.shape[1]))
    u = UINT.get(got.dtype)
    diff = (got.view(u) != want.view(u)) if u else (got != want)
    rep = Comparison(names, label or got.dtype.name, got.shape[0], not diff.any())
    if rep.bit_exact:
        rep.max_abs = {n: 0.0 for n in names}
        rep.max_ulps = {n: 0.0 for n in names} if u else {}
        return rep
    k, j = (int(i) for i in np.argwhere(diff)[0])
    rep.first_sample, rep.first_variable = k, names[j]
    rep.first_values = (got[k, j].item(), want[k, j].item())
    rep.n_different = int(diff.any(axis=1).sum())
    with np.errstate(all="ignore"):
        ad = np.abs(got.astype(np.float64) - want.astype(np.float64))
    ad[diff & np.isnan(ad)] = np.inf
    ad[~diff] = 0.0
    for jj, n in enumerate(names):
        col = diff[:, jj]
        rep.max_abs[n] = float(ad[:, jj].max())
        if u:
            rep.max_ulps[n] = float(ulps(got[col, jj], want[col, jj]).max()) if col.any() else 0.0
    return rep


def first_difference(got, want, names: Optional[Sequence[str]] = None) -> Optional[str]:
    """None if got and want have identical shape, dtype and bit patterns;
    otherwise a message naming the first differing sample and variable."""
    got = np.asarray(got)
    want = np.asarray(want)
    if got.dtype != want.dtype or got.shape != want.shape:
        return f"dtype/shape differ: {got.dtype}{got.shape} vs {want.dtype}{want.shape}"
    return compare_states(got, want, names).summary()


# ---------------------------------------------------------------------------
# numbers <-> bit patterns


def as_bits(a) -> np.ndarray:
    """The bit patterns of an array: float64 -> uint64, float32 -> uint32; signed integers
    as 32-bit two's complement (as the MCU dumpers print them), others as uint32."""
    a = np.asarray(a)
    if a.dtype == np.float64:
        return a.view(np.uint64)
    if a.dtype == np.float32:
        return a.view(np.uint32)
    if a.dtype.kind == "i":
        return a.astype(np.int64).astype(np.uint32)  # two's complement, as the dumpers print
    return a.astype(np.uint32)


def bits_as_values(bits: np.ndarray, state_dtype) -> np.ndarray:
    """as_bits undone: the values of dtype `state_dtype` (float64, float32, else int32)."""
    dt = np.dtype(state_dtype)
    if dt == np.float64:
        return bits.astype(np.uint64).view(np.float64)
    if dt == np.float32:
        return bits.astype(np.uint32).view(np.float32)
    return bits.astype(np.uint32).view(np.int32)


def words_as_values(words: np.ndarray, size: int, integer: bool, signed: bool) -> np.ndarray:
    """State words (uint64 array of the patterns a target printed) of a C type of `size`
    bytes: floats as float32/float64, integers widened to int64."""
    vals = np.asarray(words, dtype=np.uint64)
    if not integer:
        return vals.astype(np.uint32).view(np.float32) if size == 4 else vals.view(np.float64)
    if size > 4:
        return vals.view(np.int64) if signed else vals.astype(np.int64)
    if signed:
        return vals.astype(np.uint32).view(np.int32).astype(np.int64)
    return vals.astype(np.int64)


def f32_hex(v: float) -> str:
    """The float32 bit pattern of v, 8 hex digits (big-endian order)."""
    return struct.pack(">f", v).hex()


def c_double_literal(v: float) -> str:
    """An exact C literal of a double (hexadecimal floating point; signed zeros kept).
    ValueError for a non-finite value."""
    if not math.isfinite(v):
        raise ValueError(f"non-finite value {v!r}")
    if v == 0.0:
        return "-0.0" if math.copysign(1.0, v) < 0 else "0.0"
    return v.hex()


def c_float_literal(v: float) -> str:
    """An exact C float literal of v rounded to float32 (``0x1.8p-1f``). ValueError for a
    value that is not finite in float32."""
    v32 = float(np.float32(v))
    return c_double_literal(v32) + "f"
