# The filter families: one include per csrc/<family>.h.
include "filters_1d.pxi"
include "mahony.pxi"
include "madgwick.pxi"
include "multiwii.pxi"
include "kk.pxi"
include "mahony2d.pxi"
include "dcm.pxi"
include "fusion.pxi"
