"""Orientation errors against a reference, as the BROAD benchmark defines them.

D. Laidig, M. Caruso, A. Cereatti, T. Seel. BROAD - A Benchmark for Robust
Inertial Orientation Estimation. Data 6(7), 2021. doi:10.3390/data6070072

Both orientations are brought to one earth frame, ENU, as sensor-to-earth unit
quaternions [w, x, y, z]. With q the estimate and r the reference, the
earth-frame error quaternion is e = q (x) r^-1 and, per sample,

    total error        = 2 arccos(|e_w|)
    heading error      = 2 arctan(|e_z / e_w|)        (evaluated as 2 atan2(|e_z|, |e_w|))
    inclination error  = 2 arccos(sqrt(e_w^2 + e_z^2))

(heading and inclination are the twist about earth z and the swing of e).
Each is reported as an RMS in degrees over the samples that count: the
movement mask (when given) is true and the reference row is finite. Reference
rows with NaN are excluded and counted. A non-finite estimate in a counted
sample is counted too, and makes the RMS NaN (a broken filter is never hidden).

Frames. imufuse's filters use an NWU earth frame (x north, y west, z up).
NWU -> ENU is a rotation of +90 deg about z applied on the earth side:
q_ENU = z(+90 deg) (x) q_NWU. NED -> ENU is the 180 deg rotation about
(1, 1, 0)/sqrt(2) (x <-> y, z -> -z), also on the earth side. A quaternion
given earth-to-sensor is conjugated first.

Heading offset removal (option): the optical frame's north and the magnetic
north differ by a constant; with `remove_heading_offset=True` the circular
mean of the signed heading error (2 atan2(e_z, e_w), over the counted
samples) is removed on the earth side, e' = z(-offset) (x) e, before the
heading and total errors are taken (inclination does not change). The offset
is reported.

6-DOF (IMU) filters have no heading reference: compare them on inclination only.
"""
import math
from dataclasses import dataclass, field

import numpy as np

from .latency import estimate_latency  # noqa: F401  (documented here: imufuse.evaluation)
from .rotations import DIRECTIONS, quat_conj, quat_mul, quat_rows as _quats

FRAMES = ("NWU", "ENU", "NED")

_S = math.sqrt(0.5)
#: earth-side rotation taking a frame's coordinates to ENU coordinates
TO_ENU = {
    "ENU": np.array([1.0, 0.0, 0.0, 0.0]),
    "NWU": np.array([_S, 0.0, 0.0, _S]),        # +90 deg about z
    "NED": np.array([0.0, _S, _S, 0.0]),        # 180 deg about (1, 1, 0)/sqrt(2)
}

METRICS = ("total", "heading", "inclination")


def _check_frame(frame, name):
    if frame not in FRAMES:
        raise ValueError(f"{name}: must be one of {', '.join(FRAMES)}, got {frame!r}")


def to_enu(q, frame="NWU", direction="sensor-to-earth", what="frame"):
    """(N, 4) quaternions in `frame` (`direction` as given) -> sensor-to-ENU."""
    _check_frame(frame, what)
    if direction not in DIRECTIONS:
        raise ValueError(f"direction: must be one of {', '.join(DIRECTIONS)}, got {direction!r}")
    q = _quats(q, "q")
    if direction == "earth-to-sensor":
        q = quat_conj(q)
    return quat_mul(TO_ENU[frame], q)


def from_enu(q, frame="NWU", direction="sensor-to-earth"):
    """Inverse of to_enu: sensor-to-ENU quaternions -> `frame`, `direction`."""
    _check_frame(frame, "frame")
    if direction not in DIRECTIONS:
        raise ValueError(f"direction: must be one of {', '.join(DIRECTIONS)}, got {direction!r}")
    q = quat_mul(quat_conj(TO_ENU[frame]), _quats(q, "q"))
    return quat_conj(q) if direction == "earth-to-sensor" else q


