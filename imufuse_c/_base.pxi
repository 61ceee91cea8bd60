# Base classes of the compiled filters, included once per precision by
# _f32.pyx / _f64.pyx (which define imf_real, DTYPE).
#
# Longer than 500 lines because: it is everything generic of every float binding (the
# bindings themselves are generated), in one place so that one fix reaches every filter.
#
# A filter class wraps one C struct imf_<filter>_t. The base classes hold
# everything generic: parameter validation (delegated to the reference
# class, so both backends accept the same arguments), the state read (a
# copy of the struct's state member x into a new array, _stateout.pxi), the
# update() inputs (contiguous float rows read in place, _row3), reset, and
# the run() loop, which runs without the GIL and calls the filter's _step for
# every sample.
#
# Time: run(..., dt=array) / update(..., dt=value) call the filter's _set_dt
# (imf_<filter>_set_dt) before each of those samples and restore the
# constructor's dt afterwards; the fixed-step paths are untouched. Start (3-D
# filters): init="first" feeds the first samples to the shared attitude window
# (csrc/imf_attitude.h) and _set_attitude; q0= and state= are set at reset.
from cpython.float cimport PyFloat_AsDouble, PyFloat_Check
from cpython.long cimport PyLong_CheckExact
from libc.math cimport sqrt
from libc.string cimport memcpy
from libc.stdint cimport uint32_t
cimport numpy as cnp

import numpy as np

cnp.import_array()

include "_stateout.pxi"
include "_guard.pxi"

# the numpy type of imf_real
cdef int _NATIVE = cnp.NPY_DOUBLE if sizeof(imf_real) == 8 else cnp.NPY_FLOAT

cdef extern from "imf_math.h" nogil:
    int imf_finite3(imf_real a, imf_real b, imf_real c)

cdef extern from "imf_attitude.h" nogil:
    ctypedef struct imf_attitude_t:
        imf_real q[4]
        imf_real r[9]
    ctypedef struct imf_attitude_window_t:
        uint32_t n
        uint32_t window
    int imf_attitude_from_quat(imf_attitude_t *att, imf_real q0, imf_real q1, imf_real q2,
                               imf_real q3)
    void imf_attitude_window_init(imf_attitude_window_t *w, uint32_t window)
    int imf_attitude_window_add(imf_attitude_window_t *w, imf_attitude_t *att, imf_real ax,
                                imf_real ay, imf_real az, imf_real mx, imf_real my, imf_real mz)

cdef extern from "lanes.h" nogil:
    ctypedef struct imf_scorer_t:
        const unsigned char *use
        const double *r
        int store
    ctypedef struct imf_score_acc_t:
        double sq[3]
        double n_est_nan
        Py_ssize_t j
        double *ew
        double *ez
        unsigned char *ok
    ctypedef int (*imf_lanes_fn)(void *const *f, int p, Py_ssize_t k0, Py_ssize_t k1,
                                 const imf_real *gyr, const imf_real *acc, const imf_real *mag,
                                 const imf_real *dts, const imf_scorer_t *sc,
                                 imf_score_acc_t *accs, imf_real *const *out)
    void imf_estimate_q(int adapter, const double *s, const int *idx, double q[4])
    void imf_score_q(const imf_scorer_t *sc, imf_score_acc_t *acc, Py_ssize_t k,
                     const double q[4])
    imf_lanes_fn imf_lanes_kernel(const char *c_update, int width)
    int imf_lanes_best()
    const char *imf_lanes_isa(int width)

from imufuse.shared import checks as _checks
from imufuse.shared import estimate as _estimate
from imufuse.reference._base import init_arguments as _init_arguments

_R = np.float32 if DTYPE == "float32" else float


cdef inline imf_real _dt_step(object dt) except? -1:
    """dt of one update(..., dt=...): a Python float that is finite and > 0, and still so in
    imf_real, without a Python call (update(dt=) within a few ns of update()); anything
    else through _checks.dt_value, which accepts and refuses exactly the same values."""
    cdef double v
    cdef imf_real r
    if type(dt) is float:
        v = dt
        r = <imf_real>v
        if v > 0.0 and v - v == 0.0 and r > 0 and r - r == 0:
            return r
    return <imf_real><double>_checks.dt_value(dt, DTYPE)


cdef inline void _copy_state(imf_real *dst, const char *x, Py_ssize_t n) noexcept nogil:
    # a short element loop: cheaper than a memcpy call for a few words per sample; a long
    # state (RobustAHRS: 125 words) by memcpy's vector moves
    cdef const imf_real *src = <const imf_real *>x
    cdef Py_ssize_t j
    if n > 32:
        memcpy(dst, x, n * sizeof(imf_real))
        return
    for j in range(n):
        dst[j] = src[j]


