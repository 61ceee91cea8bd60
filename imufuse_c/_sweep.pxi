# run_filters / run_many: many parameter sets of one 3-D filter over one log in one call,
# without the GIL, scored while they run (imufuse_c/host/lanes.h). Included by _base.pxi.
#
# A group of up to `width` filters of one class runs side by side in SIMD lanes when the
# class has a lane kernel (each lane bit for bit its filter's own update); otherwise, and
# with lanes=0, each filter runs its own C update, sample by sample. Either way every
# filter ends exactly where its own run() would: same trajectory, same state, same
# `skipped`. Groups run in threads.
from cpython.mem cimport PyMem_Free, PyMem_Malloc

import concurrent.futures as _cf
import os as _os

from imufuse import evaluation as _evaluation

_ADAPTER = {"quaternion": 0, "matrix": 1, "gravity": 2, "euler": 3}


def lane_widths():
    """{width: instruction set} of the lane kernels this CPU runs, widest first (1 is the
    kernels' one-lane build; run_filters(lanes=0) runs each filter's own update)."""
    cdef int best = imf_lanes_best()
    return {w: imf_lanes_isa(w).decode() for w in (8, 4, 2, 1) if w <= best}


def has_lanes(cls):
    """Whether filter class ``cls`` (a compiled class of this precision) has a lane kernel."""
    return imf_lanes_kernel(cls._ref.c_update.encode(), 1) != NULL


cdef inline const imf_real *_ptr(object arr):
    return NULL if arr is None else <const imf_real *>cnp.PyArray_DATA(<cnp.ndarray>arr)


cdef void _sweep(_Filter f, Py_ssize_t k0, Py_ssize_t k1, const imf_real *g, const imf_real *a,
                 const imf_real *m, const imf_real *d, const imf_scorer_t *sc,
                 imf_score_acc_t *acc, imf_real *out, int adapter, const int *idx,
                 double *buf) noexcept nogil:
    """Samples k0..k1 of one filter by its own update (the path of its run())."""
    cdef Py_ssize_t k, j, n = f._n
    cdef const imf_real *x = <const imf_real *>f._x
    cdef double q[4]
    for k in range(k0, k1):
        if d != NULL:
            f._set_dt(d[k])
        f._step3(g + 3 * k, a + 3 * k, (m + 3 * k) if m != NULL else g)
        if out != NULL:
            _copy_state(out + k * n, f._x, n)
        if sc != NULL:
            for j in range(n):
                buf[j] = x[j]
            imf_estimate_q(adapter, buf, idx, q)
            imf_score_q(sc, acc, k, q)


cdef Py_ssize_t _start(_Filter f, Py_ssize_t n_samples, const imf_real *g, const imf_real *a,
                       const imf_real *m, const imf_scorer_t *sc, imf_score_acc_t *acc,
                       imf_real *out, int adapter, const int *idx,
                       double *buf) noexcept nogil:
    """A pending init="first": the window samples as run() takes them; returns the first
    sample after it."""
    cdef Py_ssize_t k = 0, j, n = f._n
    cdef const imf_real *x = <const imf_real *>f._x
    cdef imf_real z3[3]
    cdef double q[4]
    z3[0] = 0
    z3[1] = 0
    z3[2] = 0
    while k < n_samples and f._pending:
        f._first(g + 3 * k, a + 3 * k, (m + 3 * k) if m != NULL else z3)
        if out != NULL:
            _copy_state(out + k * n, f._x, n)
        if sc != NULL:
            for j in range(n):
                buf[j] = x[j]
            imf_estimate_q(adapter, buf, idx, q)
            imf_score_q(sc, acc, k, q)
        k += 1
    return k


