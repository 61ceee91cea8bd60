"""Filter family dcm: pure-Python twin of csrc/dcm.c (not written yet)."""

FILTERS = ()
