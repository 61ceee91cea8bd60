# The Fusion suite (csrc/fusion_*.h): Longbin's Fusion walkthrough, x-io Fusion as in imufusion 1.2.3.
# Units are Fusion's (deg/s, g, degrees); see imufuse.reference.fusion.
# Hand-written (not tools/bindgen.py): Fusion's own API: dt with every update, three update
# forms, FusionOffset returning the corrected gyroscope, and Fusion's flags and internal states.
from libc.stdint cimport int32_t

from imufuse.reference import _fusion

cdef extern from "fusion_ahrs.h" nogil:
    ctypedef struct imf_fusion_ahrs_settings_t:
        int convention
        imf_real gain
        imf_real gyroscope_range
        imf_real acceleration_rejection
        imf_real magnetic_rejection
        int32_t recovery_trigger_period
    ctypedef struct imf_fusion_ahrs_state_t:
        pass
    ctypedef struct imf_fusion_ahrs_config_t:
        pass
    ctypedef struct imf_fusion_ahrs_t:
        imf_fusion_ahrs_config_t set
        uint32_t skipped
        imf_fusion_ahrs_state_t x
    ctypedef struct imf_fusion_vec_t:
        imf_real x, y, z
    void imf_fusion_ahrs_init(imf_fusion_ahrs_t *self, const imf_fusion_ahrs_settings_t *settings,
                              int invsqrt)
    void imf_fusion_ahrs_reset(imf_fusion_ahrs_t *self)
    void imf_fusion_ahrs_set_settings(imf_fusion_ahrs_t *self,
                                      const imf_fusion_ahrs_settings_t *settings)
    void imf_fusion_ahrs_update(imf_fusion_ahrs_t *self, imf_real gx, imf_real gy, imf_real gz,
                                imf_real ax, imf_real ay, imf_real az,
                                imf_real mx, imf_real my, imf_real mz, imf_real dt)
    void imf_fusion_ahrs_update_no_magnetometer(imf_fusion_ahrs_t *self, imf_real gx, imf_real gy,
                                                imf_real gz, imf_real ax, imf_real ay,
                                                imf_real az, imf_real dt)
    void imf_fusion_ahrs_update_external_heading(imf_fusion_ahrs_t *self, imf_real gx,
                                                 imf_real gy, imf_real gz, imf_real ax,
                                                 imf_real ay, imf_real az, imf_real heading,
                                                 imf_real dt)
    void imf_fusion_ahrs_set_heading(imf_fusion_ahrs_t *self, imf_real heading)
    void imf_fusion_ahrs_get_state(const imf_fusion_ahrs_t *self, imf_real *out)
    void imf_fusion_ahrs_set_state(imf_fusion_ahrs_t *self, const imf_real *inp)
    void imf_fusion_ahrs_outputs(const imf_fusion_ahrs_t *self, imf_real *out)
    unsigned imf_fusion_ahrs_flags(const imf_fusion_ahrs_t *self)
    enum:
        IMF_FUSION_AHRS_N_STATE
        IMF_FUSION_N_OUT

cdef extern from "fusion_offset.h" nogil:
    ctypedef struct imf_fusion_offset_state_t:
        uint32_t timer
    ctypedef struct imf_fusion_offset_t:
        uint32_t skipped
        imf_fusion_offset_state_t x
    void imf_fusion_offset_init(imf_fusion_offset_t *self, uint32_t sample_rate)
    void imf_fusion_offset_update(imf_fusion_offset_t *self, const imf_real *g, imf_real *out)
    void imf_fusion_offset_get_state(const imf_fusion_offset_t *self, imf_real *out)
    void imf_fusion_offset_set_state(imf_fusion_offset_t *self, const imf_real *inp)

cdef extern from "fusion_calibration.h" nogil:
    void imf_fusion_calibrate_inertial(const imf_real *m, const imf_real *s, const imf_real *b,
                                       const imf_real *inp, imf_real *out, size_t n)
    void imf_fusion_calibrate_magnetic(const imf_real *soft_iron, const imf_real *hard_iron,
                                       const imf_real *inp, imf_real *out, size_t n)
    void imf_fusion_axes_apply(const int *perm, const int *negate, const imf_real *inp,
                               imf_real *out, size_t n)
    void imf_fusion_compass_headings(int convention, const imf_real *acc, const imf_real *mag,
                                     imf_real *out, size_t n, int invsqrt)


