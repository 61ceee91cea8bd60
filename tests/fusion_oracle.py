"""The Fusion oracle: imufusion 1.2.3 from PyPI (Longbin's Fusion walkthrough), fetched and built
in the test session, never committed.

- `fetch_sdist()`: `pip download --no-deps --no-binary :all: imufusion==1.2.3`,
  SHA-256 checked, cached (IMUFUSE_ORACLE_CACHE, default ~/.cache/imufuse/oracle).
- `imufusion_module()`: the sdist built as imufusion builds itself
  (`pip install --no-build-isolation`, its own setup.py: FUSION_USE_NORMAL_SQRT)
  into the cache, imported from there: the real PyPI package.
- `fusion_c(normal_sqrt)`: Fusion's C files from the same sdist compiled with
  cffi (-std=c99 -O2 -ffp-contract=off, with or without FUSION_USE_NORMAL_SQRT)
  together with a small batch shim written here, which reads every member of
  FusionAhrs / FusionOffset after every sample.

Unreachable PyPI or a missing compiler skips, or fails with
IMUFUSE_REQUIRE_ORACLE=1 (as tests/test_published.py).
"""
import glob
import hashlib
import importlib.machinery
import importlib.util
import os
import shutil
import subprocess
import sys
import sysconfig
import tarfile
import tempfile
from pathlib import Path

import pytest

VERSION = "1.2.3"
SHA256 = "e403e66abd77b5206be8511ecbd54d62fa452f681444bfe9ea17e1d31af6c493"
CACHE = Path(os.environ.get("IMUFUSE_ORACLE_CACHE", Path.home() / ".cache" / "imufuse" / "oracle"))
CFLAGS = ["-std=c99", "-O2", "-ffp-contract=off"]