cdef inline void _emit(imf_real *dst, const char *x, Py_ssize_t n, const int *cols,
                       int ncols) noexcept nogil:
    # what run() keeps of the state after a sample: all of it, or the words outputs= needs
    cdef const imf_real *src = <const imf_real *>x
    cdef int j
    if ncols == 0:
        _copy_state(dst, x, n)
    else:
        for j in range(ncols):
            dst[j] = src[cols[j]]


cdef inline bint _plain(object x):
    # a Python float (or subclass: numpy.float64) or a Python int that fits a
    # double: converted directly; anything else goes through imufuse.shared.checks
    return PyFloat_Check(x) or (PyLong_CheckExact(x) and -2**1000 < x < 2**1000)


# one float64 or float32 element (type number t) as imf_real
cdef inline imf_real _load(const char *base, int t, Py_ssize_t i) noexcept nogil:
    if t == cnp.NPY_DOUBLE:
        return <imf_real>(<const double *>base)[i]
    return <imf_real>(<const float *>base)[i]


cdef inline bint _row3(object v, imf_real *out) noexcept:
    """A 1-D array of three float64 or float32 values, C-contiguous, aligned and
    native-endian (a row of an (N, 3) array): read in place through the numpy
    C API (the values are those the generic path would read)."""
    if not cnp.PyArray_Check(v):
        return False
    cdef int t = cnp.PyArray_TYPE(<cnp.ndarray>v)
    if cnp.PyArray_NDIM(<cnp.ndarray>v) != 1 or cnp.PyArray_DIM(<cnp.ndarray>v, 0) != 3 \
            or (t != cnp.NPY_DOUBLE and t != cnp.NPY_FLOAT) \
            or not cnp.PyArray_ISCARRAY_RO(<cnp.ndarray>v) \
            or not cnp.PyArray_ISNOTSWAPPED(<cnp.ndarray>v):
        return False
    cdef const char *p = <const char *>cnp.PyArray_DATA(<cnp.ndarray>v)
    out[0] = _load(p, t, 0)
    out[1] = _load(p, t, 1)
    out[2] = _load(p, t, 2)
    return True


cdef int _vec3(object v, imf_real *out) except -1:
    """One 3-vector of update(): fast paths for contiguous float64/float32
    arrays (_row3), tuples and lists; anything else through the sequence
    protocol. A conversion error raises TypeError/ValueError (update() reports
    it)."""
    cdef int i
    if _row3(v, out):
        return 0
    if (type(v) is tuple or type(v) is list) and len(v) == 3 and _plain(v[0]) \
            and _plain(v[1]) and _plain(v[2]):
        for i in range(3):
            out[i] = <imf_real>PyFloat_AsDouble(v[i])
        return 0
    # the shared validation: real numbers only (no strings, complex, sets, dicts)
    x, y, z = _checks.as_vec3("vector", v)
    out[0] = <imf_real><double>x
    out[1] = <imf_real><double>y
    out[2] = <imf_real><double>z
    return 0


cdef int _unbound(object f) except -1:
    """An instance whose __init__ never ran (type(f).__new__(type(f))): its C
    struct was never initialised; raise instead of touching it."""
    raise TypeError(f"{type(f).__name__}: object not initialised (__init__ was not called)")


def _rebuild(cls, ctor, x, skipped, pending, win):
    """Unpickle / copy a filter: constructed as it was, then its state bytes, skipped count
    and a pending init="first" window restored as they were (it continues bit for bit)."""
    args, kwargs = ctor
    f = cls(*args, **kwargs)
    (<_Filter>f)._restore(x, skipped, pending, win)
    return f


#: constructor arguments checked before, by _ctor_key: (checked, C init arguments, start).
#: A filter built again with the same arguments (a fresh filter per log, per search point)
#: skips the checks in Python, which cost a hundred times a short run.
_CTOR_CHECKED = {}
_CTOR_CHECKED_MAX = 1024


cdef object _typed(object v):
    # a value with its type, a tuple's items each with theirs: (0.6, 1.4) and
    # (0.6+0j, 1.4+0j) are equal with one hash, but only the first is a valid acc_gate
    if type(v) is tuple:
        return (tuple, tuple([_typed(x) for x in <tuple>v]))
    return (type(v), v)


