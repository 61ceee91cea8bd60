"""Filter family multiwii: pure-Python twin of csrc/multiwii.c (not written yet)."""

FILTERS = ()
