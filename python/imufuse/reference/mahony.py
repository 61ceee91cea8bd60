"""Filter family mahony: pure-Python twin of csrc/mahony.c (not written yet)."""

FILTERS = ()