def error_quaternion(q, r):
    """e = q (x) r^-1 (both sensor-to-earth in one earth frame), normalised."""
    q, r = _quats(q, "q"), _quats(r, "r")
    with np.errstate(invalid="ignore", divide="ignore"):
        q = q / np.linalg.norm(q, axis=1, keepdims=True)
        r = r / np.linalg.norm(r, axis=1, keepdims=True)
    return quat_mul(q, quat_conj(r))


def error_angles(e):
    """(total, heading, inclination) in radians, per sample, of error quaternions e."""
    e = _quats(e, "e")
    aw, az = np.abs(e[:, 0]), np.abs(e[:, 3])
    total = 2.0 * np.arccos(np.minimum(aw, 1.0))
    heading = 2.0 * np.arctan2(az, aw)
    inclination = 2.0 * np.arccos(np.minimum(np.sqrt(e[:, 0] ** 2 + e[:, 3] ** 2), 1.0))
    return total, heading, inclination


@dataclass
class Evaluation:
    """Errors of one estimate against one reference (degrees)."""
    total: float                    # RMS, deg
    heading: float
    inclination: float
    n: int                          # samples counted
    n_samples: int                  # samples in the log
    n_ref_nan: int                  # excluded: reference not finite or zero (within the mask)
    n_outside_mask: int             # excluded: movement mask false
    n_est_nan: int                  # counted samples whose estimate is not finite
    heading_offset: float = 0.0     # deg, removed from the heading (0 unless asked)
    per_sample: dict = field(default_factory=dict, repr=False)  # metric -> (N,) deg, NaN outside
    #: whether the estimate has a heading (imufuse.session sets False for 6-D and gravity-vector
    #: filters: their heading and total errors measure an unobserved yaw)
    has_heading: bool = True

    def rms(self, metric):
        return getattr(self, metric)

    @property
    def ok(self):
        """Something was evaluated and every counted estimate was finite."""
        return self.n > 0 and self.n_est_nan == 0

    def summary(self, heading=None):
        """One line of the errors. Without a heading (has_heading False, or heading=False: 6-D
        filters, gravity-vector filters) the inclination only: the heading and total errors
        would measure the unobserved yaw."""
        if heading is None:
            heading = self.has_heading
        if heading:
            s = (f"total {self.total:.3f}, heading {self.heading:.3f}, inclination "
                 f"{self.inclination:.3f} deg RMS over {self.n} of {self.n_samples} samples")
        else:
            s = (f"inclination {self.inclination:.3f} deg RMS over {self.n} of {self.n_samples} "
                 "samples")
        excl = []
        if self.n_outside_mask:
            excl.append(f"{self.n_outside_mask} outside the movement mask")
        if self.n_ref_nan:
            excl.append(f"{self.n_ref_nan} with a NaN reference")   # (or a zero one)
        if excl:
            s += f" ({', '.join(excl)} excluded)"
        if self.heading_offset and heading:
            s += f"; heading offset {self.heading_offset:.3f} deg removed"
        if self.n_est_nan:
            s += f"; {self.n_est_nan} non-finite estimates"
        if not heading:
            s += "; no heading or total error: the filter estimates no heading"
        return s


def _counted(q_ref, movement):
    """(movement mask, reference rows usable, samples outside the mask, masked-in samples
    with an unusable reference) of an (N, 4) reference."""
    n = len(q_ref)
    mask = np.ones(n, dtype=bool)
    if movement is not None:
        m = np.asarray(movement)
        if m.shape != (n,):
            raise ValueError(f"movement: expected shape ({n},), got {m.shape}")
        if m.dtype != bool:
            if not np.all(np.isin(m, (0, 1))):
                raise ValueError("movement: must be boolean (0/1) values")
            m = m.astype(bool)
        mask = m.copy()
    # a reference row is missing when it is not finite or is (near) zero: a zero row is the
    # "no tracking" marker of some systems and has no orientation; both are excluded and counted
    # (a row whose norm overflows has no orientation either)
    with np.errstate(all="ignore"):
        n2_ref = np.einsum("ij,ij->i", q_ref, q_ref)
        ref_ok = np.all(np.isfinite(q_ref), axis=1) & (n2_ref > 1e-12) & np.isfinite(n2_ref)
    n_outside = int(np.count_nonzero(~mask))
    n_ref_nan = int(np.count_nonzero(mask & ~ref_ok))
    return mask, ref_ok, n_outside, n_ref_nan


