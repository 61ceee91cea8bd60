"""The firmware validation harness (imufuse.firmware): csrc compiled through
it is bit-exact; realistic firmware mistakes planted in copies of csrc are
reported with the right first diverging sample, which each test computes on
its own from a Python mirror of the mistaken code."""
import os
import shutil

import numpy as np
import pytest

import imufuse.reference as reference
from bits import ulps as bits_ulps
from imufuse.registry import FLOAT_CASES

from imufuse import sim
from imufuse.firmware import (Firmware, FirmwareError, compare_states, csrc_firmware,
                              parse_prototype, validate)

pytest.importorskip("cffi")

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CSRC = os.path.join(ROOT, "csrc")
F32 = np.float32


@pytest.fixture(scope="session", autouse=True)
def _cache(tmp_path_factory):
    """One build cache for the session (shared with test_cli's subprocesses)."""
    d = str(tmp_path_factory.getbasetemp() / "fw-cache")
    old = os.environ.get("IMUFUSE_CACHE")
    os.environ["IMUFUSE_CACHE"] = d
    yield d
    if old is None:
        del os.environ["IMUFUSE_CACHE"]
    else:
        os.environ["IMUFUSE_CACHE"] = old


def _inputs(kind, n=1500, seed=3, swing=False, rest=0):
    """Simulated fast motion; swing: the accelerometer's magnitude swung between 0.5 and
    1.5 g (a 3 s period), so that every magnitude gate and window is crossed both ways;
    rest: that many samples at rest first (the first reading held, a gyro bias of
    (2, -3, 4) deg/s and a little noise), then a third as many with the rate about z
    ramped from 0 to 12 deg/s, so that rest detection, the bias learnt at rest and the
    rest window's edge run too."""
    if kind == "1d":
        d = sim.axis1d("fast", rate=200.0, duration=n / 200.0, seed=seed)
        return d.gyr, d.acc_angle
    d = sim.imu("fast", rate=200.0, duration=n / 200.0, seed=seed)
    acc = d.acc
    if swing:
        acc = acc * (1.0 + 0.5 * np.sin(2 * np.pi * np.arange(n) / 600.0))[:, None]
    gyr, mag = d.gyr, d.mag
    if rest:
        m = rest + rest // 3
        still = np.radians([2.0, -3.0, 4.0]) + np.random.default_rng(seed).normal(0.0, 1e-3, (m, 3))
        still[rest:, 2] += np.radians(np.linspace(0.0, 12.0, m - rest))
        gyr = np.concatenate([still, gyr])
        acc = np.concatenate([np.repeat(acc[:1], m, axis=0), acc])
        mag = np.concatenate([np.repeat(mag[:1], m, axis=0), mag])
    return (gyr, acc) if kind == "imu" else (gyr, acc, mag)


def _first_diff(a, b):
    """Index of the first sample whose bit patterns differ (None if none): the
    test's own computation, independent of the harness."""
    u = {4: np.uint32, 8: np.uint64}[a.dtype.itemsize]
    rows = np.flatnonzero((a.view(u) != b.view(u)).any(axis=1))
    return int(rows[0]) if rows.size else None


def _planted(tmp_path, old, new, count=1):
    """A copy of csrc with `old` replaced by `new` (exactly `count` times)."""
    d = tmp_path / "csrc"
    shutil.copytree(CSRC, d)
    path = d / "filters_1d.c"
    text = path.read_text()
    assert text.count(old) == count, f"csrc changed: {old!r} found {text.count(old)} times"
    path.write_text(text.replace(old, new))
    return str(d)


# ---------------------------------------------------------------------------
# csrc through the harness

def _csrc_matrix():
    """float32 (the firmware precision) for every class, float64 for the first
    class of each C family (each build costs a compiler run)."""
    seen, families, out = set(), set(), []
    for c in FLOAT_CASES:
        if c.name in seen:
            continue
        seen.add(c.name)
        out.append(pytest.param(c, "float32", id=f"{c.name}-float32"))
        fam = getattr(reference, c.name).__module__
        if fam not in families:
            families.add(fam)
            out.append(pytest.param(c, "float64", id=f"{c.name}-float64"))
    return out


