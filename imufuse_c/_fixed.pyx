# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False
# The fixed-point filters of csrc/fixed: int16 counts in, int32 state out.
# One build serves both profiles (the profile is a constructor argument).
import imufuse.reference as _reference

include "fixed_base.pxi"
include "fixed_filters.pxi"
