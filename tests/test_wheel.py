"""The binary wheel as a user without a C compiler gets it (docs/release.md).

tools/test.sh builds the wheel once from the sdist, repairs it with auditwheel into a manylinux
wheel (build/wheelhouse), installs that wheel into the suite's venv and sets IMUFUSE_TEST_WHEEL
to it. Here the wheel goes into a fresh venv without system site packages, with numpy from the
index and a PATH on which there is no C compiler: every compiled module imports (each checks its
C against the reference at import), the demo runs every filter bit-exact, `run` and `compare`
read the shipped example log, and `validate`, which compiles firmware, fails in one line that
says a C compiler is needed and how to get one (exit 5). The wheel carries the C library
(csrc/, its CMakeLists.txt and Makefile) byte for byte, and no library of the build host.

Without IMUFUSE_TEST_WHEEL (pytest run from a checkout) the wheel's tests skip; under
tools/test.sh or CI a missing wheel fails.
"""
import importlib.metadata
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

import imufuse

ROOT = Path(__file__).resolve().parents[1]
WHEEL = os.environ.get("IMUFUSE_TEST_WHEEL")
COMPILERS = ("cc", "gcc", "clang", "c99", "tcc")
# the compiled modules: each checks its C against the reference when imported
MODULES = ("imufuse_c._f32", "imufuse_c._f64", "imufuse_c._fixed", "imufuse_c._csvout",
           "imufuse_c._csvin")
# variables that would hand a compiler, or another installation of imufuse, to the fresh venv
DROP = ("CC", "CXX", "CPP", "LD", "CFLAGS", "CXXFLAGS", "CPPFLAGS", "LDFLAGS", "PYTHONPATH",
        "PYTHONHOME", "VIRTUAL_ENV", "IMUFUSE_CACHE")


@pytest.fixture(scope="module")
def wheel():
    if not WHEEL:
        if os.environ.get("IMUFUSE_TEST_INSTALLED") or os.environ.get("CI"):
            pytest.fail("IMUFUSE_TEST_WHEEL unset under tools/test.sh or CI: the script must "
                        "export the repaired wheel it installs")
        pytest.skip("IMUFUSE_TEST_WHEEL unset: tools/test.sh builds the repaired wheel and sets "
                    "it; a pytest run from a checkout has no wheel")
    path = Path(WHEEL)
    assert path.is_file(), f"IMUFUSE_TEST_WHEEL={WHEEL}: no such wheel"
    return path


def _no_compiler_env(tmp: Path, bins=()):
    """os.environ less compilers and Python paths, PATH = the given dirs plus an empty one;
    checked to find no C compiler."""
    empty = tmp / "bin"
    empty.mkdir(exist_ok=True)
    path = os.pathsep.join([*(str(b) for b in bins), str(empty)])
    env = {k: v for k, v in os.environ.items() if k not in DROP}
    env.update(PATH=path, IMUFUSE_CACHE=str(tmp / "cache"))
    found = {c: shutil.which(c, path=path) for c in COMPILERS}
    assert not any(found.values()), f"a compiler on the test's PATH: {found}"
    return env


@pytest.fixture(scope="module")
def venv(wheel, tmp_path_factory):
    """A fresh venv (no system site packages) with the wheel and its dependency (numpy, from
    the index) installed where no C compiler is; (python, env, work directory)."""
    tmp = tmp_path_factory.mktemp("wheel-venv")
    d = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(d)], check=True, timeout=300)
    assert "include-system-site-packages = false" in (d / "pyvenv.cfg").read_text()
    env = _no_compiler_env(tmp, [d / "bin"])
    py = d / "bin" / "python"
    p = subprocess.run([str(py), "-m", "pip", "install", "-q", "--disable-pip-version-check",
                        str(wheel)], capture_output=True, text=True, env=env, timeout=600)
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-3000:]
    work = tmp / "work"
    work.mkdir()
    return py, env, work


def _py(venv, *args, timeout=300):
    py, env, work = venv
    return subprocess.run([str(py), *args], capture_output=True, text=True, env=env, cwd=work,
                          timeout=timeout)