@pytest.mark.parametrize("case,dtype", _csrc_matrix())
def test_csrc_is_bit_exact(case, dtype):
    fw = csrc_firmware(case.name, CSRC, dtype)
    inputs = _inputs(case.kind, swing=True, rest=600)
    for backend in ("c", "ref"):
        v = validate(fw, case.name, case.params, inputs, backend=backend)
        assert v.comparison.dtype == dtype
        assert v.bit_exact, v.text()
        # and the firmware trajectory really is imufuse's, by the test's own comparison
        want = case.make(backend, dtype).run(*[np.asarray(a, dtype) for a in inputs])
        assert _first_diff(v.got, want) is None


def test_user_declaration_globals_and_dt_argument(tmp_path):
    """Firmware in the common MCU style: globals, its own names, dt per call."""
    src = tmp_path / "att.c"
    src.write_text("""
#include <math.h>
float att_theta;
static float att_k0, att_omk0;
void att_begin(float k0) { att_k0 = k0; att_omk0 = 1.0f - k0; att_theta = 0.0f; }
void att_step(float gyro, float acc_angle, float dt)
{
    float pred, th;
    if (!isfinite(gyro) || !isfinite(acc_angle)) return;
    pred = att_theta + gyro * dt;
    th = att_omk0 * pred + att_k0 * acc_angle;
    if (isfinite(th)) att_theta = th;
}
""")
    (tmp_path / "att.h").write_text("extern float att_theta;\nvoid att_begin(float k0);\n"
                                    "void att_step(float gyro, float acc_angle, float dt);\n")
    fw = Firmware([str(src)], headers=["att.h"], include_dirs=[str(tmp_path)],
                  init="att_begin", update="att_step", state={"theta": "att_theta"})
    inputs = list(_inputs("1d", n=600))
    inputs[0][100] = np.nan                       # the skip policy agrees too
    v = validate(fw, "Kalman1D", dict(dt=0.005, k0=0.02), inputs)
    assert v.bit_exact, v.text()
    assert v.comparison.dtype == "float32"


def test_declaration_errors(tmp_path):
    with pytest.raises(FirmwareError, match="not found"):
        Firmware([str(tmp_path / "none.c")], update="void f(float a, float b)", state_names=("theta",))
    src = tmp_path / "f.c"
    src.write_text("void f(float a) { (void)a; }\n")
    fw = Firmware([str(src)], update="void f(float a)", state={"theta": "=0.0f"})
    with pytest.raises(FirmwareError, match="takes 1 input values"):
        validate(fw, "Kalman1D", dict(dt=0.01, k0=0.1), _inputs("1d", n=10))
    bad = tmp_path / "bad.c"
    bad.write_text("void g(float a, float b) { this is not C; }\n")
    fw = Firmware([str(bad)], update="void g(float a, float b)", state={"theta": "=0.0f"})
    with pytest.raises(FirmwareError, match="compilation failed"):
        validate(fw, "Kalman1D", dict(dt=0.01, k0=0.1), _inputs("1d", n=10))
    p = parse_prototype("void upd(my_t *const self, const float g[3], float *a, imf_real dt);")
    assert p.name == "upd" and [q.name for q in p.params] == ["self", "g", "a", "dt"]
    assert [q.vector for q in p.params] == [True, True, True, False]


def test_compare_states_reports_ulps_and_abs():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(200, 3)).astype(np.float32)
    b = a.copy()
    b[57, 2] = np.nextafter(b[57, 2], F32(np.inf))
    b[120, 0] = b[120, 0] * F32(1.001)
    rep = compare_states(b, a, ("p", "q", "r"))
    assert not rep.bit_exact
    assert (rep.first_sample, rep.first_variable) == (57, "r")
    assert rep.n_different == 2
    assert rep.max_ulps["r"] == 1 and rep.max_ulps["q"] == 0
    assert rep.max_ulps["p"] == bits_ulps(b[120:121, 0], a[120:121, 0]).max()
    assert rep.max_abs["p"] == pytest.approx(abs(float(b[120, 0]) - float(a[120, 0])))
    assert compare_states(a, a.copy()).bit_exact


# ---------------------------------------------------------------------------
# planted mistakes (float32 builds)

class _DoubleLiteral(reference.Complementary1D):
    """Mirror of `(1.0 - self->alpha) * angle`: the accelerometer term is
    computed in double, the sum too, then rounded once to float."""

    def _update(self, rate, angle):
        if not np.isfinite(rate) or not np.isfinite(angle):
            return self._skip()
        gyro_part = self.alpha * (self.theta + rate * self.dt)          # float32
        theta = F32(float(gyro_part) + (1.0 - float(self.alpha)) * float(angle))
        if not np.isfinite(theta):
            return self._skip()
        self.theta = theta