cdef inline double _dt_value(object dt) except? -1.0:
    """dt of one update: a float >= 0 (or non-finite: the C's non-finite policy)
    without a Python call; anything else through _fusion.check_dt_value."""
    cdef double d
    if type(dt) is float:
        d = dt
        if not d < 0.0:
            return d
    return _fusion.check_dt_value(dt)


cdef int _settings_from(tuple a, imf_fusion_ahrs_settings_t *st) except -1:
    st.convention = a[0]
    st.gain = <imf_real>a[1]
    st.gyroscope_range = <imf_real>a[2]
    st.acceleration_rejection = <imf_real>a[3]
    st.magnetic_rejection = <imf_real>a[4]
    st.recovery_trigger_period = a[5]
    return 0


def _empty(cls):
    return cls.__new__(cls)


cdef class FusionAHRS:
    cdef imf_fusion_ahrs_t s
    cdef tuple _args
    cdef _StateOut _out
    cdef int _busy          # run() in progress in some thread (_guard.pxi)
    _ref = _reference.FusionAHRS
    dtype = DTYPE
    kind = "fusion"
    state_names = _fusion.AHRS_STATE_NAMES
    __doc__ = _reference.FusionAHRS.__doc__

    def __cinit__(self, *args, **kwargs):
        self._out = _StateOut(IMF_FUSION_AHRS_N_STATE, _NATIVE)

    def __init__(self, *args, **kwargs):
        a = _reference.FusionAHRS._params(*args, dtype=DTYPE, **kwargs)
        _idle(self._busy, self)
        self._args = a
        self._init()

    cdef _init(self):
        cdef imf_fusion_ahrs_settings_t st
        _settings_from(self._args, &st)
        imf_fusion_ahrs_init(&self.s, &st, self._args[6])

    def reset(self):
        """Back to the initial state, keeping the settings (FusionAhrsReset)."""
        _idle(self._busy, self)
        imf_fusion_ahrs_reset(&self.s)

    # a value: the whole C struct (settings and state, no pointers) is copied as it is
    def __reduce__(self):
        _idle(self._busy, self)
        raw = (<char *>&self.s)[:sizeof(self.s)]
        return (_empty, (type(self),), (self._args, raw))

    def __setstate__(self, st):
        args, raw = st
        if len(raw) != sizeof(self.s):
            raise ValueError("FusionAHRS: pickled state of another build")
        _idle(self._busy, self)
        self._args = args
        memcpy(&self.s, <const char *>raw, sizeof(self.s))

    def __copy__(self):
        fn, a, st = self.__reduce__()
        f = fn(*a)
        f.__setstate__(st)
        return f

    def __deepcopy__(self, memo):
        return self.__copy__()

    def set_settings(self, **settings):
        """New settings at any time (FusionAhrsSetSettings): the state is kept."""
        _fusion.check_settings(settings)
        names = ("convention", "gain", "gyroscope_range", "acceleration_rejection",
                 "magnetic_rejection", "recovery_trigger_period")
        a = self._args
        cur = dict(zip(names, ([k for k, v in _fusion.CONVENTIONS.items() if v == a[0]][0],
                               *a[1:6])))
        cur.update(settings)
        inv = [k for k, v in _fusion.INVSQRT.items() if v == a[6]][0]
        new = _reference.FusionAHRS._params(**cur, invsqrt=inv, dtype=DTYPE)
        cdef imf_fusion_ahrs_settings_t st
        _settings_from(new, &st)
        _idle(self._busy, self)
        self._args = new
        imf_fusion_ahrs_set_settings(&self.s, &st)

    @property
    def skipped(self):
        _idle(self._busy, self)
        return self.s.skipped

    def update(self, gyr, acc, mag, dt):
        """One sample: gyr (deg/s), acc (g), mag (any unit), dt (s)."""
        cdef imf_real g[3]
        cdef imf_real a[3]
        cdef imf_real m[3]
        try:
            _vec3(gyr, g)
            _vec3(acc, a)
            _vec3(mag, m)
        except (TypeError, ValueError):
            for name, v in (("gyr", gyr), ("acc", acc), ("mag", mag)):
                _checks.as_vec3(name, v)
            raise
        cdef imf_real d = <imf_real>_dt_value(dt)
        _idle(self._busy, self)
        imf_fusion_ahrs_update(&self.s, g[0], g[1], g[2], a[0], a[1], a[2], m[0], m[1], m[2], d)

    def update_no_magnetometer(self, gyr, acc, dt):
        """One sample without magnetometer; heading held at 0 while initialising."""
        cdef imf_real g[3]
        cdef imf_real a[3]
        try:
            _vec3(gyr, g)
            _vec3(acc, a)
        except (TypeError, ValueError):
            for name, v in (("gyr", gyr), ("acc", acc)):
                _checks.as_vec3(name, v)
            raise
        cdef imf_real d = <imf_real>_dt_value(dt)
        _idle(self._busy, self)
        imf_fusion_ahrs_update_no_magnetometer(&self.s, g[0], g[1], g[2], a[0], a[1], a[2], d)

    def update_external_heading(self, gyr, acc, heading, dt):
        """One sample with a heading (degrees) from another source."""
        cdef imf_real g[3]
        cdef imf_real a[3]
        try:
            _vec3(gyr, g)
            _vec3(acc, a)
        except (TypeError, ValueError):
            for name, v in (("gyr", gyr), ("acc", acc)):
                _checks.as_vec3(name, v)
            raise
        cdef imf_real h = <imf_real>_fusion.check_scalar("heading", heading)
        cdef imf_real d = <imf_real>_dt_value(dt)
        _idle(self._busy, self)
        imf_fusion_ahrs_update_external_heading(&self.s, g[0], g[1], g[2], a[0], a[1], a[2], h, d)

    def set_heading(self, heading):
        """Rotate about the earth vertical so that the yaw is heading (degrees)."""
        h = _fusion.check_scalar("heading", heading)
        if not np.isfinite(h):
            raise ValueError(f"heading: must be finite, got {heading!r}")
        _idle(self._busy, self)
        imf_fusion_ahrs_set_heading(&self.s, <imf_real>h)

    @property
    def state(self):
        out = self._out.take()          # a new copy for every read (_stateout.pxi)
        _idle(self._busy, self)
        imf_fusion_ahrs_get_state(&self.s, <imf_real *>cnp.PyArray_DATA(<cnp.ndarray>out))
        return out

    @state.setter
    def state(self, value):
        arr = _fusion.ahrs_state(value, DTYPE, self._args[5])
        problem = _checks.dead_state(self, arr, "fusion")
        if problem:
            raise ValueError(problem)
        cdef const imf_real[::1] v = arr
        _idle(self._busy, self)
        imf_fusion_ahrs_set_state(&self.s, &v[0])

    @property
    def quaternion(self):
        return self.state[:4].copy()

    @quaternion.setter
    def quaternion(self, value):
        q = _fusion.quaternion(value, DTYPE)
        st = self.state
        st[:4] = q
        cdef const imf_real[::1] v = st
        _idle(self._busy, self)
        imf_fusion_ahrs_set_state(&self.s, &v[0])

    def outputs(self):
        """The outputs now (see imufuse.reference.FusionAHRS.outputs)."""
        out = np.empty(IMF_FUSION_N_OUT, dtype=DTYPE)
        cdef imf_real[::1] o = out
        _idle(self._busy, self)
        imf_fusion_ahrs_outputs(&self.s, &o[0])
        return _fusion.pack_one(out, imf_fusion_ahrs_flags(&self.s))

    def outputs_batch(self, states):
        """outputs() for every row of a run() result, without a Python loop."""
        arr = _fusion.states_array(states, DTYPE)
        cdef Py_ssize_t n = arr.shape[0], k
        out = np.empty((n, IMF_FUSION_N_OUT), dtype=DTYPE)
        flags = np.empty(n, dtype=np.uint32)
        cdef const imf_real[:, ::1] st = arr
        cdef imf_real[:, ::1] o = out
        cdef uint32_t[::1] fl = flags
        _idle(self._busy, self)         # the settings are copied from the filter
        cdef imf_fusion_ahrs_t tmp = self.s
        with nogil:
            for k in range(n):
                imf_fusion_ahrs_set_state(&tmp, &st[k, 0])
                imf_fusion_ahrs_outputs(&tmp, &o[k, 0])
                fl[k] = imf_fusion_ahrs_flags(&tmp)
        return _fusion.pack_outputs(out, flags)

    def run(self, gyr, acc, mag=None, *, dt, heading=None):
        """All samples (see imufuse.reference.FusionAHRS.run); (N, 22) states."""
        _claim(&self._busy, self)
        try:
            return self._run(gyr, acc, mag, dt, heading)
        finally:
            self._busy = 0

    cdef object _run(self, gyr, acc, mag, dt, heading):
        g_a, a_a, m_a, h_a, d_a = _fusion.run_arrays(DTYPE, gyr, acc, mag, heading, dt)
        cdef Py_ssize_t n = g_a.shape[0], k
        cdef int mode = 0 if m_a is not None else (1 if h_a is not None else 2)
        out = np.empty((n, IMF_FUSION_AHRS_N_STATE), dtype=DTYPE)
        cdef const imf_real[:, ::1] g = g_a
        cdef const imf_real[:, ::1] a = a_a
        cdef const imf_real[:, ::1] m = m_a if m_a is not None else g_a
        cdef const imf_real[::1] h = h_a if h_a is not None else d_a
        cdef const imf_real[::1] d = d_a
        cdef imf_real[:, ::1] o = out
        with nogil:
            for k in range(n):
                if mode == 0:
                    imf_fusion_ahrs_update(&self.s, g[k, 0], g[k, 1], g[k, 2], a[k, 0], a[k, 1],
                                           a[k, 2], m[k, 0], m[k, 1], m[k, 2], d[k])
                elif mode == 1:
                    imf_fusion_ahrs_update_external_heading(&self.s, g[k, 0], g[k, 1], g[k, 2],
                                                            a[k, 0], a[k, 1], a[k, 2], h[k], d[k])
                else:
                    imf_fusion_ahrs_update_no_magnetometer(&self.s, g[k, 0], g[k, 1], g[k, 2],
                                                           a[k, 0], a[k, 1], a[k, 2], d[k])
                imf_fusion_ahrs_get_state(&self.s, &o[k, 0])
        return out

    def __repr__(self):
        return f"<imufuse_c FusionAHRS dtype={DTYPE}>"