@dataclass
class Reference:
    """A log's reference prepared once for scoring many estimates in compiled code
    (imufuse_c's run_filters / run_many with score=): use, (N,) uint8, 1 where a sample counts;
    r, (N, 4) the reference sensor-to-ENU, unit (rows that do not count are zero). The counts
    are evaluate()'s. Made by prepare_reference."""
    use: np.ndarray
    r: np.ndarray
    n: int
    n_samples: int
    n_ref_nan: int
    n_outside_mask: int
    heading_offset: bool = False

    def sealed(self, n_log):
        """A private, read-only copy checked whole for a log of ``n_log`` samples: what the
        compiled scorer reads (run_filters(score=...)). ValueError/TypeError naming the
        field that does not hold: use (n_log,) of 0/1, r (n_log, 4) finite with unit rows
        (within 1e-6) where use is 1, n the number of 1s in use, n_samples == n_log."""
        use, r = self.use, self.r
        if (type(self) is _SealedReference and self.__dict__.get("_by") is _SEALER
                and self.n_samples == n_log and not use.flags.writeable
                and not r.flags.writeable and use.shape == (n_log,) and r.shape == (n_log, 4)
                and use.dtype == np.uint8 and r.dtype == np.float64
                and use.flags.c_contiguous and r.flags.c_contiguous):
            # sealed already: read-only, of its length (an owner may resize a read-only array)
            return self
        if not isinstance(use, np.ndarray) or not isinstance(r, np.ndarray):
            bad = "use" if not isinstance(use, np.ndarray) else "r"
            raise TypeError(f"score: Reference.{bad} must be a numpy array (prepare_reference "
                            f"makes it), got {type(getattr(self, bad)).__name__}")
        if use.ndim == 1 and len(use) != n_log:
            raise ValueError(f"score: a reference of {len(use)} samples for a log of {n_log}")
        if use.shape != (n_log,) or use.dtype.kind not in "biu":
            raise ValueError(f"score: Reference.use must be ({n_log},) of 0/1 for a log of "
                             f"{n_log} samples, got {use.dtype} {use.shape}")
        if r.shape != (n_log, 4) or r.dtype.kind != "f":
            raise ValueError(f"score: Reference.r must be ({n_log}, 4) floats for a log of "
                             f"{n_log} samples, got {r.dtype} {r.shape}")
        if not np.all((use == 0) | (use == 1)):
            raise ValueError("score: Reference.use must hold 0 or 1 only")
        u = np.array(use, dtype=np.uint8, order="C")
        rr = np.array(r, dtype=np.float64, order="C")
        on = u.astype(bool)
        count = int(np.count_nonzero(on))
        with np.errstate(all="ignore"):
            norm = np.sqrt(np.einsum("ij,ij->i", rr[on], rr[on]))
        if not (np.all(np.isfinite(rr)) and np.all(np.abs(norm - 1.0) <= 1e-6)):
            raise ValueError("score: Reference.r must be finite, with unit rows where use is 1 "
                             "(prepare_reference makes it)")
        for field_ in ("n", "n_samples", "n_ref_nan", "n_outside_mask"):
            v = getattr(self, field_)
            if type(v) is not int or v < 0:
                raise (TypeError if type(v) is not int else ValueError)(
                    f"score: Reference.{field_} must be an int >= 0, got {v!r}")
        if self.n != count:
            raise ValueError(f"score: Reference.n is {self.n} but use counts {count} samples "
                             "(a Reference changed after prepare_reference?)")
        if self.n_samples != n_log:
            raise ValueError(f"score: a reference of {self.n_samples} samples for a log of "
                             f"{n_log}")
        u.flags.writeable = rr.flags.writeable = False
        out = object.__new__(_SealedReference)     # (its __setattr__ refuses every write)
        out.__dict__.update(use=u, r=rr, n=count, n_samples=n_log, n_ref_nan=self.n_ref_nan,
                            n_outside_mask=self.n_outside_mask,
                            heading_offset=bool(self.heading_offset), _by=_SEALER)
        return out

    def finish(self, sq_total, sq_heading, sq_inclination, n_est_nan, stored=None,
               has_heading=True):
        """The Evaluation of one estimate from the compiled scorer's sums (or, with the
        heading offset removed, from its stored e_w, e_z, finite flags: the offset and the
        errors are then taken here, as evaluate() takes them)."""
        cnt, offset = self.n, 0.0
        if stored is not None:
            ew, ez, ok = stored
            ok = ok.astype(bool)
            if np.any(ok):
                psi = 2.0 * np.arctan2(ez[ok], ew[ok])
                offset = math.atan2(float(np.sum(np.sin(psi))), float(np.sum(np.cos(psi))))
                c, s = math.cos(offset / 2), -math.sin(offset / 2)
                ew, ez = c * ew - s * ez, c * ez + s * ew     # z(-offset) (x) e, w and z
            aw, az = np.abs(ew), np.abs(ez)
            angles = (2.0 * np.arccos(np.minimum(aw, 1.0)), 2.0 * np.arctan2(az, aw),
                      2.0 * np.arccos(np.minimum(np.sqrt(ew ** 2 + ez ** 2), 1.0)))
            sq_total, sq_heading, sq_inclination = (float(np.dot(np.degrees(a), np.degrees(a)))
                                                    for a in angles)
        rms = [math.sqrt(v / cnt) if cnt else math.nan
               for v in (sq_total, sq_heading, sq_inclination)]
        return Evaluation(total=rms[0], heading=rms[1], inclination=rms[2], n=cnt,
                          n_samples=self.n_samples, n_ref_nan=self.n_ref_nan,
                          n_outside_mask=self.n_outside_mask, n_est_nan=int(n_est_nan),
                          heading_offset=math.degrees(offset), has_heading=has_heading)