def _adapter(cls):
    """(adapter code, state indices, has heading) of the estimate of class cls."""
    names = tuple(cls._ref.state_names)
    key = _estimate.detect(names)
    if key is None:
        raise ValueError(f"score: {cls.__name__} has no orientation in its state")
    idx = [-1] * 9
    heading = cls._ref.kind == "ahrs"
    if key == "quaternion":
        idx[:4] = range(4)
    elif key == "matrix":
        idx[:9] = range(9)
    elif key == "gravity":
        idx[:3] = range(3)
        heading = False
    else:
        for r, p, y in (("roll", "pitch", "yaw"), ("phi", "theta", "psi")):
            if r in names and p in names:
                idx[:3] = [names.index(r), names.index(p), names.index(y) if y in names else -1]
                heading = heading and y in names
                break
    return _ADAPTER[key], np.asarray(idx, dtype=np.intc), heading


cdef tuple _run_group(list filters, tuple inputs, object dts, object ref, object traj,
                      int width):
    """One group of filters of one class over native (N, 3) inputs: trajectories into
    traj[i] (or None), scores against ref (an evaluation.Reference, or None). Returns the
    per-filter score sums (or Nones). Only run_filters calls it, its filters claimed."""
    cdef int p = len(filters), i, ran = 0
    cdef _Filter f0 = filters[0], f
    cdef Py_ssize_t N = cnp.PyArray_DIM(<cnp.ndarray>inputs[0], 0), kmax = 0, k
    cdef int n = f0._n
    cdef const imf_real *g = _ptr(inputs[0])
    cdef const imf_real *a = _ptr(inputs[1])
    cdef const imf_real *m = _ptr(inputs[2]) if len(inputs) == 3 else NULL
    cdef const imf_real *d = _ptr(dts)
    cdef imf_scorer_t sc
    cdef imf_scorer_t *scp = NULL
    cdef int adapter = 0
    cdef const int *idx = NULL
    cdef imf_lanes_fn kernel = NULL
    cdef imf_score_acc_t *accs = <imf_score_acc_t *>PyMem_Malloc(p * sizeof(imf_score_acc_t))
    cdef imf_real **outs = <imf_real **>PyMem_Malloc(p * sizeof(imf_real *))
    cdef void **ptrs = <void **>PyMem_Malloc(p * sizeof(void *))
    cdef Py_ssize_t *k0 = <Py_ssize_t *>PyMem_Malloc(p * sizeof(Py_ssize_t))
    cdef double *buf = <double *>PyMem_Malloc(max(n, 9) * sizeof(double))
    if accs == NULL or outs == NULL or ptrs == NULL or k0 == NULL or buf == NULL:
        PyMem_Free(accs)
        PyMem_Free(outs)
        PyMem_Free(ptrs)
        PyMem_Free(k0)
        PyMem_Free(buf)
        raise MemoryError()
    stores = []
    try:
        if ref is not None:
            code, idx_a, _ = _adapter(type(f0))
            adapter = code
            idx = <const int *>cnp.PyArray_DATA(<cnp.ndarray>idx_a)
            sc.use = <const unsigned char *>cnp.PyArray_DATA(<cnp.ndarray>ref.use)
            sc.r = <const double *>cnp.PyArray_DATA(<cnp.ndarray>ref.r)
            sc.store = 1 if ref.heading_offset else 0
            scp = &sc
        for i in range(p):
            f = filters[i]
            if f._x == NULL:
                _unbound(f)
            ptrs[i] = f._whole
            outs[i] = NULL if traj is None else <imf_real *>cnp.PyArray_DATA(<cnp.ndarray>traj[i])
            accs[i].sq[0] = accs[i].sq[1] = accs[i].sq[2] = 0.0
            accs[i].n_est_nan = 0.0
            accs[i].j = 0
            accs[i].ew = accs[i].ez = NULL
            accs[i].ok = NULL
            if scp != NULL and sc.store:
                st = (np.empty(ref.n), np.empty(ref.n), np.empty(ref.n, dtype=np.uint8))
                stores.append(st)
                accs[i].ew = <double *>cnp.PyArray_DATA(<cnp.ndarray>st[0])
                accs[i].ez = <double *>cnp.PyArray_DATA(<cnp.ndarray>st[1])
                accs[i].ok = <unsigned char *>cnp.PyArray_DATA(<cnp.ndarray>st[2])
        if width > 0 and all((<_Filter>f)._whole != NULL for f in filters):
            kernel = imf_lanes_kernel(type(f0)._ref.c_update.encode(), width)
        # a pending init="first" window, filter by filter, then each on its own to the
        # latest start of the group
        for i in range(p):
            f = filters[i]
            with nogil:
                k0[i] = _start(f, N, g, a, m, scp, &accs[i], outs[i], adapter, idx, buf)
                if k0[i] > kmax:
                    kmax = k0[i]
        for i in range(p):
            f = filters[i]
            with nogil:
                _sweep(f, k0[i], kmax, g, a, m, d, scp, &accs[i], outs[i], adapter, idx, buf)
        if kernel != NULL:
            with nogil:
                ran = kernel(ptrs, p, kmax, N, g, a, m, d, scp, accs,
                             outs if traj is not None else NULL)
        if not ran:
            for i in range(p):
                f = filters[i]
                with nogil:
                    _sweep(f, kmax, N, g, a, m, d, scp, &accs[i], outs[i], adapter, idx, buf)
        if d != NULL:
            for i in range(p):
                f = filters[i]
                f._set_dt(f._dt0)
        if scp == NULL:
            return [None] * p, bool(ran)
        return [(accs[i].sq[0], accs[i].sq[1], accs[i].sq[2], int(accs[i].n_est_nan),
                 stores[i] if stores else None) for i in range(p)], bool(ran)
    finally:
        PyMem_Free(accs)
        PyMem_Free(outs)
        PyMem_Free(ptrs)
        PyMem_Free(k0)
        PyMem_Free(buf)