cdef object _ctor_key(object cls, tuple args, dict kwargs):
    """The arguments as a key that tells 1, 1.0, True and np.float64(1) apart (each value
    with its type, inside tuples too), or None when a value is not hashable (not cached)."""
    key = (cls, tuple([_typed(a) for a in args]),
           tuple(sorted([(k, _typed(v)) for k, v in kwargs.items()])))
    try:
        hash(key)
    except TypeError:
        return None
    return key


#: (adapter, state words) of run(..., outputs=) per filter class and output (a class's
#: state names are its own: imufuse.shared.estimate.output_columns once per pair)
_OUT_COLUMNS = {}


cdef tuple _out_columns(object f, object outputs):
    try:
        key = (type(f), outputs)
        hit = _OUT_COLUMNS.get(key)
    except TypeError:     # not hashable: output_columns names the mistake
        key = hit = None
    if hit is None:
        hit = _estimate.output_columns(f, outputs)
        if key is not None:
            _OUT_COLUMNS[key] = hit
    return hit


cdef object _outputs(object f, str key, tuple cols, object out):
    """outputs= from the kept state words: a quaternion state's unit quaternions in C
    (imufuse.shared.estimate's quaternion adapter, operation for operation), any other
    through the estimate adapter."""
    if key != "quaternion":
        return _estimate.outputs_from_columns(f, key, cols, out)
    cdef Py_ssize_t k, n = cnp.PyArray_DIM(<cnp.ndarray>out, 0)
    # float64: in place (each row read before it is written)
    res = out if sizeof(imf_real) == sizeof(double) else np.empty((n, 4), dtype=np.float64)
    cdef const imf_real *s = <const imf_real *>cnp.PyArray_DATA(<cnp.ndarray>out)
    cdef double *r = <double *>cnp.PyArray_DATA(<cnp.ndarray>res)
    cdef double a, b, c, d, norm
    with nogil:
        for k in range(n):
            a = s[4 * k]
            b = s[4 * k + 1]
            c = s[4 * k + 2]
            d = s[4 * k + 3]
            norm = sqrt(((a * a + b * b) + c * c) + d * d)
            r[4 * k] = a / norm
            r[4 * k + 1] = b / norm
            r[4 * k + 2] = c / norm
            r[4 * k + 3] = d / norm
    return res


