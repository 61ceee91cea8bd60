"""The batch path (imufuse_c.run_filters / run_many: the lane kernels, the threads, the C
scorer, and the checks before them) under AddressSanitizer + UndefinedBehaviorSanitizer and
under ThreadSanitizer.

imufuse_c._f64 is compiled again from the package's own generated C (imufuse_c/_f64.c and
its translation units, which building the package writes into the checkout) with each
sanitizer, at -O0 (about 10 s), and put into a copy of the installed imufuse_c. The batch
tests (tests/test_batch.py, the batch tests of tests/test_reliability3.py and the thread
guard's tests) then run against it in a child interpreter with the sanitizer's runtime
preloaded; any report fails the test. In the same child a canary (an overflow read through
ctypes, a race of two threads writing one buffer) must be reported, so a run in which the
sanitizer is not active cannot pass. The float64 tests only: _f32 is the same code
(imufuse_c/_sweep.pxi, imufuse_c/host) in the other precision. The long-rest tests are left
out here (the same paths as the short ones, 300 000 samples)."""
import os
import shutil
import subprocess
import sys
import sysconfig
import textwrap
from pathlib import Path

import numpy as np
import pytest

import imufuse_c

ROOT = Path(__file__).resolve().parents[1]
GENERATED = ROOT / "imufuse_c" / "_f64.c"
UNITS = ROOT / "build" / "imufuse_units" / "_f64"
TESTS = [str(ROOT / "tests" / t) for t in ("test_batch.py", "test_reliability3.py",
                                           "test_thread_guard.py")
         if (ROOT / "tests" / t).exists()]
# test_reliability3's batch tests; the float64 ones; not the long rests
SELECT = ("not float32 and not long_rest and (not test_reliability3 or filter or reference "
          "or threads or run_many or copies)")
# under ThreadSanitizer, the tests that run more than one thread
SELECT_THREADS = ("not float32 and not long_rest and (run_many_is_each_run or scores_equal "
                  "or copies or side_by_side or releases or (every_entry_point and RobustAHRS "
                  "and not RobustAHRSQ))")

SANITIZERS = {
    "address,undefined": ("libasan.so", {"ASAN_OPTIONS": "detect_leaks=0:abort_on_error=0",
                                         "UBSAN_OPTIONS": "halt_on_error=1:print_stacktrace=1"},
                          "AddressSanitizer: heap-buffer-overflow"),
    "thread": ("libtsan.so", {"TSAN_OPTIONS": "halt_on_error=1:exitcode=66"},
               "ThreadSanitizer: data race"),
}

CANARY = {
    "address,undefined": textwrap.dedent("""
        import ctypes
        libc = ctypes.CDLL(None)
        libc.malloc.restype = ctypes.c_void_p
        p = libc.malloc(16)
        buf = ctypes.create_string_buffer(64)
        ctypes.memmove(buf, p, 64)      # reads 48 bytes past the block
    """),
    "thread": textwrap.dedent("""
        import ctypes, threading
        libc = ctypes.CDLL(None)
        libc.malloc.restype = ctypes.c_void_p
        p = libc.malloc(1 << 20)
        def w():
            for _ in range(200):
                ctypes.memset(p, 1, 1 << 20)
        ts = [threading.Thread(target=w) for _ in range(2)]
        [t.start() for t in ts]
        [t.join() for t in ts]
    """),
}


def _runtime(lib):
    cc = shutil.which("gcc") or shutil.which("cc")
    if cc is None:
        pytest.skip("no C compiler (tools/install-toolchains.sh installs gcc)")
    path = subprocess.run([cc, f"-print-file-name={lib}"], capture_output=True,
                          text=True).stdout.strip()
    if not os.path.isabs(path) or not os.path.exists(path):
        pytest.skip(f"{cc} has no {lib} (the sanitizer runtime; Debian's gcc has it)")
    return cc, os.path.realpath(path)


# one worker per sanitizer (pytest-xdist --dist loadgroup): the build of one sanitizer and its
# tests stay together, the two sanitizers' may run side by side (no brackets in a group name)
@pytest.fixture(scope="module", params=[
    pytest.param(s, marks=pytest.mark.xdist_group(f"sanitizers_batch-{s}")) for s in SANITIZERS])
def sanitized(request, tmp_path_factory):
    """(package directory, environment) of imufuse_c with _f64 built under one sanitizer."""
    san = request.param
    lib, options, _ = SANITIZERS[san]
    cc, runtime = _runtime(lib)
    if not GENERATED.exists() or not list(UNITS.glob("*.c")):
        pytest.skip(f"the generated C of imufuse_c ({GENERATED.relative_to(ROOT)}, "
                    f"{UNITS.relative_to(ROOT)}) is not in this checkout: build the package "
                    "from it first (tools/test.sh does)")
    d = tmp_path_factory.mktemp("san")
    pkg = d / "imufuse_c"
    shutil.copytree(Path(imufuse_c.__file__).parent, pkg,
                    ignore=shutil.ignore_patterns("__pycache__", "*.c"))
    target = next(pkg.glob("_f64.*so"))
    cmd = [cc, "-shared", "-fPIC", "-O0", f"-fsanitize={san}", "-std=c99", "-ffp-contract=off",
           "-w", "-DIMF_DOUBLE", "-DNPY_NO_DEPRECATED_API=NPY_1_7_API_VERSION",
           f"-I{ROOT / 'csrc'}", f"-I{ROOT / 'csrc' / 'fixed'}",
           f"-I{ROOT / 'imufuse_c' / 'host'}", f"-I{np.get_include()}",
           f"-I{sysconfig.get_paths()['include']}", str(GENERATED),
           *map(str, sorted(UNITS.glob("*.c"))), "-o", str(target), "-lm"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr[-3000:]
    # the sanitized imufuse_c first; imufuse (and its filter matrix, imufuse.registry) where
    # this process found it
    path = os.pathsep.join(filter(None, [str(d), os.environ.get("PYTHONPATH")]))
    env = {**os.environ, **options, "PYTHONSAFEPATH": "1", "PYTHONPATH": path,
           "LD_PRELOAD": runtime, "PYTHONDONTWRITEBYTECODE": "1"}
    env.pop("PYTEST_XDIST_WORKER", None)
    return d, env, san


def _python():
    # the interpreter itself, not a wrapper script (a shell wrapper cannot run with a
    # preloaded ThreadSanitizer runtime)
    return os.path.realpath(sys.executable)


def test_the_sanitizer_is_active(sanitized):
    d, env, san = sanitized
    code = (f"import imufuse_c._f64 as m; assert m.__file__.startswith({str(d)!r}), m.__file__\n"
            + CANARY[san])
    r = subprocess.run([_python(), "-c", code], capture_output=True, text=True, env=env,
                       timeout=300, cwd=d)
    assert SANITIZERS[san][2] in r.stderr, (r.returncode, r.stderr[-3000:])


def test_batch_tests_run_clean(sanitized):
    d, env, san = sanitized
    r = subprocess.run([_python(), "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider",
                        "-p", "no:xdist", "-p", "no:randomly", "--rootdir", str(ROOT),
                        "-k", SELECT_THREADS if san == "thread" else SELECT, *TESTS],
                       capture_output=True, text=True, env=env, timeout=900, cwd=d)
    out = r.stdout[-3000:] + r.stderr[-6000:]
    assert r.returncode == 0, out
    for word in ("Sanitizer", "runtime error:"):
        assert word not in r.stderr, out
    assert " passed" in r.stdout, out
    print(r.stdout.strip().splitlines()[-1])