def test_wheel_installs_and_imports_without_a_compiler(venv):
    """imufuse and every compiled module from the fresh venv, with numpy as the only other
    package; the C library and the harness data found through importlib.resources there."""
    py, _, _ = venv
    prefix = py.parent.parent.resolve()
    p = _py(venv, "-c", "import importlib, imufuse, imufuse_c\n"
            f"for m in {MODULES!r}: print(importlib.import_module(m).__file__)\n"
            "from imufuse.shared.resources import csrc_dir, mcu_data_dir\n"
            "print(imufuse.__file__, imufuse_c.__file__, csrc_dir(), mcu_data_dir(), sep='\\n')\n"
            "print(imufuse.__version__)")
    assert p.returncode == 0, p.stderr
    *paths, version = p.stdout.splitlines()
    assert version == imufuse.__version__
    for where in paths:
        assert Path(where).resolve().is_relative_to(prefix), where
    csrc = Path(paths[-2])
    assert (csrc / "CMakeLists.txt").is_file() and (csrc / "imf_version.h").is_file()
    pkgs = _py(venv, "-m", "pip", "list", "--format=freeze", "--disable-pip-version-check")
    names = {ln.split("==")[0].lower() for ln in pkgs.stdout.splitlines()}
    assert names - {"pip", "setuptools", "wheel"} == {"imufuse", "numpy"}, names
    assert _py(venv, "-c", "import cffi").returncode != 0      # the firmware extra is not in


def test_demo_runs_every_filter_from_the_wheel(venv):
    """The README's main job: every filter compiled against its reference bit for bit, then
    every three-axis filter on the shipped recording (no matplotlib: plots are skipped)."""
    p = _py(venv, "-m", "imufuse", "demo", "--no-plot")
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-3000:]
    assert re.search(r"^ok: 0 of \d+ bit-exact checks failed", p.stdout, re.M), p.stdout
    # x-io Fusion's current release among the filters compare runs by default
    assert re.search(r"^FusionAHRS13\s+ahrs\s", p.stdout, re.M), p.stdout


def test_run_and_compare_the_example_log_from_the_wheel(venv):
    _, _, work = venv
    p = _py(venv, "-c", "import imufuse.io; print(imufuse.io.example_log())")
    assert p.returncode == 0, p.stderr
    log = p.stdout.strip()
    out = work / "out.csv"
    p = _py(venv, "-m", "imufuse", "run", log, "-f", "MadgwickAHRS", "--dtype", "float32",
            "-o", str(out))
    assert p.returncode == 0, p.stderr
    lines = out.read_text().splitlines()
    assert len(lines) > 10_000 and "q0" in lines[0], lines[:2]
    p = _py(venv, "-m", "imufuse", "compare", log)
    assert p.returncode == 0, p.stderr
    assert re.search(r"^RobustAHRS\s", p.stdout, re.M), p.stdout


def _one_line_no_compiler(p):
    assert p.returncode == 5, (p.returncode, p.stdout, p.stderr)
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1, p.stderr
    msg = lines[0]
    assert msg.startswith("imufuse: error: ") and "C compiler" in msg, msg
    assert "apt install gcc" in msg and "CC" in msg, msg
    assert "Traceback" not in p.stderr
    return msg


def test_validate_without_a_compiler_says_so_in_one_line(venv):
    """`validate` compiles firmware on the host: without cffi and a compiler, one line names both
    (the extra to install, and how to get a compiler); with cffi (the firmware extra's
    package, a binary wheel) still exit 5, one line: a C compiler is needed."""
    args = ("-m", "imufuse", "validate", "--csrc", "-f", "Kalman1D", "--duration", "1")
    msg = _one_line_no_compiler(_py(venv, *args))
    assert "pip install 'imufuse[firmware]'" in msg, msg
    p = _py(venv, "-m", "pip", "install", "-q", "--disable-pip-version-check", "--only-binary",
            ":all:", "cffi", timeout=600)
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-3000:]
    msg = _one_line_no_compiler(_py(venv, *args))
    assert "cffi" not in msg, msg