# our own glue: batch loops over Fusion's API, dumping every state member
SHIM = r"""
#include <math.h>
#include "Fusion.h"

static void dump_state(const FusionAhrs *a, float *s)
{
    s[0] = a->quaternion.element.w; s[1] = a->quaternion.element.x;
    s[2] = a->quaternion.element.y; s[3] = a->quaternion.element.z;
    s[4] = a->accelerometer.axis.x; s[5] = a->accelerometer.axis.y; s[6] = a->accelerometer.axis.z;
    s[7] = a->rampedGain;
    s[8] = a->halfAccelerometerFeedback.axis.x; s[9] = a->halfAccelerometerFeedback.axis.y;
    s[10] = a->halfAccelerometerFeedback.axis.z;
    s[11] = a->halfMagnetometerFeedback.axis.x; s[12] = a->halfMagnetometerFeedback.axis.y;
    s[13] = a->halfMagnetometerFeedback.axis.z;
    s[14] = (float) a->initialising; s[15] = (float) a->angularRateRecovery;
    s[16] = (float) a->accelerometerIgnored; s[17] = (float) a->accelerationRecoveryTrigger;
    s[18] = (float) a->accelerationRecoveryTimeout; s[19] = (float) a->magnetometerIgnored;
    s[20] = (float) a->magneticRecoveryTrigger; s[21] = (float) a->magneticRecoveryTimeout;
}

static void dump_outputs(const FusionAhrs *a, float *o, unsigned *flags)
{
    const FusionVector lin = FusionAhrsGetLinearAcceleration(a);
    const FusionVector earth = FusionAhrsGetEarthAcceleration(a);
    const FusionEuler e = FusionQuaternionToEuler(FusionAhrsGetQuaternion(a));
    const FusionAhrsInternalStates st = FusionAhrsGetInternalStates(a);
    const FusionAhrsFlags f = FusionAhrsGetFlags(a);
    int i;
    for (i = 0; i < 3; i++) {
        o[i] = NAN; /* 1.2.3 has no gravity output */
        o[3 + i] = lin.array[i];
        o[6 + i] = earth.array[i];
        o[9 + i] = e.array[i];
    }
    o[12] = st.accelerationError; o[13] = st.accelerationRecoveryTrigger;
    o[14] = st.magneticError; o[15] = st.magneticRecoveryTrigger;
    *flags = (unsigned) f.initialising | (unsigned) f.angularRateRecovery << 1
             | (unsigned) f.accelerationRecovery << 2 | (unsigned) f.magneticRecovery << 3
             | (unsigned) st.accelerometerIgnored << 4 | (unsigned) st.magnetometerIgnored << 5;
}

void ahrs_run(int conv, float gain, float range, float accrej, float magrej, unsigned period,
              long n, const int *mode, const int *reset, const float *set_heading,
              const float *g, const float *a, const float *m, const float *h, const float *dt,
              long change_at, int conv2, float gain2, float range2, float accrej2, float magrej2,
              unsigned period2, float *state, float *out, unsigned *flags)
{
    FusionAhrs ahrs;
    const FusionAhrsSettings s = {(FusionConvention) conv, gain, range, accrej, magrej, period};
    const FusionAhrsSettings s2 = {(FusionConvention) conv2, gain2, range2, accrej2, magrej2, period2};
    long k;
    FusionAhrsInitialise(&ahrs);
    FusionAhrsSetSettings(&ahrs, &s);
    for (k = 0; k < n; k++) {
        const FusionVector gv = {.array = {g[3 * k], g[3 * k + 1], g[3 * k + 2]}};
        const FusionVector av = {.array = {a[3 * k], a[3 * k + 1], a[3 * k + 2]}};
        const FusionVector mv = {.array = {m[3 * k], m[3 * k + 1], m[3 * k + 2]}};
        if (k == change_at) {
            FusionAhrsSetSettings(&ahrs, &s2);
        }
        if (reset[k]) {
            FusionAhrsReset(&ahrs);
        }
        if (!isnan(set_heading[k])) {
            FusionAhrsSetHeading(&ahrs, set_heading[k]);
        }
        if (mode[k] == 0) {
            FusionAhrsUpdate(&ahrs, gv, av, mv, dt[k]);
        } else if (mode[k] == 1) {
            FusionAhrsUpdateExternalHeading(&ahrs, gv, av, h[k], dt[k]);
        } else {
            FusionAhrsUpdateNoMagnetometer(&ahrs, gv, av, dt[k]);
        }
        dump_state(&ahrs, state + 22 * k);
        dump_outputs(&ahrs, out + 16 * k, flags + k);
    }
}

void offset_run(unsigned rate, long n, const float *g, float *out, float *state)
{
    FusionOffset off;
    long k;
    FusionOffsetInitialise(&off, rate);
    for (k = 0; k < n; k++) {
        const FusionVector gv = {.array = {g[3 * k], g[3 * k + 1], g[3 * k + 2]}};
        const FusionVector c = FusionOffsetUpdate(&off, gv);
        out[3 * k] = c.axis.x; out[3 * k + 1] = c.axis.y; out[3 * k + 2] = c.axis.z;
        state[4 * k] = off.gyroscopeOffset.axis.x; state[4 * k + 1] = off.gyroscopeOffset.axis.y;
        state[4 * k + 2] = off.gyroscopeOffset.axis.z; state[4 * k + 3] = (float) off.timer;
    }
}

static FusionMatrix mat(const float *m)
{
    FusionMatrix r;
    int i;
    for (i = 0; i < 9; i++) {
        r.array[i / 3][i % 3] = m[i];
    }
    return r;
}

void calib_inertial(long n, const float *in, const float *m, const float *s, const float *b,
                    float *out)
{
    const FusionVector sv = {.array = {s[0], s[1], s[2]}}, bv = {.array = {b[0], b[1], b[2]}};
    long k;
    for (k = 0; k < n; k++) {
        const FusionVector u = {.array = {in[3 * k], in[3 * k + 1], in[3 * k + 2]}};
        const FusionVector c = FusionCalibrationInertial(u, mat(m), sv, bv);
        out[3 * k] = c.axis.x; out[3 * k + 1] = c.axis.y; out[3 * k + 2] = c.axis.z;
    }
}

void calib_magnetic(long n, const float *in, const float *m, const float *h, float *out)
{
    const FusionVector hv = {.array = {h[0], h[1], h[2]}};
    long k;
    for (k = 0; k < n; k++) {
        const FusionVector u = {.array = {in[3 * k], in[3 * k + 1], in[3 * k + 2]}};
        const FusionVector c = FusionCalibrationMagnetic(u, mat(m), hv);
        out[3 * k] = c.axis.x; out[3 * k + 1] = c.axis.y; out[3 * k + 2] = c.axis.z;
    }
}

void axes_swap(int alignment, long n, const float *in, float *out)
{
    long k;
    for (k = 0; k < n; k++) {
        const FusionVector u = {.array = {in[3 * k], in[3 * k + 1], in[3 * k + 2]}};
        const FusionVector c = FusionAxesSwap(u, (FusionAxesAlignment) alignment);
        out[3 * k] = c.axis.x; out[3 * k + 1] = c.axis.y; out[3 * k + 2] = c.axis.z;
    }
}

void compass(int conv, long n, const float *a, const float *m, float *out)
{
    long k;
    for (k = 0; k < n; k++) {
        const FusionVector av = {.array = {a[3 * k], a[3 * k + 1], a[3 * k + 2]}};
        const FusionVector mv = {.array = {m[3 * k], m[3 * k + 1], m[3 * k + 2]}};
        out[k] = FusionCompassCalculateHeading((FusionConvention) conv, av, mv);
    }
}

float fast_invsqrt(float x)
{
#ifdef FUSION_USE_NORMAL_SQRT
    (void) x;
    return NAN;
#else
    return FusionFastInverseSqrt(x);
#endif
}
"""

