"""Filter family kk: pure-Python twin of csrc/kk.c (not written yet)."""

FILTERS = ()