cdef class FusionOffset:
    cdef imf_fusion_offset_t s
    cdef tuple _args
    cdef _StateOut _out
    cdef int _busy          # run() in progress in some thread (_guard.pxi)
    _ref = _reference.FusionOffset
    dtype = DTYPE
    kind = "fusion_offset"
    state_names = _fusion.OFFSET_STATE_NAMES
    __doc__ = _reference.FusionOffset.__doc__

    def __cinit__(self, *args, **kwargs):
        self._out = _StateOut(4, _NATIVE)

    def __init__(self, sample_rate):
        a = _reference.FusionOffset._params(sample_rate)
        _idle(self._busy, self)
        self._args = a
        imf_fusion_offset_init(&self.s, self._args[0])

    def reset(self):
        _idle(self._busy, self)
        imf_fusion_offset_init(&self.s, self._args[0])

    def __reduce__(self):
        _idle(self._busy, self)
        raw = (<char *>&self.s)[:sizeof(self.s)]
        return (_empty, (type(self),), (self._args, raw))

    def __setstate__(self, st):
        args, raw = st
        if len(raw) != sizeof(self.s):
            raise ValueError("FusionOffset: pickled state of another build")
        _idle(self._busy, self)
        self._args = args
        memcpy(&self.s, <const char *>raw, sizeof(self.s))

    def __copy__(self):
        fn, a, st = self.__reduce__()
        f = fn(*a)
        f.__setstate__(st)
        return f

    def __deepcopy__(self, memo):
        return self.__copy__()

    @property
    def skipped(self):
        _idle(self._busy, self)
        return self.s.skipped

    def update(self, gyr):
        cdef imf_real g[3]
        try:
            _vec3(gyr, g)
        except (TypeError, ValueError):
            _checks.as_vec3("gyr", gyr)
            raise
        out = np.empty(3, dtype=DTYPE)
        cdef imf_real[::1] o = out
        _idle(self._busy, self)
        imf_fusion_offset_update(&self.s, g, &o[0])
        return out

    def run(self, gyr):
        _claim(&self._busy, self)
        try:
            return self._run(gyr)
        finally:
            self._busy = 0

    cdef object _run(self, gyr):
        (g_a,) = _checks.as_nx3(DTYPE, gyr=gyr)
        cdef Py_ssize_t n = g_a.shape[0], k
        out = np.empty((n, 3), dtype=DTYPE)
        st = np.empty((n, 4), dtype=DTYPE)
        cdef const imf_real[:, ::1] g = g_a
        cdef imf_real[:, ::1] o = out
        cdef imf_real[:, ::1] s = st
        with nogil:
            for k in range(n):
                imf_fusion_offset_update(&self.s, &g[k, 0], &o[k, 0])
                imf_fusion_offset_get_state(&self.s, &s[k, 0])
        return out, st

    @property
    def state(self):
        out = self._out.take()          # a new copy for every read (_stateout.pxi)
        _idle(self._busy, self)
        imf_fusion_offset_get_state(&self.s, <imf_real *>cnp.PyArray_DATA(<cnp.ndarray>out))
        return out

    @state.setter
    def state(self, value):
        arr = _checks.as_state(value, 4, DTYPE, self.state_names)
        timeout = 5 * self._args[0]
        if arr[3] != int(arr[3]) or not 0 <= arr[3] <= timeout:
            raise ValueError(f"state: timer must be an integer in [0, {timeout}]")
        cdef const imf_real[::1] v = arr
        _idle(self._busy, self)
        imf_fusion_offset_set_state(&self.s, &v[0])

    def __repr__(self):
        return f"<imufuse_c FusionOffset dtype={DTYPE}>"