cdef class _Filter:
    cdef tuple _ctor
    cdef char *_x
    cdef Py_ssize_t _n
    cdef uint32_t *_skipped
    cdef object _args
    cdef dict _kw
    cdef tuple _start
    cdef imf_real _dt0
    cdef int _pending
    cdef imf_attitude_window_t _win
    cdef _StateOut _out
    cdef void *_whole
    cdef int _busy          # run() in progress in some thread (_guard.pxi)
    cdef int _ncols         # run() keeps these state words only (outputs=): 0 keeps all
    cdef int _cols[16]
    _ref = None
    dtype = DTYPE

    def __init__(self, *args, init="identity", init_window=1, q0=None, state=None, **kwargs):
        start = {k: v for k, v, d in (("init", init, "identity"), ("init_window", init_window, 1),
                                      ("q0", q0, None), ("state", state, None))
                 if not (v is d or (isinstance(v, (str, int)) and v == d))}
        ctor = (args, dict(kwargs, **start))
        # the same arguments checked before (a start given by values that hash, such as
        # init="first": tune's filter per log and search point): their checked values
        key = _ctor_key(type(self), args, ctor[1])
        hit = _CTOR_CHECKED.get(key) if key is not None else None
        if hit is None:
            checked = self._ref._checked_params(DTYPE, *args, **kwargs)
            # the C init arguments by name (the reference _init's = the C init's names)
            kw = _init_arguments(self._ref, checked)
            how = _checks.check_start(self._ref.kind, self._ref.state_names, DTYPE, init,
                                      init_window, q0, state,
                                      getattr(self._ref, "own_start", None))
            if key is not None and len(_CTOR_CHECKED) < _CTOR_CHECKED_MAX:
                _CTOR_CHECKED[key] = (checked, kw, how)
        else:
            checked, kw, how = hit
        kw = dict(kw)
        n = len(self._ref.state_names)
        out = _StateOut(n, _NATIVE)
        _idle(self._busy, self)     # everything checked: no Python code until the C init
        self._ctor, self._args, self._kw, self._n, self._out, self._start = \
            ctor, checked, kw, n, out, how
        # the constructor's period (filters without a dt, like VarioKF, never use it)
        self._dt0 = <imf_real><double>self._kw.get("dt", 0.0)
        self._init()
        self._apply_start()

    cdef int _init(self) except -1:
        raise NotImplementedError

    cdef void _set_dt(self, imf_real dt) noexcept nogil:
        pass

    cdef void _set_attitude(self, const imf_attitude_t *att) noexcept nogil:
        pass

    cdef void _step3(self, const imf_real *g, const imf_real *a, const imf_real *m) noexcept nogil:
        # one sample of a 3-D filter (run_filters, _sweep.pxi): m is ignored by 6-D filters
        pass

    cdef int _apply_start(self) except -1:
        cdef imf_attitude_t att
        how = self._start[0]
        self._pending = 0
        if how == "first":
            imf_attitude_window_init(&self._win, <uint32_t>self._start[1])
            self._pending = 1
        elif how == "q":
            q = self._start[1]
            if not imf_attitude_from_quat(&att, <double>q[0], <double>q[1], <double>q[2],
                                          <double>q[3]):
                raise ValueError(f"q0: not a valid quaternion in {DTYPE}")
            self._set_attitude(&att)
        elif how == "state":
            self.state = self._start[1]
        return 0

    cdef void _first(self, const imf_real *g, const imf_real *a,
                     const imf_real *m) noexcept nogil:
        # init="first": one sample of the window of first readings
        cdef imf_attitude_t att
        cdef int r
        if not imf_finite3(g[0], g[1], g[2]):
            self._skipped[0] += 1
            return
        r = imf_attitude_window_add(&self._win, &att, a[0], a[1], a[2], m[0], m[1], m[2])
        if r < 0:
            self._skipped[0] += 1
        elif r > 0:
            self._set_attitude(&att)
            if self._win.n >= self._win.window:
                self._pending = 0

    # ---- filters are values: copy, deepcopy and pickle continue bit for bit
    def __reduce__(self):
        if self._x == NULL:
            _unbound(self)
        _idle(self._busy, self)
        x = (<char *>self._x)[:self._n * sizeof(imf_real)]
        skipped, pending = self._skipped[0], self._pending
        win = (<char *>&self._win)[:sizeof(self._win)]
        return (_rebuild, (type(self), self._ctor, x, skipped, pending, win))

    def __copy__(self):
        fn, args = self.__reduce__()
        return fn(*args)

    def __deepcopy__(self, memo):
        return self.__copy__()

    cdef int _restore(self, bytes x, uint32_t skipped, int pending, bytes win) except -1:
        if len(x) != self._n * <Py_ssize_t>sizeof(imf_real) or len(win) != sizeof(self._win):
            raise ValueError(f"{type(self).__name__}: pickled state of another build")
        memcpy(self._x, <const char *>x, len(x))
        self._skipped[0] = skipped
        self._pending = pending
        memcpy(&self._win, <const char *>win, len(win))
        return 0

    cdef int _bind(self, void *x, size_t size, uint32_t *skipped, void *whole=NULL) except -1:
        if size != <size_t>self._n * sizeof(imf_real):
            raise AssertionError("state struct does not match state_names")
        self._x = <char *>x
        self._whole = whole     # the C struct: a lane kernel reads its settings and state
        self._skipped = skipped
        return 0

    @property
    def kind(self):
        return self._ref.kind

    @property
    def state_names(self):
        return self._ref.state_names

    @property
    def skipped(self):
        """Samples rejected by the non-finite policy since construction or reset."""
        if self._skipped == NULL:
            _unbound(self)
        _idle(self._busy, self)
        return self._skipped[0]

    @property
    def state(self):
        if self._x == NULL:
            _unbound(self)
        out = self._out.take()          # a new copy for every read (_stateout.pxi)
        _idle(self._busy, self)
        memcpy(cnp.PyArray_DATA(<cnp.ndarray>out), self._x, self._n * sizeof(imf_real))
        return out

    @state.setter
    def state(self, value):
        if self._x == NULL:
            _unbound(self)
        arr = _checks.as_state(value, self._n, DTYPE, self._ref.state_names)
        with np.errstate(all="ignore"):     # an overflow in the check is its answer, no warning
            problem = self._ref._valid_state(self._args, _R, arr)
        _checks.check_valid_state(problem)
        problem = _checks.dead_state(self, arr, self._ref.kind)
        if problem:
            raise ValueError(problem)
        cdef const imf_real[::1] v = arr
        _idle(self._busy, self)         # checked above: no Python code from here
        memcpy(self._x, &v[0], self._n * sizeof(imf_real))
        self._pending = 0   # a state set by hand ends a pending init="first"

    @classmethod
    def run_many(cls, params, *inputs, dt=None, score=None, outputs="state", lanes=None,
                 threads=None):
        """Run one filter per parameter set of ``params`` (a sequence of constructor keyword
        dicts, e.g. {"beta": 0.05, "dt": 0.01, "init": "first"}) over one log in one compiled
        call: each set's result is bit for bit its own run()'s. See run_filters for inputs,
        dt, score, outputs, lanes and threads."""
        return _run_many(cls, params, inputs, dt, score, outputs, lanes, threads)

    def reset(self):
        """Back to the state after construction (init runs again)."""
        if self._x == NULL:
            _unbound(self)
        _idle(self._busy, self)
        self._init()
        self._apply_start()

    def __repr__(self):
        return f"<imufuse_c {type(self).__name__} dtype={DTYPE}>"

    cdef void _keep(self, tuple cols):
        # run(..., outputs=) keeps only the state words its output is read from
        # (imufuse.shared.estimate.output_columns) while the filter runs: read afterwards as
        # run_outputs reads the whole trajectory, the same values without N x len(state)
        # words. Set inside run()'s claim (_guard.pxi), cleared in its finally.
        cdef int j
        if cols is None:
            self._ncols = 0
            return
        for j in range(len(cols)):
            self._cols[j] = cols[j]
        self._ncols = len(cols)


