"""The Fusion 1.3 oracle: imufusion 1.3.3 from PyPI (x-io Fusion's current release), fetched
and built in the test session, never committed. The machinery is fusion_oracle.py's (the
1.2.3 oracle); what differs here:

- `fetch_sdist()`: the sdist by its PyPI URL (pip download would build numpy from source to
  read its metadata), SHA-256 checked, cached in IMUFUSE_ORACLE_CACHE.
- `imufusion_module()`: built by the sdist's own setup.py (`setup.py build_ext`: its
  sources and FUSION_USE_NORMAL_SQRT), its pyproject.toml set aside because the license
  field of its metadata needs a newer setuptools than the build requires.
- `fusion_c(normal_sqrt)`: Fusion 1.3's C from the same sdist with cffi and a batch shim
  that reads every member of FusionAhrs / FusionBias after every sample.

Unreachable PyPI or a missing compiler skips, or fails with IMUFUSE_REQUIRE_ORACLE=1.
"""
import shutil
import subprocess
import sys
import tarfile
import tempfile
import urllib.request
from pathlib import Path

import pytest

import fusion_oracle
from fusion_oracle import CACHE, buf, unavailable  # noqa: F401  (buf: for the tests)

VERSION = "1.3.3"
SHA256 = "b2175e5ed1e1cca95ef8673432d1f089037f957cde4325a510738c9e7ad3b87d"
URL = ("https://files.pythonhosted.org/packages/aa/5e/c2bd75da78da778816dc576dcfac5a6dff2aeca3"
       "d7658cb19082d1e65465/imufusion-1.3.3.tar.gz")

SHIM = r"""
#include <math.h>
#include "Fusion.h"

static void dump_state(const FusionAhrs *a, float *s)
{
    int i;
    for (i = 0; i < 4; i++) {
        s[i] = a->quaternion.array[i];
    }
    for (i = 0; i < 3; i++) {
        s[4 + i] = a->accelerometer.array[i];
        s[8 + i] = a->halfAccelerometerResidual.array[i];
        s[11 + i] = a->halfMagnetometerResidual.array[i];
    }
    s[7] = a->startupGain;
    s[14] = a->samplePeriod;
    s[15] = (float) a->startup; s[16] = (float) a->overrangeRecovery;
    s[17] = (float) a->accelerometerIgnored; s[18] = (float) a->accelerationRecoveryTrigger;
    s[19] = (float) a->accelerationRecoveryThreshold; s[20] = (float) a->magnetometerIgnored;
    s[21] = (float) a->magneticRecoveryTrigger; s[22] = (float) a->magneticRecoveryThreshold;
}

static void dump_outputs(const FusionAhrs *a, float *o, unsigned *flags)
{
    const FusionVector grav = FusionAhrsGetGravity(a);
    const FusionVector lin = FusionAhrsGetLinearAcceleration(a);
    const FusionVector earth = FusionAhrsGetEarthAcceleration(a);
    const FusionEuler e = FusionQuaternionToEuler(FusionAhrsGetQuaternion(a));
    const FusionAhrsInternalStates st = FusionAhrsGetInternalStates(a);
    const FusionAhrsFlags f = FusionAhrsGetFlags(a);
    int i;
    for (i = 0; i < 3; i++) {
        o[i] = grav.array[i];
        o[3 + i] = lin.array[i];
        o[6 + i] = earth.array[i];
        o[9 + i] = e.array[i];
    }
    o[12] = st.accelerationError; o[13] = st.accelerationRecoveryTrigger;
    o[14] = st.magneticError; o[15] = st.magneticRecoveryTrigger;
    *flags = (unsigned) f.startup | (unsigned) f.overrangeRecovery << 1
             | (unsigned) f.accelerationRecovery << 2 | (unsigned) f.magneticRecovery << 3
             | (unsigned) st.accelerometerIgnored << 4 | (unsigned) st.magnetometerIgnored << 5;
}

static FusionAhrsSettings settings(const float *p)
{
    const FusionAhrsSettings s = {p[0], (FusionConvention) (int) p[1], p[2], p[3], p[4], p[5],
                                  p[6]};
    return s;
}

/* op[k]: bit 0 restart, bit 1 skip start-up, bit 2 new settings (set2) before sample k */
void ahrs_run(const float *set1, const float *set2, long n, const int *mode, const int *op,
              const float *set_heading, const float *period, const float *g, const float *a,
              const float *m, const float *h, float *state, float *out, unsigned *flags)
{
    FusionAhrs ahrs;
    const FusionAhrsSettings s1 = settings(set1), s2 = settings(set2);
    long k;
    FusionAhrsInitialise(&ahrs);
    FusionAhrsSetSettings(&ahrs, &s1);
    for (k = 0; k < n; k++) {
        const FusionVector gv = {.array = {g[3 * k], g[3 * k + 1], g[3 * k + 2]}};
        const FusionVector av = {.array = {a[3 * k], a[3 * k + 1], a[3 * k + 2]}};
        const FusionVector mv = {.array = {m[3 * k], m[3 * k + 1], m[3 * k + 2]}};
        if (op[k] & 4) {
            FusionAhrsSetSettings(&ahrs, &s2);
        }
        if (op[k] & 1) {
            FusionAhrsRestart(&ahrs);
        }
        if (op[k] & 2) {
            FusionAhrsSkipStartup(&ahrs);
        }
        if (!isnan(set_heading[k])) {
            FusionAhrsSetHeading(&ahrs, set_heading[k]);
        }
        if (!isnan(period[k])) {
            FusionAhrsSetSamplePeriod(&ahrs, period[k]);
        }
        if (mode[k] == 0) {
            FusionAhrsUpdate(&ahrs, gv, av, mv);
        } else if (mode[k] == 1) {
            FusionAhrsUpdateExternalHeading(&ahrs, gv, av, h[k]);
        } else {
            FusionAhrsUpdateNoMagnetometer(&ahrs, gv, av);
        }
        dump_state(&ahrs, state + 23 * k);
        dump_outputs(&ahrs, out + 16 * k, flags + k);
    }
}

/* at restart_at: the offset is kept (as in non-volatile memory), the bias initialised
   again and the offset given back */
void bias_run(const float *set, long n, const float *g, long restart_at, float *out,
              float *state)
{
    FusionBias bias;
    const FusionBiasSettings s = {set[0], set[1], set[2]};
    long k;
    FusionBiasInitialise(&bias);
    FusionBiasSetSettings(&bias, &s);
    for (k = 0; k < n; k++) {
        const FusionVector gv = {.array = {g[3 * k], g[3 * k + 1], g[3 * k + 2]}};
        FusionVector c;
        if (k == restart_at) {
            const FusionVector kept = FusionBiasGetOffset(&bias);
            FusionBiasInitialise(&bias);
            FusionBiasSetSettings(&bias, &s);
            FusionBiasSetOffset(&bias, kept);
        }
        c = FusionBiasUpdate(&bias, gv);
        out[3 * k] = c.axis.x; out[3 * k + 1] = c.axis.y; out[3 * k + 2] = c.axis.z;
        state[4 * k] = bias.offset.axis.x; state[4 * k + 1] = bias.offset.axis.y;
        state[4 * k + 2] = bias.offset.axis.z; state[4 * k + 3] = (float) bias.timer;
    }
}

void remap(int alignment, long n, const float *in, float *out)
{
    long k;
    for (k = 0; k < n; k++) {
        const FusionVector u = {.array = {in[3 * k], in[3 * k + 1], in[3 * k + 2]}};
        const FusionVector c = FusionRemap(u, (FusionRemapAlignment) alignment);
        out[3 * k] = c.axis.x; out[3 * k + 1] = c.axis.y; out[3 * k + 2] = c.axis.z;
    }
}

void compass(int conv, long n, const float *a, const float *m, float *out)
{
    long k;
    for (k = 0; k < n; k++) {
        const FusionVector av = {.array = {a[3 * k], a[3 * k + 1], a[3 * k + 2]}};
        const FusionVector mv = {.array = {m[3 * k], m[3 * k + 1], m[3 * k + 2]}};
        out[k] = FusionCompass(av, mv, (FusionConvention) conv);
    }
}
"""

