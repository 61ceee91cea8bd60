# cython: boundscheck=False, wraparound=False
"""CSV text for columns of doubles, formatted in C without the GIL (csvfmt.h).

Every value is written as Python's "%.17g" % x, or "%.9g" % x for the
columns marked float32: the same text as the pure-Python writer, digits
correctly rounded, so the values read back to the same bits.
"""
from libc.stdlib cimport malloc, free
from cpython.bytes cimport PyBytes_FromStringAndSize

import numpy as np

cdef extern from "csvfmt.h" nogil:
    int CSVFMT_MAX_VALUE
    int csvfmt_value(char *out, double x, int P)
    long csvfmt_rows(char *out, const char *const *cols, const long *stride, const int *prec,
                     int ncol, long r0, long r1)

#: bytes of text per block (the fixed buffer); a block holds whole rows
BLOCK_BYTES = 1 << 20


def format_value(double x, int precision=17):
    """One value as "%.{precision}g" text (precision 9 or 17)."""
    cdef char buf[40]
    if precision not in (9, 17):
        raise ValueError(f"precision: must be 9 or 17, got {precision!r}")
    cdef int n = csvfmt_value(buf, x, precision)
    if n < 0:
        raise ValueError(f"cannot format {x!r}")
    return buf[:n].decode("ascii")


def iter_blocks(columns, precisions):
    """Yield the CSV lines of equal-length 1-D columns as bytes, in blocks of
    whole rows of at most BLOCK_BYTES (one fixed buffer, reused).

    columns: sequence of (N,) arrays, read in place when float64 (strided
    views too: no copy), else converted to float64;
    precisions: one per column, 9 or 17."""
    cdef int ncol = len(columns), j
    if len(precisions) != ncol:
        raise ValueError(f"precisions: expected {ncol} values, got {len(precisions)}")
    if ncol == 0:
        return
    arrs = [np.asarray(c, dtype=np.float64) for c in columns]
    cdef long n = arrs[0].shape[0] if arrs[0].ndim == 1 else -1
    for j in range(ncol):
        if arrs[j].ndim != 1 or arrs[j].shape[0] != n:
            raise ValueError(f"columns: expected equal-length 1-D arrays, column {j} has "
                             f"shape {arrs[j].shape}")
        if precisions[j] not in (9, 17):
            raise ValueError(f"precisions: must be 9 or 17, got {precisions[j]!r}")
    cdef long per_row = ncol * (CSVFMT_MAX_VALUE + 1)
    cdef long rows = max(1, BLOCK_BYTES // per_row)
    cdef const char **ptrs = <const char **>malloc(ncol * sizeof(char *))
    cdef long *stride = <long *>malloc(ncol * sizeof(long))
    cdef int *prec = <int *>malloc(ncol * sizeof(int))
    cdef char *buf = <char *>malloc(rows * per_row)
    cdef const double[:] view
    cdef long r0, r1, got
    try:
        if ptrs == NULL or stride == NULL or prec == NULL or buf == NULL:
            raise MemoryError()
        for j in range(ncol):
            view = arrs[j]
            ptrs[j] = <const char *>&view[0] if n > 0 else NULL
            stride[j] = view.strides[0]
            prec[j] = precisions[j]
        r0 = 0
        while r0 < n:
            r1 = min(n, r0 + rows)
            with nogil:
                got = csvfmt_rows(buf, ptrs, stride, prec, ncol, r0, r1)
            if got < 0:
                raise ValueError("a value could not be formatted")
            yield PyBytes_FromStringAndSize(buf, got)
            r0 = r1
    finally:
        free(ptrs)
        free(stride)
        free(prec)
        free(buf)
