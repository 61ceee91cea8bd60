"""The package as users get it: a complete sdist, csrc/ shipped inside the
package and found through importlib.resources, one version, and the firmware
tools working from any directory.

tools/test.sh runs the suite against a non-editable install of the sdist in a
fresh venv and sets IMUFUSE_TEST_INSTALLED to that venv: then the imported
packages must come from it, never from the checkout."""
import filecmp
import importlib.metadata
import os
import subprocess
import sys
import tarfile
from pathlib import Path

import pytest

import imufuse
import imufuse_c
from imufuse.shared.resources import csrc_dir, install_toolchains_script, mcu_data_dir

ROOT = Path(__file__).resolve().parents[1]
INSTALLED = os.environ.get("IMUFUSE_TEST_INSTALLED")


@pytest.mark.skipif(not INSTALLED, reason="IMUFUSE_TEST_INSTALLED unset: tools/test.sh sets it "
                    "when the suite runs against the installed sdist")
@pytest.mark.parametrize("module", [imufuse, imufuse_c], ids=lambda m: m.__name__)
def test_suite_imports_the_installed_package(module):
    where = Path(module.__file__).resolve()
    assert where.is_relative_to(Path(INSTALLED).resolve()), f"{module.__name__} from {where}"
    for src in (ROOT / "python", ROOT / "imufuse_c"):
        assert not where.is_relative_to(src), f"{module.__name__} imported from the checkout"


def _files(d):
    return sorted(str(p.relative_to(d)) for p in d.rglob("*")
                  if p.is_file() and p.suffix in (".c", ".h"))


def test_package_carries_csrc():
    """Every C file of the library, with the same contents as the checkout's."""
    got = csrc_dir()
    assert (got / "imf_config.h").is_file(), got
    names = _files(ROOT / "csrc")
    assert _files(got) == names
    match, mismatch, errors = filecmp.cmpfiles(ROOT / "csrc", got, names, shallow=False)
    assert not mismatch and not errors, (mismatch, errors)


def test_package_carries_mcu_data():
    assert (mcu_data_dir() / "imf_driver_main.c").is_file()
    assert install_toolchains_script().is_file()


def test_one_version():
    assert importlib.metadata.version("imufuse") == imufuse.__version__


def test_sdist_is_complete(tmp_path):
    """Everything the build needs (headers, .pyx, .pxi, .pxd) and nothing generated."""
    proc = subprocess.run([sys.executable, "setup.py", "-q", "sdist", "-d", str(tmp_path)],
                          cwd=ROOT, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    (sdist,) = tmp_path.glob("imufuse-*.tar.gz")
    with tarfile.open(sdist) as tar:
        top = f"imufuse-{imufuse.__version__}/"
        names = {n[len(top):] for n in tar.getnames()}
    tracked = subprocess.run(["git", "ls-files", "csrc", "imufuse_c", "python", "setup.py",
                              "pyproject.toml", "README.md"], cwd=ROOT,
                             capture_output=True, text=True)
    if tracked.returncode == 0 and tracked.stdout:   # a git checkout: every tracked file
        want = set(tracked.stdout.split())
    else:                                            # an unpacked sdist: the build's inputs
        want = {str(p.relative_to(ROOT)) for p in [*(ROOT / "csrc").rglob("*.[ch]"),
                                                    *(ROOT / "imufuse_c").glob("*.p*")]}
    assert not want - names, sorted(want - names)
    assert not {n for n in names if n.endswith((".so", ".o", ".pyc"))
                or n in ("imufuse_c/_f32.c", "imufuse_c/_f64.c", "imufuse_c/_fixed.c")}


def test_validate_csrc_from_any_directory(tmp_path):
    """`imufuse validate --csrc` without a directory validates the installed C library."""
    env = dict(os.environ, IMUFUSE_CACHE=str(tmp_path / "cache"))
    env.pop("PYTHONPATH", None)
    proc = subprocess.run([sys.executable, "-m", "imufuse", "validate", "--csrc", "-f", "KK",
                           "--dtype", "float32", "--duration", "1"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "bit-exact" in proc.stdout