def test_validate_without_a_compiler_here(tmp_path):
    """The same message from the suite's own installation (cffi installed): a PATH with no
    compiler on it is exit 5 and one line, never a failed subprocess or exit 3."""
    env = _no_compiler_env(tmp_path)
    p = subprocess.run([sys.executable, "-m", "imufuse", "validate", "--csrc", "-f", "Kalman1D",
                        "--duration", "1"], capture_output=True, text=True, env=env, cwd=tmp_path,
                       timeout=300)
    _one_line_no_compiler(p)


def _csrc_files(d: Path):
    """The library's files as the package data of pyproject.toml names them (a build
    directory inside csrc/, never shipped, left out)."""
    return sorted(str(p.relative_to(d)) for p in d.rglob("*")
                  if p.is_file() and p.relative_to(d).parts[0] != "build"
                  and (p.suffix in (".c", ".h") or p.name in ("CMakeLists.txt", "Makefile")))


def test_wheel_carries_the_c_library_and_no_host_library(wheel):
    """csrc/ inside the package (imufuse/csrc: every .c and .h, the CMake package's
    CMakeLists.txt, which installs imufuseConfig.cmake and imufuse.pc, and the Makefile) with the
    checkout's bytes, the MCU harness data, the shipped recording; the four compiled modules and
    no other shared object (auditwheel grafted no library of this host); a manylinux x86_64
    tag."""
    with zipfile.ZipFile(wheel) as z:
        names = set(z.namelist())
        want = _csrc_files(ROOT / "csrc")
        assert "CMakeLists.txt" in want and "Makefile" in want and "fixed/imf_fixed.h" in want
        got = sorted(n[len("imufuse/csrc/"):] for n in names
                     if n.startswith("imufuse/csrc/") and not n.endswith("/"))
        assert got == want
        for n in want:
            assert z.read(f"imufuse/csrc/{n}") == (ROOT / "csrc" / n).read_bytes(), n
        for n in ("imufuse/mcu/data/install-toolchains.sh", "imufuse/mcu/data/imf_driver_main.c",
                  "imufuse/data/broad_03_slow_rotation_45s.npz", "imufuse/py.typed",
                  "imufuse_c/__init__.pyi"):
            assert n in names, n
        shared = sorted(n for n in names if re.search(r"\.so(\.|$)", n))
        assert [n.split(".")[0] for n in shared] == [m.replace(".", "/") for m in sorted(MODULES)]
        assert not [n for n in names if ".libs/" in n.split("/", 1)[0] + "/"], "grafted libraries"
        (wheel_info,) = [n for n in names if n.endswith(".dist-info/WHEEL")]
        tags = re.findall(r"^Tag: (\S+)$", z.read(wheel_info).decode(), re.M)
    assert tags and all(re.fullmatch(r"cp3\d+-cp3\d+-manylinux_?\w*_x86_64", t) for t in tags), tags


def test_suite_runs_against_the_wheel(wheel):
    """The package this suite imports was installed from the repaired wheel, not built again."""
    with zipfile.ZipFile(wheel) as z:
        (info,) = [n for n in z.namelist() if n.endswith(".dist-info/WHEEL")]
        want = re.findall(r"^Tag: (\S+)$", z.read(info).decode(), re.M)
    got = re.findall(r"^Tag: (\S+)$", importlib.metadata.distribution("imufuse").read_text("WHEEL")
                     or "", re.M)
    assert got == want


def test_release_doc_names_the_wheel_tag(wheel):
    """docs/release.md states the platforms the wheel covers: its manylinux tag as built."""
    tags = re.search(r"-(manylinux[\w.]+)\.whl$", wheel.name)
    assert tags, wheel.name
    doc = (ROOT / "docs" / "release.md").read_text()
    for tag in tags.group(1).split("."):
        assert f"`{tag}`" in doc, (tag, "docs/release.md")