_SEALER = object()      # marks the copies Reference.sealed made


class _SealedReference(Reference):
    """Reference.sealed's copy: fields fixed, arrays read-only; sealed again for its log, itself."""

    def __init__(self, **fields):
        # dataclasses.replace: a copy with other fields, checked whole when it is sealed
        self.__dict__.update(fields)

    def __setattr__(self, name, value):
        raise AttributeError(f"a sealed Reference cannot change ({name}): seal the original again")


def prepare_reference(q_ref, *, ref_frame="ENU", ref_direction="sensor-to-earth",
                      movement=None, remove_heading_offset=False):
    """The Reference of evaluate(q_est, q_ref, est_frame="NWU", ...)'s other arguments, for
    scoring estimates in compiled code."""
    q_ref = _quats(q_ref, "q_ref")
    _check_frame(ref_frame, "ref_frame")
    if ref_direction not in DIRECTIONS:
        raise ValueError(f"direction: must be one of {', '.join(DIRECTIONS)}, "
                         f"got {ref_direction!r}")
    mask, ref_ok, n_outside, n_ref_nan = _counted(q_ref, movement)
    use = mask & ref_ok
    r = np.zeros((len(q_ref), 4))
    if np.any(use):
        rr = to_enu(q_ref[use], ref_frame, ref_direction, "ref_frame")
        r[use] = rr / np.linalg.norm(rr, axis=1, keepdims=True)
    return Reference(use=use.astype(np.uint8), r=np.ascontiguousarray(r),
                     n=int(np.count_nonzero(use)), n_samples=len(q_ref), n_ref_nan=n_ref_nan,
                     n_outside_mask=n_outside, heading_offset=bool(remove_heading_offset))


