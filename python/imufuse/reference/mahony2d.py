"""Filter family mahony2d: pure-Python twin of csrc/mahony2d.c (not written yet)."""

FILTERS = ()