# ---- run(): inputs read in place ---------------------------------------------
# A C-contiguous, aligned, native-endian float32 or float64 array of the right
# shape is read where it lies: no copy, no temporary. Arrays of the other float
# type are converted element by element inside the loop (a float32 filter given
# float64 data rounds each value to float32 as it reads it, exactly as
# numpy's astype would); anything else (lists, strided views, other dtypes, bad
# shapes) goes through imufuse.shared.checks.run_inputs, which converts it or raises
# the error naming the shapes. (The per-sample dt and init="first" paths
# convert through _checks.run_inputs.)

cdef inline int _in_place(object v, int ndim, Py_ssize_t *n) except -2:
    """The numpy type number of v if it can be read in place as a (n,) or (n, 3)
    float array (n = -1: any, set to v's), else -1."""
    if not cnp.PyArray_Check(v):
        return -1
    cdef cnp.ndarray arr = <cnp.ndarray>v
    cdef int t = cnp.PyArray_TYPE(arr)
    if (t != cnp.NPY_DOUBLE and t != cnp.NPY_FLOAT) or cnp.PyArray_NDIM(arr) != ndim \
            or not cnp.PyArray_ISCARRAY_RO(arr) or not cnp.PyArray_ISNOTSWAPPED(arr):
        return -1
    if ndim == 2 and cnp.PyArray_DIM(arr, 1) != 3:
        return -1
    if n[0] < 0:
        n[0] = cnp.PyArray_DIM(arr, 0)
    elif cnp.PyArray_DIM(arr, 0) != n[0]:
        return -1
    return t


cdef inline void _load3(const char *base, int t, Py_ssize_t k, imf_real *out) noexcept nogil:
    out[0] = _load(base, t, 3 * k)
    out[1] = _load(base, t, 3 * k + 1)
    out[2] = _load(base, t, 3 * k + 2)


cdef inline object _trajectory(Py_ssize_t n_samples, Py_ssize_t n):
    cdef cnp.npy_intp dims[2]
    dims[0] = n_samples
    dims[1] = n
    return cnp.PyArray_EMPTY(2, dims, _NATIVE, 0)


