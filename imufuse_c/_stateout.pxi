# The array a `state` read returns, included by _base.pxi (float filters) and
# fixed_base.pxi (fixed-point filters): one pattern for every filter.
#
# Every read returns a new copy of the state: later updates never change an
# array already returned. Creating a numpy array and freeing it costs about
# 40 ns, more than the rest of the read; so each filter keeps the last two
# arrays it returned and writes the next read into one of them when nothing
# else refers to it any more: no other reference (the filter's own is the
# only one: no variable, container, view or buffer holds it), no weak
# reference, and shape, strides, dtype, flags and base as created. Such an
# array can no longer be seen by anyone, so filling it is the same as
# freeing it and creating a new one (numpy's allocator would even hand back
# the same memory): the caller cannot tell the difference, except by id().
# A loop that drops or overwrites each state it reads (`q = f.state`) is
# served from the two arrays; one that keeps them gets a new array each time.
# Free-threaded Python builds (no GIL) always create a new array.
cimport numpy as cnp
from cpython.ref cimport PyObject

cnp.import_array()

cdef extern from *:
    """
    /* 1 if o (an array made by imf_state_new) may be refilled: see _stateout.pxi */
    static int imf_state_reusable(PyObject *o, npy_intp n, PyArray_Descr *descr, int flags)
    {
    #ifdef Py_GIL_DISABLED
        (void)o; (void)n; (void)descr; (void)flags;
        return 0;
    #else
        PyArrayObject *a = (PyArrayObject *)o;
        return o != Py_None && Py_REFCNT(o) == 1
            && ((PyArrayObject_fields *)o)->weakreflist == NULL
            && PyArray_NDIM(a) == 1 && PyArray_DIMS(a)[0] == n
            && PyArray_STRIDES(a)[0] == PyArray_ITEMSIZE(a)
            && PyArray_DESCR(a) == descr && PyArray_FLAGS(a) == flags
            && PyArray_BASE(a) == NULL;
    #endif
    }

    /* a new 1-D array of n elements of descr (contents uninitialised) */
    static PyObject *imf_state_new(npy_intp n, PyArray_Descr *descr)
    {
        Py_INCREF(descr);   /* PyArray_NewFromDescr steals it */
        return PyArray_NewFromDescr(&PyArray_Type, descr, 1, &n, NULL, NULL, 0, NULL);
    }
    """
    bint imf_state_reusable(PyObject *o, cnp.npy_intp n, cnp.dtype descr, int flags) noexcept
    object imf_state_new(cnp.npy_intp n, cnp.dtype descr)


cdef class _StateOut:
    """The arrays of one filter's state reads (see the top of _stateout.pxi)."""
    cdef object _a, _b
    cdef cnp.dtype _descr
    cdef cnp.npy_intp _n
    cdef int _flags
    cdef bint _next

    def __cinit__(self, Py_ssize_t n, int typenum):
        self._descr = cnp.PyArray_DescrFromType(typenum)
        self._n = n
        self._flags = -1          # set by the first array made

    cdef object take(self):
        """An array of n elements, nobody else's: fill it, then return it."""
        if imf_state_reusable(<PyObject *>self._a, self._n, self._descr, self._flags):
            return self._a
        if imf_state_reusable(<PyObject *>self._b, self._n, self._descr, self._flags):
            return self._b
        out = imf_state_new(self._n, self._descr)
        self._flags = cnp.PyArray_FLAGS(<cnp.ndarray>out)
        if self._next:
            self._b = out
        else:
            self._a = out
        self._next = not self._next
        return out
