# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False
# The float64 build of csrc (imf_config.h with IMF_DOUBLE): every filter class.
cdef extern from "imf_config.h":
    ctypedef double imf_real

DTYPE = "float64"

import imufuse.reference as _reference

include "_base.pxi"
include "filters.pxi"

include "_selfcheck.pxi"