class _Reassociated(reference.Mahony1DBias):
    """Mirror of `(self->kp * e + (i + rate))`."""

    def _update(self, rate, angle):
        e = angle - self.theta
        i = self.i + self.ki_dt * e
        theta = self.theta + (self.kp * e + (i + rate)) * self.dt
        self.theta, self.i = theta, i


class _Reciprocal(reference.Complementary1DBias):
    """Mirror of normalising the coefficients by a reciprocal of a0."""

    def _set_dt(self, dt):
        R = self._R
        kp_dt = self.kp * dt
        ki_dt2 = self.ki * dt * dt
        a0 = R(1.0) + kp_dt + ki_dt2
        inv_a0 = R(1.0) / a0
        self.dt = dt
        self.b0a = (kp_dt + ki_dt2) * inv_a0
        self.b0w = dt * inv_a0
        self.ki_dt = self.ki * dt


def _quiet_start(rate, angle, n0=40):
    """Inputs that start with n0 samples of zero angle, so no mistake can show
    before sample n0."""
    rate, angle = rate.copy(), angle.copy()
    angle[:n0] = 0.0
    rate[:n0] = 0.0
    return rate, angle


MISTAKES = {
    "double_literal": dict(
        name="Complementary1D", params=dict(dt=0.005, alpha=0.98), mirror=_DoubleLiteral,
        old="+ self->one_minus_alpha * angle;", new="+ (1.0 - self->alpha) * angle;"),
    "reassociated": dict(
        name="Mahony1DBias", params=dict(dt=0.005, kp=2.0, ki=0.3), mirror=_Reassociated,
        old="(self->kp * e + i + rate) * self->dt", new="(self->kp * e + (i + rate)) * self->dt"),
    "reciprocal_normalisation": dict(
        # (at these gains both coefficients of the reciprocal differ in float32)
        name="Complementary1DBias", params=dict(dt=0.002, kp=3.0, ki=0.2), mirror=_Reciprocal,
        old=" / a0;\n", new=" * inv_a0;\n", count=2,
        extra=("const imf_real a0 = IMF_R(1.0) + kp_dt + ki_dt2;\n",
               "const imf_real a0 = IMF_R(1.0) + kp_dt + ki_dt2;\n"
               "    const imf_real inv_a0 = IMF_R(1.0) / a0;\n")),
}


@pytest.mark.parametrize("mistake", list(MISTAKES))
def test_planted_mistake_is_found_at_its_first_sample(mistake, tmp_path):
    m = MISTAKES[mistake]
    d = _planted(tmp_path, m["old"], m["new"], m.get("count", 1))
    if "extra" in m:
        path = os.path.join(d, "filters_1d.c")
        text = open(path).read()
        assert text.count(m["extra"][0]) == 1
        text = text.replace(m["extra"][0], m["extra"][1])
        open(path, "w").write(text)
    rate, angle = _quiet_start(*_inputs("1d"))
    inputs = (rate.astype(F32), angle.astype(F32))
    fw = csrc_firmware(m["name"], d, "float32")
    v = validate(fw, m["name"], m["params"], inputs)

    # the test's own answer: the mirror of the mistake against the reference
    want = getattr(reference, m["name"])(**m["params"], dtype="float32").run(*inputs)
    mistaken = m["mirror"](**m["params"], dtype="float32").run(*inputs)
    k = _first_diff(mistaken, want)
    assert k is not None and k >= 40, "the mistake must show, and not before the quiet start"
    assert _first_diff(v.got, mistaken) is None, "the mirror must be the compiled mistake"

    assert not v.bit_exact
    assert v.comparison.first_sample == k
    names = getattr(reference, m["name"]).state_names
    j = int(np.flatnonzero(mistaken[k].view(np.uint32) != want[k].view(np.uint32))[0])
    assert v.comparison.first_variable == names[j]
    assert f"first divergence at sample {k}," in v.text()
    for jj, n in enumerate(names):
        assert v.comparison.max_ulps[n] == bits_ulps(mistaken[:, jj], want[:, jj]).max()


def test_double_literal_is_harmless_in_float64(tmp_path):
    """The same edit in a float64 build changes nothing: the harness must not
    cry wolf."""
    m = MISTAKES["double_literal"]
    d = _planted(tmp_path, m["old"], m["new"])
    fw = csrc_firmware(m["name"], d, "float64")
    v = validate(fw, m["name"], m["params"], _inputs("1d"))
    assert v.bit_exact, v.text()


# ---------------------------------------------------------------------------
# a 3D filter: normalisation in a different order (in-place rows in DCM)

