# One filter, one thread: the guard of a compiled filter's C struct, included by _base.pxi
# (float filters, Fusion, the variometer, run_filters) and fixed_base.pxi (fixed point).
#
# run() updates the struct without the GIL, so a second Python thread using the same
# object meanwhile (update, state, reset, copy, another run, run_filters, a setter) would
# race on it: torn states, silently wrong. Every filter object has a C int flag `_busy`:
# a region that releases the GIL while it touches the struct claims it (_claim, under the
# GIL: the test and the set are one step for every other Python thread) and clears it in a
# `finally`; every other entry point that touches the struct checks it (_idle) after its
# Python-level argument checks, with no Python code between the check and the C access.
# A busy filter raises RuntimeError naming its class; nothing is waited for or locked.
# (A free-threaded Python build has no GIL to make the claim atomic: not covered.)


cdef int _in_use(object f) except -1:
    raise RuntimeError(f"{type(f).__name__}: in use by another thread (its run() releases the "
                       "GIL); give each thread its own filter (copy.copy(f))")


cdef inline int _idle(int busy, object f) except -1:
    """Raise if the filter f is being run by another thread (busy: its flag)."""
    if busy:
        _in_use(f)
    return 0


cdef inline int _claim(int *busy, object f) except -1:
    """Mark the filter f in use (its flag at busy) or raise if it already is; the caller
    clears the flag in a `finally`."""
    if busy[0]:
        _in_use(f)
    busy[0] = 1
    return 0