CDEF = """
void ahrs_run(int conv, float gain, float range, float accrej, float magrej, unsigned period,
              long n, const int *mode, const int *reset, const float *set_heading,
              const float *g, const float *a, const float *m, const float *h, const float *dt,
              long change_at, int conv2, float gain2, float range2, float accrej2, float magrej2,
              unsigned period2, float *state, float *out, unsigned *flags);
void offset_run(unsigned rate, long n, const float *g, float *out, float *state);
void calib_inertial(long n, const float *in, const float *m, const float *s, const float *b,
                    float *out);
void calib_magnetic(long n, const float *in, const float *m, const float *h, float *out);
void axes_swap(int alignment, long n, const float *in, float *out);
void compass(int conv, long n, const float *a, const float *m, float *out);
float fast_invsqrt(float x);
"""


def unavailable(msg):
    if os.environ.get("IMUFUSE_REQUIRE_ORACLE"):
        pytest.fail(msg)
    pytest.skip(msg)


def _sha256(path):
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def fetch_sdist():
    sdist = CACHE / f"imufusion-{VERSION}.tar.gz"
    if sdist.exists() and _sha256(sdist) == SHA256:
        return sdist
    CACHE.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        got = Path(tmp) / sdist.name
        cmd = [sys.executable, "-m", "pip", "download", "--no-deps", "--no-binary", ":all:",
               "--no-build-isolation", "--disable-pip-version-check", "-q",
               f"imufusion=={VERSION}", "-d", tmp]
        try:
            r = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
        except (OSError, subprocess.TimeoutExpired) as exc:
            unavailable(f"cannot fetch imufusion {VERSION}: {exc}")
        if r.returncode != 0 or not got.exists():
            unavailable(f"cannot fetch imufusion {VERSION} sdist from PyPI: {r.stderr.strip()[-500:]}")
        if _sha256(got) != SHA256:
            pytest.fail(f"imufusion {VERSION} sdist has an unexpected SHA-256 {_sha256(got)}")
        shutil.copyfile(got, sdist)
    return sdist


def imufusion_module(sdist, version=VERSION, builder=None):
    """The sdist built by its own setup.py (FUSION_USE_NORMAL_SQRT), imported. builder(sdist,
    tmp) builds it into tmp where pip cannot (default: pip install --target)."""
    tag = sysconfig.get_config_var("EXT_SUFFIX") or ""
    target = CACHE / f"imufusion-{version}-{hashlib.sha256(tag.encode()).hexdigest()[:8]}"
    found = glob.glob(str(target / "imufusion*.so"))
    if not found:
        with tempfile.TemporaryDirectory(dir=CACHE) as tmp:
            err = (builder or _pip_build)(sdist, tmp)
            if err:
                unavailable(f"cannot build imufusion {version}: {err[-800:]}")
            shutil.rmtree(target, ignore_errors=True)
            shutil.copytree(tmp, target)
        found = glob.glob(str(target / "imufusion*.so"))
    loader = importlib.machinery.ExtensionFileLoader("imufusion", found[0])
    spec = importlib.util.spec_from_file_location("imufusion", found[0], loader=loader)
    mod = importlib.util.module_from_spec(spec)
    loader.exec_module(mod)
    return mod