cdef class _Filter1D(_Filter):
    cdef void _step(self, imf_real rate, imf_real angle) noexcept nogil:
        pass

    def update(self, rate, angle, dt=None):
        """One sample: rate (rad/s), angle (rad); dt (s): this sample's period."""
        if self._x == NULL:
            _unbound(self)
        cdef double w, a
        if _plain(rate) and _plain(angle):
            w = rate
            a = angle
        else:
            w, a = _checks.update_inputs("1d", (rate, angle))
        cdef imf_real d
        if dt is None:
            _idle(self._busy, self)
            self._step(<imf_real>w, <imf_real>a)
        else:
            d = _dt_step(dt)
            _idle(self._busy, self)
            self._set_dt(d)
            self._step(<imf_real>w, <imf_real>a)
            self._set_dt(self._dt0)

    cdef object _run_dt(self, rate, angle, dt):
        rate_a, angle_a = _checks.run_inputs("1d", DTYPE, (rate, angle))
        cdef Py_ssize_t n_samples = rate_a.shape[0], n = self._n, k
        dt_a = _checks.dt_array(dt, n_samples, DTYPE)
        out = np.empty((n_samples, n), dtype=DTYPE)
        cdef const imf_real[::1] w = rate_a
        cdef const imf_real[::1] a = angle_a
        cdef const imf_real[::1] d = dt_a
        cdef imf_real[:, ::1] o = out
        with nogil:
            for k in range(n_samples):
                self._set_dt(d[k])
                self._step(w[k], a[k])
                _copy_state(&o[k, 0], self._x, n)
            self._set_dt(self._dt0)
        return out

    def run(self, rate, angle, dt=None, outputs="state"):
        """All samples: rate, angle 1-D arrays, dt (optional) the (N,) sample
        periods; returns the (N, len(state)) trajectory."""
        if outputs != "state":
            raise ValueError(f"outputs: {type(self).__name__} has no orientation quaternion "
                             "(a single-axis filter); use the state")
        if self._x == NULL:
            _unbound(self)
        _claim(&self._busy, self)
        try:
            if dt is not None:
                return self._run_dt(rate, angle, dt)
            return self._run(rate, angle)
        finally:
            self._busy = 0

    cdef object _run(self, rate, angle):
        # run() at the constructor's dt: arrays read in place where they can be
        cdef Py_ssize_t n_samples = -1, n = self._n, k
        cdef int tw = _in_place(rate, 1, &n_samples)
        cdef int ta = _in_place(angle, 1, &n_samples) if tw >= 0 else -1
        if ta < 0:
            rate, angle = _checks.run_inputs("1d", DTYPE, (rate, angle))
            tw = ta = _NATIVE
            n_samples = cnp.PyArray_DIM(<cnp.ndarray>rate, 0)
        out = _trajectory(n_samples, n)
        cdef const char *w = <const char *>cnp.PyArray_DATA(<cnp.ndarray>rate)
        cdef const char *a = <const char *>cnp.PyArray_DATA(<cnp.ndarray>angle)
        cdef imf_real *o = <imf_real *>cnp.PyArray_DATA(<cnp.ndarray>out)
        with nogil:
            for k in range(n_samples):
                self._step(_load(w, tw, k), _load(a, ta, k))
                _copy_state(o + k * n, self._x, n)
        return out