def _run_many(cls, params, inputs, dt, score, outputs, lanes, threads):
    """cls.run_many: one filter per parameter set (each validated as its constructor
    validates it), then run_filters."""
    filters = []
    for i, p in enumerate(params):
        try:
            filters.append(cls(**dict(p)))
        except (TypeError, ValueError) as e:
            raise type(e)(f"parameter set {i} ({dict(p)}): {e}") from None
    return run_filters(filters, *inputs, dt=dt, score=score, outputs=outputs, lanes=lanes,
                       threads=threads)


def _groups(int p, int width):
    """p sets in groups of at most width, as even as possible: [(start, stop), ...]."""
    if width <= 1:
        return [(i, i + 1) for i in range(p)]
    count = -(-p // width)
    base, extra = divmod(p, count)
    out, start = [], 0
    for j in range(count):
        stop = start + base + (1 if j < extra else 0)
        out.append((start, stop))
        start = stop
    return out


def _check_distinct(filters):
    """Every entry its own object: one C state updated by two lanes or two threads at once
    is a data race, and each entry is left as its own run() leaves it."""
    seen = {}
    for i, f in enumerate(filters):
        j = seen.setdefault(id(f), i)
        if j != i:
            raise ValueError(f"run_filters: filters[{j}] and filters[{i}] are the same object; "
                             "each entry runs from its own state and is left as its own run() "
                             "leaves it: give distinct filters ([copy.copy(f) for _ in "
                             "range(n)])")


cdef int _claim_all(list filters) except -1:
    """Claim every filter (_guard.pxi) before any work starts: if one is in use by another
    thread, those already claimed are released and the RuntimeError raised."""
    cdef Py_ssize_t i, j
    cdef _Filter f
    for i in range(len(filters)):
        f = filters[i]
        try:
            _claim(&f._busy, f)
        except RuntimeError:
            for j in range(i):
                (<_Filter>filters[j])._busy = 0
            raise
    return 0


def _check_threads(threads):
    if threads is None:
        return None
    if type(threads) is not int or threads < 1:
        raise TypeError(f"threads: a positive int or None (one per core), got {threads!r}")
    return threads


def _sealed_reference(score, Py_ssize_t N):
    """The score= argument checked whole before C reads it: an imufuse.evaluation.Reference
    (made by prepare_reference) of this log's N samples, its arrays of the types, shapes
    and contents the scorer reads (anything else is refused by type or by name)."""
    if not isinstance(score, _evaluation.Reference):
        raise TypeError(f"score: an imufuse.evaluation.Reference (prepare_reference), got "
                        f"{type(score).__name__}")
    return score.sealed(N)


def run_filters(filters, *inputs, dt=None, score=None, outputs="state", lanes=None,
                threads=None):
    """Run ``filters`` (instances of one 3-D filter class of this precision, each as it
    stands: its settings, its state, a pending init="first") over one log in one call.

    inputs: gyr, acc (and mag for AHRS filters), (N, 3); dt: None or the (N,) sample
    periods. Without ``score``: a (P, N, len(state)) array (outputs="state"), or (P, N, 4)
    quaternions (outputs="q"); row i is bit for bit filters[i].run(*inputs, dt=dt), and each
    filter is left as its run() leaves it. With ``score`` (an
    imufuse.evaluation.Reference of this log): no trajectory is kept; returns one
    imufuse.evaluation.Evaluation per filter, the BROAD errors computed while it ran (within
    1e-12 of evaluate() on its run()'s estimate).

    lanes: None, the widest lane kernel this CPU runs (lane_widths()); 1, 2, 4 or 8, that
    width; 0, each filter's own update. Classes without a lane kernel run their own update.
    threads: groups run side by side in this many threads (None: one per core)."""
    filters = list(filters)
    if not filters:
        return [] if score is not None else np.empty((0, 0, 0), dtype=DTYPE)
    for i, f in enumerate(filters):
        if not isinstance(f, _Filter):
            raise TypeError(f"run_filters: filters[{i}] is {type(f).__module__}."
                            f"{type(f).__qualname__}, not a compiled {DTYPE} filter")
    cls = type(filters[0])
    if any(type(f) is not cls for f in filters):
        i = next(i for i, f in enumerate(filters) if type(f) is not cls)
        raise TypeError(f"run_filters: filters[0] is {cls.__name__} and filters[{i}] "
                        f"{type(filters[i]).__name__}: every filter must be of one class and "
                        "precision")
    _check_distinct(filters)
    threads = _check_threads(threads)
    if cls._ref.kind not in ("imu", "ahrs"):
        raise TypeError(f"run_filters: {cls.__name__} is not a 3-D filter")
    if outputs not in _estimate.OUTPUTS:
        raise ValueError(f"outputs: must be one of {', '.join(map(repr, _estimate.OUTPUTS))}, "
                         f"got {outputs!r}")
    _claim_all(filters)     # one state, one thread: released when the call returns
    try:
        arrays = tuple(_checks.run_inputs(cls._ref.kind, DTYPE, inputs))
        N = arrays[0].shape[0]
        dts = None if dt is None else _checks.dt_array(dt, N, DTYPE)
        best = imf_lanes_best()
        if lanes is None:
            width = best if has_lanes(cls) else 0
        else:
            if type(lanes) is not int or lanes not in (0, 1, 2, 4, 8) or lanes > best:
                raise ValueError(f"lanes: one of 0 (each filter's own update) or "
                                 f"{', '.join(map(str, lane_widths()))} on this CPU, "
                                 f"got {lanes!r}")
            width = lanes
        heading = None
        if score is not None:
            score = _sealed_reference(score, N)
            _, _, heading = _adapter(cls)
        P = len(filters)
        traj = None
        if score is None:
            traj = np.empty((P, N, len(cls._ref.state_names)), dtype=DTYPE)
        groups = _groups(P, width if width > 0 and has_lanes(cls) else 1)

        def one(span):
            i, j = span
            return _run_group(filters[i:j], arrays, dts, score,
                              None if traj is None else traj[i:j], width)[0]
        workers = max(1, min(threads or _os.cpu_count() or 1, len(groups)))
        if workers == 1:
            res = [one(s) for s in groups]
        else:
            with _cf.ThreadPoolExecutor(max_workers=workers) as ex:
                res = list(ex.map(one, groups))
        sums = [r for part in res for r in part]
        if score is None:
            if outputs == "q":
                return np.stack([_estimate.run_outputs(f, t, "q")
                                 for f, t in zip(filters, traj)])
            return traj
        return [score.finish(*s, has_heading=heading) for s in sums]
    finally:
        for f in filters:
            (<_Filter>f)._busy = 0