def _pip_build(sdist, tmp):
    cmd = [sys.executable, "-m", "pip", "install", "--no-build-isolation", "--no-deps",
           "--disable-pip-version-check", "-q", "--target", tmp, str(sdist)]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    return r.stderr.strip() if r.returncode != 0 else ""


def fusion_c(sdist, normal_sqrt, version=VERSION, shim=SHIM, cdef=CDEF,
             sources=("FusionAhrs.c", "FusionOffset.c", "FusionCompass.c")):
    """Fusion's C from the sdist + shim, compiled with cffi; returns (ffi, lib)."""
    try:
        import cffi
    except ImportError:
        unavailable("cffi is needed to compile Fusion's C")
    if shutil.which("gcc") is None and shutil.which("cc") is None:
        unavailable("a C compiler is needed to compile Fusion's C")
    with tarfile.open(sdist) as tar:
        files = {Path(m.name).name: tar.extractfile(m).read()
                 for m in tar.getmembers() if m.name.startswith(f"imufusion-{version}/Fusion/")
                 and m.isfile()}
    key = hashlib.sha256(repr((sorted(files.items()), shim, cdef, CFLAGS, normal_sqrt)).encode()
                         ).hexdigest()[:12]
    name = f"_fusion_oracle_{key}"
    build = CACHE / f"fusion-c-{key}"
    so = glob.glob(str(build / f"{name}*.so"))
    if not so:
        build.mkdir(parents=True, exist_ok=True)
        src = build / "Fusion"
        src.mkdir(exist_ok=True)
        for fname, data in files.items():
            (src / fname).write_bytes(data)
        ffi = cffi.FFI()
        ffi.cdef(cdef)
        ffi.set_source(name, shim, sources=[str(src / f) for f in sources],
                       include_dirs=[str(src)],
                       define_macros=[("FUSION_USE_NORMAL_SQRT", None)] if normal_sqrt else [],
                       extra_compile_args=CFLAGS, libraries=["m"])
        ffi.compile(tmpdir=str(build))
        so = glob.glob(str(build / f"{name}*.so"))
    spec = importlib.util.spec_from_file_location(name, so[0])
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.ffi, mod.lib


_CTYPES = {"float32": "float[]", "int32": "int[]", "uint32": "unsigned int[]"}


def buf(ffi, a):
    """A C pointer to a contiguous float32/int32/uint32 array (no copy; keep a alive)."""
    return ffi.from_buffer(_CTYPES[a.dtype.name], a, require_writable=False)


def fusion_sources(sdist, version, dest):
    """Fusion's C files of an imufusion sdist (its Fusion/ directory, unmodified) copied into
    dest; returns dest as a string (the --source-dir of a Fusion declaration)."""
    with tarfile.open(sdist) as tar:
        for m in tar.getmembers():
            if m.name.startswith(f"imufusion-{version}/Fusion/") and m.isfile():
                (Path(dest) / os.path.basename(m.name)).write_bytes(tar.extractfile(m).read())
    return str(dest)


def validate_declared_fusion(declaration, source_dir, target, flags=None, seconds=3.0):
    """x-io's C as a declaration file declares it, validated on simulated fast motion (200 Hz,
    seed 3; the gyroscope in Fusion's deg/s) on ``target``, built with ``flags`` (None: the
    declaration's)."""
    import numpy as np

    from imufuse import sim
    from imufuse.catalogue import inputs_for
    from imufuse.firmware import validate_isolated
    from imufuse.firmware.declfile import load_declaration
    d = load_declaration(declaration, source_dir=source_dir)
    if flags is not None:
        d.firmware.cflags = d.firmware.cflags_given = list(flags)
    s = sim.imu("fast", rate=200.0, duration=seconds, seed=3)
    g, a, m = inputs_for("ahrs", s)
    return validate_isolated(d.firmware, d.filter, dict(d.params, dt=s.dt),
                             [np.degrees(g), a, m], target=target)