CDEF = """
void ahrs_run(const float *set1, const float *set2, long n, const int *mode, const int *op,
              const float *set_heading, const float *period, const float *g, const float *a,
              const float *m, const float *h, float *state, float *out, unsigned *flags);
void bias_run(const float *set, long n, const float *g, long restart_at, float *out,
              float *state);
void remap(int alignment, long n, const float *in, float *out);
void compass(int conv, long n, const float *a, const float *m, float *out);
"""

SOURCES = ("FusionAhrs.c", "FusionBias.c", "FusionCompass.c", "FusionConvention.c",
           "FusionRemap.c")


def fetch_sdist():
    sdist = CACHE / f"imufusion-{VERSION}.tar.gz"
    if sdist.exists() and fusion_oracle._sha256(sdist) == SHA256:
        return sdist
    CACHE.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        got = Path(tmp) / sdist.name
        try:
            with urllib.request.urlopen(URL, timeout=120) as r:
                got.write_bytes(r.read())
        except OSError as exc:
            unavailable(f"cannot fetch imufusion {VERSION} sdist from PyPI: {exc}")
        if fusion_oracle._sha256(got) != SHA256:
            pytest.fail(f"imufusion {VERSION} sdist has an unexpected SHA-256 "
                        f"{fusion_oracle._sha256(got)}")
        shutil.copyfile(got, sdist)
    return sdist


def _setup_py_build(sdist, tmp):
    """The sdist's setup.py, run as `setup.py build_ext --inplace` without its pyproject."""
    src = Path(tmp) / "src"
    with tarfile.open(sdist) as tar:
        tar.extractall(src, filter="data")
    root = src / f"imufusion-{VERSION}"
    (root / "pyproject.toml").unlink()
    r = subprocess.run([sys.executable, "setup.py", "-q", "build_ext", "--inplace"], cwd=root,
                       capture_output=True, text=True, timeout=600)
    if r.returncode != 0:
        return r.stderr.strip() or r.stdout.strip()
    for so in root.glob("imufusion*.so"):
        shutil.copy(so, tmp)
    shutil.rmtree(src)
    return ""


def imufusion_module(sdist):
    return fusion_oracle.imufusion_module(sdist, version=VERSION, builder=_setup_py_build)


def fusion_c(sdist, normal_sqrt):
    return fusion_oracle.fusion_c(sdist, normal_sqrt, version=VERSION, shim=SHIM, cdef=CDEF,
                                  sources=SOURCES)
