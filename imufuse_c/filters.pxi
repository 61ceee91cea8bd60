# The filter families: one include per csrc/<family>.h.
include "filters_1d.pxi"
