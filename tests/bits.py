"""Bit-pattern comparison for the tests: imufuse.shared.bits (the one definition of
"equal", docs/internals.md numerical contract 4) plus an assertion."""
from imufuse.shared.bits import UINT, compare_states, first_difference, ulps

__all__ = ["UINT", "ulps", "compare_states", "first_difference", "assert_same_bits"]


def assert_same_bits(got, want, names=None):
    msg = first_difference(got, want, names)
    assert msg is None, msg