def fusion_calibrate_inertial(x, M, s, b):
    (arr,) = _checks.as_nx3(DTYPE, x=np.atleast_2d(x))
    mm = _fusion.model_param("M", M, (3, 3), DTYPE)
    ss = _fusion.model_param("s", s, (3,), DTYPE)
    bb = _fusion.model_param("b", b, (3,), DTYPE)
    out = np.empty_like(arr)
    cdef const imf_real[:, ::1] i = arr
    cdef imf_real[:, ::1] o = out
    cdef const imf_real[::1] mv = mm
    cdef const imf_real[::1] sv = ss
    cdef const imf_real[::1] bv = bb
    cdef size_t n = arr.shape[0]
    if n:
        with nogil:
            imf_fusion_calibrate_inertial(&mv[0], &sv[0], &bv[0], &i[0, 0], &o[0, 0], n)
    return _checks.canonical_nan(out)


def fusion_calibrate_magnetic(x, S, h):
    (arr,) = _checks.as_nx3(DTYPE, x=np.atleast_2d(x))
    mm = _fusion.model_param("S", S, (3, 3), DTYPE)
    hh = _fusion.model_param("h", h, (3,), DTYPE)
    out = np.empty_like(arr)
    cdef const imf_real[:, ::1] i = arr
    cdef imf_real[:, ::1] o = out
    cdef const imf_real[::1] mv = mm
    cdef const imf_real[::1] hv = hh
    cdef size_t n = arr.shape[0]
    if n:
        with nogil:
            imf_fusion_calibrate_magnetic(&mv[0], &hv[0], &i[0, 0], &o[0, 0], n)
    return _checks.canonical_nan(out)


