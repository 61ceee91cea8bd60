# Fusion 1.3 (csrc/fusion13.h, fusion13_bias.h): x-io Fusion's current release as in imufusion 1.3.3.
# Units are Fusion's (deg/s, g, degrees); see imufuse.reference.fusion13.
# Hand-written (not tools/bindgen.py): Fusion's own API: the sample period set before an
# update, three update forms, start-up skipped, FusionBias returning the corrected gyroscope.
from imufuse.reference import _fusion13

cdef extern from "fusion13.h" nogil:
    ctypedef struct imf_fusion13_ahrs_settings_t:
        imf_real sample_rate
        int convention
        imf_real gain
        imf_real gyroscope_range
        imf_real acceleration_rejection
        imf_real magnetic_rejection
        imf_real rejection_timeout
    ctypedef struct imf_fusion13_ahrs_state_t:
        pass
    ctypedef struct imf_fusion13_ahrs_config_t:
        pass
    ctypedef struct imf_fusion13_ahrs_t:
        uint32_t skipped
    void imf_fusion13_ahrs_init(imf_fusion13_ahrs_t *self,
                                const imf_fusion13_ahrs_settings_t *settings, int invsqrt)
    void imf_fusion13_ahrs_set_settings(imf_fusion13_ahrs_t *self,
                                        const imf_fusion13_ahrs_settings_t *settings)
    void imf_fusion13_ahrs_set_sample_period(imf_fusion13_ahrs_t *self, imf_real sample_period)
    void imf_fusion13_ahrs_restart(imf_fusion13_ahrs_t *self)
    void imf_fusion13_ahrs_skip_startup(imf_fusion13_ahrs_t *self)
    void imf_fusion13_ahrs_update(imf_fusion13_ahrs_t *self, imf_real gx, imf_real gy,
                                  imf_real gz, imf_real ax, imf_real ay, imf_real az,
                                  imf_real mx, imf_real my, imf_real mz)
    void imf_fusion13_ahrs_update_no_magnetometer(imf_fusion13_ahrs_t *self, imf_real gx,
                                                  imf_real gy, imf_real gz, imf_real ax,
                                                  imf_real ay, imf_real az)
    void imf_fusion13_ahrs_update_external_heading(imf_fusion13_ahrs_t *self, imf_real gx,
                                                   imf_real gy, imf_real gz, imf_real ax,
                                                   imf_real ay, imf_real az, imf_real heading)
    void imf_fusion13_ahrs_set_heading(imf_fusion13_ahrs_t *self, imf_real heading)
    void imf_fusion13_ahrs_get_state(const imf_fusion13_ahrs_t *self, imf_real *out)
    void imf_fusion13_ahrs_set_state(imf_fusion13_ahrs_t *self, const imf_real *inp)
    void imf_fusion13_ahrs_outputs(const imf_fusion13_ahrs_t *self, imf_real *out)
    unsigned imf_fusion13_ahrs_flags(const imf_fusion13_ahrs_t *self)
    enum:
        IMF_FUSION13_AHRS_N_STATE

cdef extern from "fusion13_bias.h" nogil:
    ctypedef struct imf_fusion13_bias_settings_t:
        imf_real sample_rate
        imf_real stationary_threshold
        imf_real stationary_period
    ctypedef struct imf_fusion13_bias_t:
        uint32_t skipped
    void imf_fusion13_bias_init(imf_fusion13_bias_t *self,
                                const imf_fusion13_bias_settings_t *settings)
    void imf_fusion13_bias_set_settings(imf_fusion13_bias_t *self,
                                        const imf_fusion13_bias_settings_t *settings)
    void imf_fusion13_bias_update(imf_fusion13_bias_t *self, const imf_real *g, imf_real *out)
    void imf_fusion13_bias_get_state(const imf_fusion13_bias_t *self, imf_real *out)
    void imf_fusion13_bias_set_state(imf_fusion13_bias_t *self, const imf_real *inp)


