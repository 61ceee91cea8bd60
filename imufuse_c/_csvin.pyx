# cython: boundscheck=False, wraparound=False
"""The numbers of a CSV log, parsed in C without the GIL (csvparse.h).

`read_numbers` reads a file from a byte offset (past its header) in blocks of
BLOCK_BYTES into one array sized from the file's line count: the memory is the
array and one block, whatever the file's length. It reads what numpy.loadtxt
reads from the same lines, to the bit (csvparse.h says exactly what), and
reports the first row it cannot read with its line and column instead of
raising: imufuse.io.text turns that into the error message.
"""
from libc.string cimport memmove

import numpy as np
cimport numpy as cnp

cnp.import_array()

cdef extern from "csvparse.h" nogil:
    enum:
        CSVP_OK
        CSVP_BAD_NUMBER
        CSVP_FEW_FIELDS
        CSVP_MANY_FIELDS
        CSVP_FULL
    ctypedef struct csvp_state:
        char delim
        int decimal_comma
        int width
        int ncol
        const int *slot
        int nslot
        double *out
        long cap
        long rows
        long line
        int nul
        long err_line
        int err_col
    int csvp_parse(csvp_state *st, const char *text, long len, int final, long *used)
    long csvp_count_lines(const char *text, long len, int *cr_only)
    void csvp_init(csvp_state *st)

#: bytes read per block; a line longer than this is not a CSV row
BLOCK_BYTES = 1 << 20

#: status names of the first row that cannot be read
STATUS = {CSVP_BAD_NUMBER: "number", CSVP_FEW_FIELDS: "few", CSVP_MANY_FIELDS: "many"}


def count_lines(path, long offset, long stop):
    """Line ends in the file's bytes [offset, stop): an upper bound of its rows (lone carriage
    returns counted when the text has no newline)."""
    cdef bytearray buf = bytearray(BLOCK_BYTES)
    cdef char *p = buf
    cdef long n = 0, r = 0, k
    cdef int cr_only = 0
    cdef long left = stop - offset
    with open(path, "rb") as fh:
        fh.seek(offset)
        while left > 0:
            k = fh.readinto(memoryview(buf)[:min(BLOCK_BYTES, left)])
            if k <= 0:
                break
            left -= k
            with nogil:
                n += csvp_count_lines(p, k, &cr_only)
                if cr_only:
                    r += 1
    return n if n else r


def read_numbers(path, long offset, long stop, delim, int width, usecols,
                 bint decimal_comma, long row_bytes=0, long block=BLOCK_BYTES):
    """The used columns of the rows in the file's bytes [offset, stop) as one float64 array
    (rows, len(usecols)), columns in the order of usecols, and what stopped the reading:
    a dict with "lines" (lines read), "nul" (True when a NUL byte ended the text), "cut"
    (the bytes of the partial row before that NUL), "status" (None, or "number", "few",
    "many" for the first row that cannot be read), "line" (its line, counted from the
    first line read, 1-based) and "column" (its field index, or for "many" its number of
    values). delim: one character, or None for runs of blanks. row_bytes: the length of the
    shortest row seen (from the first rows): the array is sized for rows of half that length
    (pages never written cost no memory, and the array is cut to the rows read in place),
    and grown should rows be shorter still; 0 counts the line ends instead (a pass more).
    block: the bytes read at a time (the tests read in tiny blocks, so that rows, numbers and
    line ends straddle them); a line longer than a block stops the reading ("long")."""
    cdef csvp_state st
    cdef int ncol = len(usecols)
    cdef long bound = (stop - offset) // max(1, row_bytes // 2) + 1024 if row_bytes > 0 \
        else count_lines(path, offset, stop) + 1
    cdef cnp.ndarray[cnp.int32_t, ndim=1] slot = np.full(max(usecols) + 1, -1, dtype=np.int32)
    cdef int i
    for i in range(ncol):
        slot[usecols[i]] = i
    out = np.empty((bound, ncol), dtype=np.float64)
    cdef double[:, ::1] outv = out
    st.delim = 0 if delim is None else ord(delim)
    st.decimal_comma = decimal_comma
    st.width = width
    st.ncol = ncol
    st.slot = <const int *> &slot[0]
    st.nslot = len(slot)
    st.out = &outv[0, 0]
    st.cap = bound
    st.rows = 0
    st.line = 0
    st.nul = 0
    st.err_line = 0
    st.err_col = 0
    csvp_init(&st)
    if block < 16:
        raise ValueError(f"block: at least 16 bytes, got {block}")
    cdef bytearray buf = bytearray(2 * block + 1)      # + the 0 after the text
    cdef char *p = buf
    cdef long have = 0, used = 0, pos, k, left = stop - offset
    cdef int rc = CSVP_OK, final = 0
    info = {"lines": 0, "nul": False, "cut": b"", "status": None, "line": 0, "column": 0}
    with open(path, "rb") as fh:
        fh.seek(offset)
        while True:
            k = fh.readinto(memoryview(buf)[have:have + min(block, left)]) if left > 0 else 0
            left -= k
            have += k
            final = left <= 0 or k == 0
            p[have] = 0                    # the sentinel csvp_parse's scans stop at
            pos = 0
            while True:
                with nogil:
                    rc = csvp_parse(&st, p + pos, have - pos, final, &used)
                pos += used
                if rc != CSVP_FULL:
                    break
                # more rows than line ends (mixed line endings): grow, go on from here
                grown = np.empty((2 * st.cap, ncol), dtype=np.float64)
                grown[:st.rows] = out[:st.rows]
                out = grown
                outv = out
                st.out = &outv[0, 0]
                st.cap = 2 * st.cap
            if rc != CSVP_OK:
                info["status"] = STATUS[rc]
                info["line"] = st.err_line
                info["column"] = st.err_col
                break
            if st.nul:
                end = buf.find(b"\0", pos, have)
                info["nul"] = True
                info["cut"] = bytes(buf[pos:end]).strip()
                break
            if final:
                break
            if pos == 0 and have >= block:
                info["status"] = "long"
                info["line"] = st.line + 1
                break
            memmove(p, p + pos, have - pos)
            have -= pos
    info["lines"] = st.line
    rows = st.rows
    if out.base is None and out.flags.owndata:
        out.resize((rows, ncol), refcheck=False)       # realloc: no copy, the rest freed
    else:
        out = out[:rows].copy()
    return out, info