def fusion_axes_apply(x, alignment):
    perm, neg = _fusion.parse_alignment(alignment)
    (arr,) = _checks.as_nx3(DTYPE, x=np.atleast_2d(x))
    out = np.empty_like(arr)
    cdef int p[3]
    cdef int ng[3]
    for j in range(3):
        p[j] = perm[j]
        ng[j] = neg[j]
    cdef const imf_real[:, ::1] i = arr
    cdef imf_real[:, ::1] o = out
    cdef size_t n = arr.shape[0]
    if n:
        with nogil:
            imf_fusion_axes_apply(p, ng, &i[0, 0], &o[0, 0], n)
    return out


def fusion_compass_heading(convention, acc, mag, invsqrt="exact"):
    conv = _fusion.ahrs_params(DTYPE, convention)[0]
    mode = _fusion.INVSQRT[_checks.check_choice("invsqrt", invsqrt, tuple(_fusion.INVSQRT))]
    a_a, m_a = _checks.as_nx3(DTYPE, acc=np.atleast_2d(acc), mag=np.atleast_2d(mag))
    out = np.empty(a_a.shape[0], dtype=DTYPE)
    cdef const imf_real[:, ::1] a = a_a
    cdef const imf_real[:, ::1] m = m_a
    cdef imf_real[::1] o = out
    cdef size_t n = a_a.shape[0]
    cdef int c = conv, md = mode
    if n:
        with nogil:
            imf_fusion_compass_headings(c, &a[0, 0], &m[0, 0], &o[0], n, md)
    return _checks.canonical_nan(out)