def evaluate(q_est, q_ref, *, est_frame="NWU", ref_frame="ENU",
             est_direction="sensor-to-earth", ref_direction="sensor-to-earth",
             movement=None, remove_heading_offset=False, per_sample=True, chunk=1 << 16):
    """BROAD errors of estimate `q_est` against reference `q_ref` ((N, 4) each).

    movement: optional (N,) bool mask of the samples that count (BROAD's
    movement phases). per_sample: keep the per-sample errors (Evaluation.
    per_sample, deg, NaN outside); False keeps the RMS only. The work is done
    in blocks of `chunk` samples, so memory stays small for long logs.
    Returns an Evaluation; `n == 0` means nothing could be evaluated (the
    caller decides whether that is an error)."""
    q_est, q_ref = _quats(q_est, "q_est"), _quats(q_ref, "q_ref")
    if len(q_est) != len(q_ref):
        raise ValueError(f"q_est and q_ref: different lengths ({len(q_est)} and {len(q_ref)})")
    for f, d, what in ((est_frame, est_direction, "est_frame"),
                       (ref_frame, ref_direction, "ref_frame")):
        _check_frame(f, what)
        if d not in DIRECTIONS:
            raise ValueError(f"direction: must be one of {', '.join(DIRECTIONS)}, got {d!r}")
    n = len(q_est)
    mask, ref_ok, n_outside, n_ref_nan = _counted(q_ref, movement)
    with np.errstate(all="ignore"):
        n2_est = np.einsum("ij,ij->i", q_est, q_est)
        est_ok = np.all(np.isfinite(q_est), axis=1) & (n2_est > 1e-12) & np.isfinite(n2_est)
    use = mask & ref_ok
    n_est_nan = int(np.count_nonzero(use & ~est_ok))
    idx = np.flatnonzero(use)

    def blocks():
        """(indices, e) of the counted samples, block by block."""
        for k in range(0, len(idx), chunk):
            i = idx[k:k + chunk]
            q = to_enu(q_est[i], est_frame, est_direction, "est_frame")
            r = to_enu(q_ref[i], ref_frame, ref_direction, "ref_frame")
            yield i, error_quaternion(q, r)

    offset = 0.0
    z = None
    if remove_heading_offset:
        ss = cc = 0.0
        for i, e in blocks():
            ok = est_ok[i]
            psi = 2.0 * np.arctan2(e[ok, 3], e[ok, 0])
            ss += float(np.sum(np.sin(psi)))
            cc += float(np.sum(np.cos(psi)))
        if np.any(use & est_ok):
            offset = math.atan2(ss, cc)
            z = np.array([math.cos(offset / 2), 0.0, 0.0, -math.sin(offset / 2)])
    per = {m: np.full(n, np.nan) for m in METRICS} if per_sample else {}
    sq = dict.fromkeys(METRICS, 0.0)
    for i, e in blocks():
        if z is not None:
            e = quat_mul(z, e)
        for name, a in zip(METRICS, error_angles(e)):
            d = np.degrees(a)
            sq[name] += float(np.dot(d, d))
            if per_sample:
                per[name][i] = d
    cnt = len(idx)
    rms = {m: (math.sqrt(sq[m] / cnt) if cnt else math.nan) for m in METRICS}
    return Evaluation(total=rms["total"], heading=rms["heading"], inclination=rms["inclination"],
                      n=cnt, n_samples=n, n_ref_nan=n_ref_nan,
                      n_outside_mask=n_outside, n_est_nan=n_est_nan,
                      heading_offset=math.degrees(offset), per_sample=per)


def mean_over_trials(evaluations):
    """{metric: mean of the per-trial RMS} (BROAD averages the trials' RMS values).
    Trials that evaluated nothing are left out; NaN if none is left."""
    ev = [e for e in evaluations if e.n > 0]
    return {m: (float(np.mean([getattr(e, m) for e in ev])) if ev else math.nan)
            for m in METRICS}