cdef int _settings13_from(tuple a, imf_fusion13_ahrs_settings_t *st) except -1:
    st.sample_rate = <imf_real>a[0]
    st.convention = a[1]
    st.gain = <imf_real>a[2]
    st.gyroscope_range = <imf_real>a[3]
    st.acceleration_rejection = <imf_real>a[4]
    st.magnetic_rejection = <imf_real>a[5]
    st.rejection_timeout = <imf_real>a[6]
    return 0


cdef class FusionAHRS13:
    cdef imf_fusion13_ahrs_t s
    cdef tuple _args
    cdef _StateOut _out
    cdef int _busy          # run() in progress in some thread (_guard.pxi)
    _ref = _reference.FusionAHRS13
    dtype = DTYPE
    kind = "fusion"
    state_names = _fusion13.AHRS_STATE_NAMES
    __doc__ = _reference.FusionAHRS13.__doc__

    def __cinit__(self, *args, **kwargs):
        self._out = _StateOut(IMF_FUSION13_AHRS_N_STATE, _NATIVE)

    def __init__(self, *args, **kwargs):
        a = _reference.FusionAHRS13._params(*args, dtype=DTYPE, **kwargs)
        _idle(self._busy, self)
        self._args = a
        cdef imf_fusion13_ahrs_settings_t st
        _settings13_from(self._args, &st)
        imf_fusion13_ahrs_init(&self.s, &st, self._args[7])

    def restart(self):
        """Back to the initial state (identity, start-up), keeping the settings and the
        sample period (FusionAhrsRestart)."""
        _idle(self._busy, self)
        imf_fusion13_ahrs_restart(&self.s)

    reset = restart

    def skip_startup(self):
        """End start-up now (FusionAhrsSkipStartup)."""
        _idle(self._busy, self)
        imf_fusion13_ahrs_skip_startup(&self.s)

    def set_sample_period(self, dt):
        """The measured sample period (s) of the next updates (FusionAhrsSetSamplePeriod)."""
        cdef imf_real d = <imf_real>_fusion.check_dt_value(dt)
        _idle(self._busy, self)
        imf_fusion13_ahrs_set_sample_period(&self.s, d)

    def __reduce__(self):
        _idle(self._busy, self)
        raw = (<char *>&self.s)[:sizeof(self.s)]
        return (_empty, (type(self),), (self._args, raw))

    def __setstate__(self, st):
        args, raw = st
        if len(raw) != sizeof(self.s):
            raise ValueError("FusionAHRS13: pickled state of another build")
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
        """New settings (FusionAhrsSetSettings): the period becomes 1 / sample_rate."""
        _fusion13.check_settings(settings)
        cur = _fusion13.user_settings(self._args)
        cur.update(settings)
        new = _reference.FusionAHRS13._params(**cur, invsqrt=_fusion13.invsqrt_name(self._args[7]),
                                              dtype=DTYPE)
        cdef imf_fusion13_ahrs_settings_t st
        _settings13_from(new, &st)
        _idle(self._busy, self)
        self._args = new
        imf_fusion13_ahrs_set_settings(&self.s, &st)

    @property
    def skipped(self):
        _idle(self._busy, self)
        return self.s.skipped

    cdef int _period(self, dt) except -1:
        cdef imf_real d
        if dt is not None:
            d = <imf_real>_dt_value(dt)
            imf_fusion13_ahrs_set_sample_period(&self.s, d)
        return 0

    def update(self, gyr, acc, mag, dt=None):
        """One sample: gyr (deg/s), acc (g), mag (any unit); dt (s) set first if given."""
        cdef imf_real g[3]
        cdef imf_real a[3]
        cdef imf_real m[3]
        for name, v in (("gyr", gyr), ("acc", acc), ("mag", mag)):
            _checks.as_vec3(name, v)
        _vec3(gyr, g)
        _vec3(acc, a)
        _vec3(mag, m)
        _idle(self._busy, self)
        self._period(dt)
        imf_fusion13_ahrs_update(&self.s, g[0], g[1], g[2], a[0], a[1], a[2], m[0], m[1], m[2])

    def update_no_magnetometer(self, gyr, acc, dt=None):
        """One sample without magnetometer; heading held at 0 during start-up."""
        cdef imf_real g[3]
        cdef imf_real a[3]
        for name, v in (("gyr", gyr), ("acc", acc)):
            _checks.as_vec3(name, v)
        _vec3(gyr, g)
        _vec3(acc, a)
        _idle(self._busy, self)
        self._period(dt)
        imf_fusion13_ahrs_update_no_magnetometer(&self.s, g[0], g[1], g[2], a[0], a[1], a[2])

    def update_external_heading(self, gyr, acc, heading, dt=None):
        """One sample with a heading (degrees) from another source."""
        cdef imf_real g[3]
        cdef imf_real a[3]
        for name, v in (("gyr", gyr), ("acc", acc)):
            _checks.as_vec3(name, v)
        _vec3(gyr, g)
        _vec3(acc, a)
        cdef imf_real h = <imf_real>_fusion.check_scalar("heading", heading)
        _idle(self._busy, self)
        self._period(dt)
        imf_fusion13_ahrs_update_external_heading(&self.s, g[0], g[1], g[2], a[0], a[1], a[2], h)

    def set_heading(self, heading):
        """Rotate about the earth vertical so that the yaw is heading (degrees)."""
        h = _fusion.check_scalar("heading", heading)
        if not np.isfinite(h):
            raise ValueError(f"heading: must be finite, got {heading!r}")
        _idle(self._busy, self)
        imf_fusion13_ahrs_set_heading(&self.s, <imf_real>h)

    @property
    def state(self):
        out = self._out.take()
        _idle(self._busy, self)
        imf_fusion13_ahrs_get_state(&self.s, <imf_real *>cnp.PyArray_DATA(<cnp.ndarray>out))
        return out

    @state.setter
    def state(self, value):
        arr = _fusion13.ahrs_state(value, DTYPE, int(self._rejection_timeout()))
        cdef const imf_real[::1] v = arr
        _idle(self._busy, self)
        imf_fusion13_ahrs_set_state(&self.s, &v[0])

    def _rejection_timeout(self):
        a = self._args
        return int(np.asarray(a[0], dtype=DTYPE) * np.asarray(a[6], dtype=DTYPE))

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
        imf_fusion13_ahrs_set_state(&self.s, &v[0])

    def outputs(self):
        """The outputs now (see imufuse.reference.FusionAHRS13.outputs)."""
        out = np.empty(IMF_FUSION_N_OUT, dtype=DTYPE)
        cdef imf_real[::1] o = out
        _idle(self._busy, self)
        imf_fusion13_ahrs_outputs(&self.s, &o[0])
        return _fusion.pack_one(out, imf_fusion13_ahrs_flags(&self.s))

    def outputs_batch(self, states):
        """outputs() for every row of a run() result, without a Python loop."""
        arr = _fusion13.states_array(states, DTYPE)
        cdef Py_ssize_t n = arr.shape[0], k
        out = np.empty((n, IMF_FUSION_N_OUT), dtype=DTYPE)
        flags = np.empty(n, dtype=np.uint32)
        cdef const imf_real[:, ::1] st = arr
        cdef imf_real[:, ::1] o = out
        cdef uint32_t[::1] fl = flags
        _idle(self._busy, self)
        cdef imf_fusion13_ahrs_t tmp = self.s
        with nogil:
            for k in range(n):
                imf_fusion13_ahrs_set_state(&tmp, &st[k, 0])
                imf_fusion13_ahrs_outputs(&tmp, &o[k, 0])
                fl[k] = imf_fusion13_ahrs_flags(&tmp)
        return _fusion.pack_outputs(out, flags)

    def run(self, gyr, acc, mag=None, *, dt=None, heading=None):
        """All samples (see imufuse.reference.FusionAHRS13.run); (N, 23) states."""
        _claim(&self._busy, self)
        try:
            return self._run(gyr, acc, mag, dt, heading)
        finally:
            self._busy = 0

    cdef object _run(self, gyr, acc, mag, dt, heading):
        g_a, a_a, m_a, h_a, d_a = _fusion13.run_arrays(DTYPE, gyr, acc, mag, heading, dt)
        cdef Py_ssize_t n = g_a.shape[0], k
        cdef int mode = 0 if m_a is not None else (1 if h_a is not None else 2)
        cdef int has_dt = d_a is not None
        out = np.empty((n, IMF_FUSION13_AHRS_N_STATE), dtype=DTYPE)
        z = np.zeros(n, dtype=DTYPE)
        cdef const imf_real[:, ::1] g = g_a
        cdef const imf_real[:, ::1] a = a_a
        cdef const imf_real[:, ::1] m = m_a if m_a is not None else g_a
        cdef const imf_real[::1] h = h_a if h_a is not None else z
        cdef const imf_real[::1] d = d_a if d_a is not None else z
        cdef imf_real[:, ::1] o = out
        with nogil:
            for k in range(n):
                if has_dt:
                    imf_fusion13_ahrs_set_sample_period(&self.s, d[k])
                if mode == 0:
                    imf_fusion13_ahrs_update(&self.s, g[k, 0], g[k, 1], g[k, 2], a[k, 0],
                                             a[k, 1], a[k, 2], m[k, 0], m[k, 1], m[k, 2])
                elif mode == 1:
                    imf_fusion13_ahrs_update_external_heading(&self.s, g[k, 0], g[k, 1],
                                                              g[k, 2], a[k, 0], a[k, 1],
                                                              a[k, 2], h[k])
                else:
                    imf_fusion13_ahrs_update_no_magnetometer(&self.s, g[k, 0], g[k, 1],
                                                             g[k, 2], a[k, 0], a[k, 1], a[k, 2])
                imf_fusion13_ahrs_get_state(&self.s, &o[k, 0])
        return out

    def __repr__(self):
        return f"<imufuse_c FusionAHRS13 dtype={DTYPE}>"