def _dcm_in_place_mirror():
    """Mirror of DCM with r_y' orthogonalised against the already-corrected
    r_x' (the rows updated in place) instead of both from the old pair."""
    import math
    from imufuse.reference.dcm import DCM
    from imufuse.reference.mahony2d import sqrt_r

    class InPlace(DCM):
        def _update(self, gx, gy, gz, ax, ay, az):
            R = self._R
            ex = ey = ez = R(0.0)
            ix, iy, iz = self.ix, self.iy, self.iz
            n2 = ax * ax + ay * ay + az * az
            if n2 > R(0.0) and math.isfinite(n2):
                norm = sqrt_r(R, n2)
                nx, ny, nz = ax / norm, ay / norm, az / norm
                ex = ny * self.r22 - nz * self.r21
                ey = nz * self.r20 - nx * self.r22
                ez = nx * self.r21 - ny * self.r20
                ix = ix + self.ki_dt * ex
                iy = iy + self.ki_dt * ey
                iz = iz + self.ki_dt * ez
            hx = (gx + (self.kp * ex + ix)) * self.dt
            hy = (gy + (self.kp * ey + iy)) * self.dt
            hz = (gz + (self.kp * ez + iz)) * self.dt
            x0 = self.r00 + (self.r01 * hz - self.r02 * hy)
            x1 = self.r01 + (self.r02 * hx - self.r00 * hz)
            x2 = self.r02 + (self.r00 * hy - self.r01 * hx)
            y0 = self.r10 + (self.r11 * hz - self.r12 * hy)
            y1 = self.r11 + (self.r12 * hx - self.r10 * hz)
            y2 = self.r12 + (self.r10 * hy - self.r11 * hx)
            dr = R(0.5) * (x0 * y0 + x1 * y1 + x2 * y2)
            r00, r01, r02 = x0 - dr * y0, x1 - dr * y1, x2 - dr * y2
            r10, r11, r12 = y0 - dr * r00, y1 - dr * r01, y2 - dr * r02   # the mistake
            sx = R(0.5) * (R(3.0) - (r00 * r00 + r01 * r01 + r02 * r02))
            sy = R(0.5) * (R(3.0) - (r10 * r10 + r11 * r11 + r12 * r12))
            r00, r01, r02 = sx * r00, sx * r01, sx * r02
            r10, r11, r12 = sy * r10, sy * r11, sy * r12
            r20 = r01 * r12 - r02 * r11
            r21 = r02 * r10 - r00 * r12
            r22 = r00 * r11 - r01 * r10
            (self.r00, self.r01, self.r02, self.r10, self.r11, self.r12,
             self.r20, self.r21, self.r22, self.ix, self.iy, self.iz) = \
                (r00, r01, r02, r10, r11, r12, r20, r21, r22, ix, iy, iz)
    return InPlace


@pytest.mark.skipif("DCM" not in reference.FILTERS, reason="DCM not present")
def test_planted_normalisation_order_in_dcm(tmp_path):
    d = tmp_path / "csrc"
    shutil.copytree(CSRC, d)
    path = d / "dcm.c"
    text = path.read_text()
    old = ("    out.r10 = y0 - dr * x0;\n    out.r11 = y1 - dr * x1;\n"
           "    out.r12 = y2 - dr * x2;\n")
    assert text.count(old) == 1, "csrc/dcm.c changed"
    path.write_text(text.replace(old, old.replace("* x", "* out.r0")))
    gyr, acc = _inputs("imu")
    gyr, acc = gyr.copy(), acc.copy()
    gyr[:40], acc[:40] = 0.0, (0.0, 0.0, 1.0)          # level and still: no error can show
    inputs = (gyr.astype(F32), acc.astype(F32))
    params = dict(dt=0.005, kp=2.0, ki=0.5)
    v = validate(csrc_firmware("DCM", str(d), "float32"), "DCM", params, inputs)

    want = reference.DCM(**params, dtype="float32").run(*inputs)
    mistaken = _dcm_in_place_mirror()(**params, dtype="float32").run(*inputs)
    k = _first_diff(mistaken, want)
    assert k is not None and k >= 40
    assert _first_diff(v.got, mistaken) is None, "the mirror must be the compiled mistake"
    assert not v.bit_exact and v.comparison.first_sample == k
    j = int(np.flatnonzero(mistaken[k].view(np.uint32) != want[k].view(np.uint32))[0])
    assert v.comparison.first_variable == reference.DCM.state_names[j]


