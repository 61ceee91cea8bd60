# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False
# The float32 build of csrc (imf_config.h): every filter class.
cdef extern from "imf_config.h":
    ctypedef float imf_real

DTYPE = "float32"

import imufuse.reference as _reference

include "_base.pxi"
include "filters.pxi"

include "_selfcheck.pxi"
