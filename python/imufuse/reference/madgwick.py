"""Filter family madgwick: pure-Python twin of csrc/madgwick.c (not written yet)."""

FILTERS = ()