cdef class _FilterIMU(_Filter):
    cdef void _step(self, const imf_real *gyr, const imf_real *acc) noexcept nogil:
        pass

    cdef void _step3(self, const imf_real *g, const imf_real *a, const imf_real *m) noexcept nogil:
        self._step(g, a)

    def update(self, gyr, acc, dt=None):
        """One sample: gyr (3,) rad/s, acc (3,) any unit; dt (s): this sample's period."""
        if self._x == NULL:
            _unbound(self)
        cdef imf_real g[3]
        cdef imf_real a[3]
        if not (_row3(gyr, g) and _row3(acc, a)):
            try:
                _vec3(gyr, g)
                _vec3(acc, a)
            except (TypeError, ValueError):
                _checks.update_inputs("imu", (gyr, acc))
                raise
        cdef imf_real d = 0
        if dt is not None:
            d = _dt_step(dt)
        _idle(self._busy, self)
        if dt is None and not self._pending:
            self._step(g, a)
        else:
            self._update_general(g, a, dt is not None, d)

    cdef object _run_general(self, gyr, acc, dt):
        # run() with per-sample dt and/or a pending init="first"
        gyr_a, acc_a = _checks.run_inputs("imu", DTYPE, (gyr, acc))
        cdef Py_ssize_t n_samples = gyr_a.shape[0], n = self._n, k = 0, k0
        cdef int use_dt = dt is not None
        cdef imf_real z3[3]
        z3[0] = 0
        z3[1] = 0
        z3[2] = 0
        dt_a = _checks.dt_array(dt, n_samples, DTYPE) if use_dt else np.zeros(1, DTYPE)
        out = np.empty((n_samples, self._ncols or n), dtype=DTYPE)
        cdef const imf_real[:, ::1] g = gyr_a
        cdef const imf_real[:, ::1] a = acc_a
        cdef const imf_real[::1] d = dt_a
        cdef imf_real[:, ::1] o = out
        with nogil:
            while k < n_samples and self._pending:
                self._first(&g[k, 0], &a[k, 0], z3)
                _emit(&o[k, 0], self._x, n, self._cols, self._ncols)
                k += 1
            k0 = k
            if use_dt:
                for k in range(k0, n_samples):
                    self._set_dt(d[k])
                    self._step(&g[k, 0], &a[k, 0])
                    _emit(&o[k, 0], self._x, n, self._cols, self._ncols)
                self._set_dt(self._dt0)
            else:
                for k in range(k0, n_samples):
                    self._step(&g[k, 0], &a[k, 0])
                    _emit(&o[k, 0], self._x, n, self._cols, self._ncols)
        return out

    cdef void _update_general(self, const imf_real *g, const imf_real *a, bint use_dt,
                              imf_real dt) noexcept:
        # update() with a dt (use_dt: dt, checked) and/or a pending init="first"
        cdef imf_real z[3]
        cdef imf_real step_dt = dt if use_dt else self._dt0
        z[0] = 0
        z[1] = 0
        z[2] = 0
        if self._pending:
            self._first(g, a, z)
        else:
            self._set_dt(step_dt)
            self._step(g, a)
            self._set_dt(self._dt0)

    def run(self, gyr, acc, dt=None, outputs="state"):
        """All samples: gyr, acc (N, 3) arrays, dt (optional) the (N,) sample
        periods; returns the (N, len(state)) trajectory, or with outputs="q" the (N, 4)
        quaternions sensor -> earth (imufuse.shared.estimate.run_outputs)."""
        cols = None
        if outputs != "state":
            key, cols = _out_columns(self, outputs)
            if len(cols) > 16:
                return _estimate.run_outputs(self, self.run(gyr, acc, dt), outputs)
        if self._x == NULL:
            _unbound(self)
        _claim(&self._busy, self)
        try:
            self._keep(cols)
            if dt is not None or self._pending:
                out = self._run_general(gyr, acc, dt)
            else:
                out = self._run(gyr, acc)
        finally:
            self._ncols = 0
            self._busy = 0
        return out if cols is None else _outputs(self, key, cols, out)

    cdef object _run(self, gyr, acc):
        # run() at the constructor's dt: arrays read in place where they can be
        cdef Py_ssize_t n_samples = -1, n = self._n, k
        cdef int tg = _in_place(gyr, 2, &n_samples)
        cdef int ta = _in_place(acc, 2, &n_samples) if tg >= 0 else -1
        if ta < 0:
            gyr, acc = _checks.run_inputs("imu", DTYPE, (gyr, acc))
            tg = ta = _NATIVE
            n_samples = cnp.PyArray_DIM(<cnp.ndarray>gyr, 0)
        cdef Py_ssize_t w = self._ncols or n
        out = _trajectory(n_samples, w)
        cdef const char *pg = <const char *>cnp.PyArray_DATA(<cnp.ndarray>gyr)
        cdef const char *pa = <const char *>cnp.PyArray_DATA(<cnp.ndarray>acc)
        cdef imf_real *o = <imf_real *>cnp.PyArray_DATA(<cnp.ndarray>out)
        cdef imf_real g[3]
        cdef imf_real a[3]
        with nogil:
            if tg == _NATIVE and ta == _NATIVE:
                for k in range(n_samples):
                    self._step(<const imf_real *>pg + 3 * k, <const imf_real *>pa + 3 * k)
                    _emit(o + k * w, self._x, n, self._cols, self._ncols)
            else:
                for k in range(n_samples):
                    _load3(pg, tg, k, g)
                    _load3(pa, ta, k, a)
                    self._step(g, a)
                    _emit(o + k * w, self._x, n, self._cols, self._ncols)
        return out