cdef int _bias_settings_from(tuple a, imf_fusion13_bias_settings_t *st) except -1:
    st.sample_rate = <imf_real>a[0]
    st.stationary_threshold = <imf_real>a[1]
    st.stationary_period = <imf_real>a[2]
    return 0


cdef class FusionBias:
    cdef imf_fusion13_bias_t s
    cdef tuple _args
    cdef _StateOut _out
    cdef int _busy          # run() in progress in some thread (_guard.pxi)
    _ref = _reference.FusionBias
    dtype = DTYPE
    kind = "fusion_bias"
    state_names = _fusion13.BIAS_STATE_NAMES
    __doc__ = _reference.FusionBias.__doc__

    def __cinit__(self, *args, **kwargs):
        self._out = _StateOut(4, _NATIVE)

    def __init__(self, sample_rate=100.0, stationary_threshold=3.0, stationary_period=3.0):
        a = _reference.FusionBias._params(sample_rate, stationary_threshold, stationary_period,
                                          dtype=DTYPE)
        _idle(self._busy, self)
        self._args = a
        self.reset()

    def reset(self):
        """Settings applied, timer and offset zero (FusionBiasInitialise)."""
        cdef imf_fusion13_bias_settings_t st
        _bias_settings_from(self._args, &st)
        _idle(self._busy, self)
        imf_fusion13_bias_init(&self.s, &st)

    def set_settings(self, **settings):
        """New settings (FusionBiasSetSettings): the timer and the offset are kept."""
        cur = dict(zip(("sample_rate", "stationary_threshold", "stationary_period"), self._args))
        for k in settings:
            if k not in cur:
                raise ValueError(f"{k}: not a setting of FusionBias; set_settings changes "
                                 f"{', '.join(cur)}")
        cur.update(settings)
        new = _reference.FusionBias._params(**cur, dtype=DTYPE)
        cdef imf_fusion13_bias_settings_t st
        _bias_settings_from(new, &st)
        _idle(self._busy, self)
        self._args = new
        imf_fusion13_bias_set_settings(&self.s, &st)

    def __reduce__(self):
        _idle(self._busy, self)
        raw = (<char *>&self.s)[:sizeof(self.s)]
        return (_empty, (type(self),), (self._args, raw))

    def __setstate__(self, st):
        args, raw = st
        if len(raw) != sizeof(self.s):
            raise ValueError("FusionBias: pickled state of another build")
        _idle(self._busy, self)
        self._args = args
        memcpy(&self.s, <const char *>raw, sizeof(self.s))

    @property
    def skipped(self):
        _idle(self._busy, self)
        return self.s.skipped

    def update(self, gyr):
        cdef imf_real g[3]
        _checks.as_vec3("gyr", gyr)
        _vec3(gyr, g)
        out = np.empty(3, dtype=DTYPE)
        cdef imf_real[::1] o = out
        _idle(self._busy, self)
        imf_fusion13_bias_update(&self.s, g, &o[0])
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
                imf_fusion13_bias_update(&self.s, &g[k, 0], &o[k, 0])
                imf_fusion13_bias_get_state(&self.s, &s[k, 0])
        return out, st

    @property
    def offset(self):
        """The gyroscope offset (deg/s), FusionBiasGetOffset; settable (FusionBiasSetOffset)."""
        return self.state[:3].copy()

    @offset.setter
    def offset(self, value):
        v = _fusion.model_param("offset", value, (3,), DTYPE)
        st = self.state
        st[:3] = v
        cdef const imf_real[::1] sv = st
        _idle(self._busy, self)
        imf_fusion13_bias_set_state(&self.s, &sv[0])

    @property
    def state(self):
        out = self._out.take()
        _idle(self._busy, self)
        imf_fusion13_bias_get_state(&self.s, <imf_real *>cnp.PyArray_DATA(<cnp.ndarray>out))
        return out

    @state.setter
    def state(self, value):
        arr = _checks.as_state(value, 4, DTYPE, self.state_names)
        ref = _reference.FusionBias(*self._args, dtype=DTYPE)
        ref.state = arr                 # the one check of the timer's range
        cdef const imf_real[::1] v = arr
        _idle(self._busy, self)
        imf_fusion13_bias_set_state(&self.s, &v[0])

    def __repr__(self):
        return f"<imufuse_c FusionBias dtype={DTYPE}>"


def fusion_remap(x, alignment):
    """FusionRemap (see imufuse.reference.fusion13.remap): one of the 24 alignments."""
    perm, neg = _fusion13.remap_alignment(alignment)
    return fusion_axes_apply(x, "".join(("-" if neg[i] else "+") + "XYZ"[perm[i]]
                                        for i in range(3)))


def fusion_model_inertial(x, misalignment=None, sensitivity=None, offset=None):
    """FusionModelInertial (see imufuse.reference.fusion13.model_inertial)."""
    return fusion_calibrate_inertial(x, np.eye(3) if misalignment is None else misalignment,
                                     np.ones(3) if sensitivity is None else sensitivity,
                                     np.zeros(3) if offset is None else offset)


def fusion_model_magnetic(x, soft_iron_matrix=None, hard_iron_offset=None):
    """FusionModelMagnetic (see imufuse.reference.fusion13.model_magnetic)."""
    return fusion_calibrate_magnetic(x, np.eye(3) if soft_iron_matrix is None else
                                     soft_iron_matrix,
                                     np.zeros(3) if hard_iron_offset is None else
                                     hard_iron_offset)