_FW_SET_SRC = """#include "fw.h"
void fw_init(fw_t *s, const fw_set_t *set)
{
    imf_mahony_settings_t t;
    imf_mahony_default_settings(&t);
    t.dt = set->dt; t.kp = set->kp; t.ki = set->ki;
    imf_mahony_init(&s->f, &t);
}
void fw_update(fw_t *s, float gx, float gy, float gz, float ax, float ay, float az)
{
    imf_mahony_update_imu(&s->f, gx, gy, gz, ax, ay, az);
}
"""


def _settings_fw(tmp_path, struct_decl, **kw):
    """Firmware whose init takes a settings struct declared as ``struct_decl`` (naming the
    type fw_set_t); it wraps csrc's MahonyIMU, reading dt, kp and ki by name."""
    d = tmp_path / "fw"
    d.mkdir(exist_ok=True)
    (d / "fw.h").write_text('#include "mahony.h"\n' + struct_decl + "\n"
                            "typedef struct { imf_mahony_t f; } fw_t;\n"
                            "void fw_init(fw_t *s, const fw_set_t *set);\n"
                            "void fw_update(fw_t *s, float gx, float gy, float gz, float ax, "
                            "float ay, float az);\n")
    (d / "fw.c").write_text(_FW_SET_SRC)
    return Firmware([str(d / "fw.c"), os.path.join(CSRC, "mahony.c"),
                     os.path.join(CSRC, "imf_attitude.c")],
                    headers=["fw.h"], include_dirs=[str(d), CSRC], init="fw_init",
                    update="fw_update",
                    state={n: f"f.x.{n}" for n in ("q0", "q1", "q2", "q3", "ix", "iy", "iz")},
                    cache_dir=str(tmp_path / "cache"), **kw)


@pytest.mark.parametrize("decl", [
    # the members of imf_mahony_settings_t with kp and ki swapped: matched by name
    "typedef struct { float dt; float ki; float kp; int invsqrt; float acc_gate_lo; "
    "float acc_gate_hi; float acc_1g; } fw_set_t;",
    "struct fw_set { float dt; float kp; float ki; }; typedef struct fw_set fw_set_t;",
    "typedef struct { float dt; float kp; float ki; unsigned char invsqrt; } fw_set_t;",
], ids=["swapped", "tagged", "uchar"])
def test_settings_struct_members_are_matched_by_name(tmp_path, decl):
    params = dict(dt=0.005, kp=2.0, ki=0.5)
    v = validate(_settings_fw(tmp_path, decl), "MahonyIMU", params, _inputs("imu"))
    assert v.bit_exact, v.text()


@pytest.mark.parametrize("decl,kw,params,msg", [
    ("typedef struct { float dt; struct { float kp; float ki; } g; } fw_set_t;", {}, {},
     "nested struct or union member"),
    ("typedef struct { float kp; float ki; } gains_t;\n"
     "typedef struct { float dt; gains_t g; } fw_set_t;", {}, {}, r"fw_set_t\.g: a struct member"),
    ("typedef struct { float dt; float kp; float ki; unsigned fast : 1; } fw_set_t;", {}, {},
     "bit-field member"),
    ("typedef struct { float dt; float kp; float ki; void (*hook)(void); } fw_set_t;", {}, {},
     "function pointer member"),
    ("typedef struct { const float dt; float kp; float ki; } fw_set_t;", {}, {},
     "const member cannot be set"),
    ("typedef struct { float dt; float kp; float ki; float acc_gate; } fw_set_t;", {},
     dict(acc_gate=(0.6, 1.4)), r"member 'acc_gate' would get \(0\.6, 1\.4\).*not a number"),
    ("typedef struct { float dt; float kp; float ki; int invsqrt; } fw_set_t;",
     dict(init_args={"invsqrt": 0.5}), {}, "integer member 'invsqrt' would get 0.5"),
    ("typedef struct { float dt; float kp; float ki; } fw_set_t;",
     dict(init_args={"kP": 3}), {}, "--init-arg kP: fw_init has no member of that name"),
], ids=["anonymous", "nested", "bitfield", "fnptr", "const", "tuple", "int", "unknown"])
def test_settings_struct_problems_are_named(tmp_path, decl, kw, params, msg):
    with pytest.raises(FirmwareError, match=msg):
        fw = _settings_fw(tmp_path, decl, **kw)
        validate(fw, "MahonyIMU", dict(dict(dt=0.005, kp=2.0, ki=0.5), **params),
                 _inputs("imu"))