cdef class _FilterAHRS(_Filter):
    cdef void _step(self, const imf_real *gyr, const imf_real *acc,
                    const imf_real *mag) noexcept nogil:
        pass

    cdef void _step3(self, const imf_real *g, const imf_real *a, const imf_real *m) noexcept nogil:
        self._step(g, a, m)

    def update(self, gyr, acc, mag, dt=None):
        """One sample: gyr (3,) rad/s, acc (3,) and mag (3,) any unit; dt (s): this
        sample's period."""
        if self._x == NULL:
            _unbound(self)
        cdef imf_real g[3]
        cdef imf_real a[3]
        cdef imf_real m[3]
        if not (_row3(gyr, g) and _row3(acc, a) and _row3(mag, m)):
            try:
                _vec3(gyr, g)
                _vec3(acc, a)
                _vec3(mag, m)
            except (TypeError, ValueError):
                _checks.update_inputs("ahrs", (gyr, acc, mag))
                raise
        cdef imf_real d = 0
        if dt is not None:
            d = _dt_step(dt)
        _idle(self._busy, self)
        if dt is None and not self._pending:
            self._step(g, a, m)
        else:
            self._update_general(g, a, m, dt is not None, d)

    cdef object _run_general(self, gyr, acc, mag, dt):
        # run() with per-sample dt and/or a pending init="first"
        gyr_a, acc_a, mag_a = _checks.run_inputs("ahrs", DTYPE, (gyr, acc, mag))
        cdef Py_ssize_t n_samples = gyr_a.shape[0], n = self._n, k = 0, k0
        cdef int use_dt = dt is not None
        dt_a = _checks.dt_array(dt, n_samples, DTYPE) if use_dt else np.zeros(1, DTYPE)
        out = np.empty((n_samples, self._ncols or n), dtype=DTYPE)
        cdef const imf_real[:, ::1] g = gyr_a
        cdef const imf_real[:, ::1] a = acc_a
        cdef const imf_real[:, ::1] m = mag_a
        cdef const imf_real[::1] d = dt_a
        cdef imf_real[:, ::1] o = out
        with nogil:
            while k < n_samples and self._pending:
                self._first(&g[k, 0], &a[k, 0], &m[k, 0])
                _emit(&o[k, 0], self._x, n, self._cols, self._ncols)
                k += 1
            k0 = k
            if use_dt:
                for k in range(k0, n_samples):
                    self._set_dt(d[k])
                    self._step(&g[k, 0], &a[k, 0], &m[k, 0])
                    _emit(&o[k, 0], self._x, n, self._cols, self._ncols)
                self._set_dt(self._dt0)
            else:
                for k in range(k0, n_samples):
                    self._step(&g[k, 0], &a[k, 0], &m[k, 0])
                    _emit(&o[k, 0], self._x, n, self._cols, self._ncols)
        return out

    cdef void _update_general(self, const imf_real *g, const imf_real *a, const imf_real *m,
                              bint use_dt, imf_real dt) noexcept:
        # update() with a dt (use_dt: dt, checked) and/or a pending init="first"
        cdef imf_real step_dt = dt if use_dt else self._dt0
        if self._pending:
            self._first(g, a, m)
        else:
            self._set_dt(step_dt)
            self._step(g, a, m)
            self._set_dt(self._dt0)

    def run(self, gyr, acc, mag, dt=None, outputs="state"):
        """All samples: gyr, acc, mag (N, 3) arrays, dt (optional) the (N,) sample
        periods; returns the (N, len(state)) trajectory, or with outputs="q" the (N, 4)
        quaternions sensor -> earth (imufuse.shared.estimate.run_outputs)."""
        cols = None
        if outputs != "state":
            key, cols = _out_columns(self, outputs)
            if len(cols) > 16:
                return _estimate.run_outputs(self, self.run(gyr, acc, mag, dt), outputs)
        if self._x == NULL:
            _unbound(self)
        _claim(&self._busy, self)
        try:
            self._keep(cols)
            if dt is not None or self._pending:
                out = self._run_general(gyr, acc, mag, dt)
            else:
                out = self._run(gyr, acc, mag)
        finally:
            self._ncols = 0
            self._busy = 0
        return out if cols is None else _outputs(self, key, cols, out)

    cdef object _run(self, gyr, acc, mag):
        # run() at the constructor's dt: arrays read in place where they can be
        cdef Py_ssize_t n_samples = -1, n = self._n, k
        cdef int tg = _in_place(gyr, 2, &n_samples)
        cdef int ta = _in_place(acc, 2, &n_samples) if tg >= 0 else -1
        cdef int tm = _in_place(mag, 2, &n_samples) if ta >= 0 else -1
        if tm < 0:
            gyr, acc, mag = _checks.run_inputs("ahrs", DTYPE, (gyr, acc, mag))
            tg = ta = tm = _NATIVE
            n_samples = cnp.PyArray_DIM(<cnp.ndarray>gyr, 0)
        cdef Py_ssize_t w = self._ncols or n
        out = _trajectory(n_samples, w)
        cdef const char *pg = <const char *>cnp.PyArray_DATA(<cnp.ndarray>gyr)
        cdef const char *pa = <const char *>cnp.PyArray_DATA(<cnp.ndarray>acc)
        cdef const char *pm = <const char *>cnp.PyArray_DATA(<cnp.ndarray>mag)
        cdef imf_real *o = <imf_real *>cnp.PyArray_DATA(<cnp.ndarray>out)
        cdef imf_real g[3]
        cdef imf_real a[3]
        cdef imf_real m[3]
        with nogil:
            if tg == _NATIVE and ta == _NATIVE and tm == _NATIVE:
                for k in range(n_samples):
                    self._step(<const imf_real *>pg + 3 * k, <const imf_real *>pa + 3 * k,
                               <const imf_real *>pm + 3 * k)
                    _emit(o + k * w, self._x, n, self._cols, self._ncols)
            else:
                for k in range(n_samples):
                    _load3(pg, tg, k, g)
                    _load3(pa, ta, k, a)
                    _load3(pm, tm, k, m)
                    self._step(g, a, m)
                    _emit(o + k * w, self._x, n, self._cols, self._ncols)
        return out


include "_sweep.pxi"
