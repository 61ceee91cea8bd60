"""Command-line polish: --version, filter names in any case with suggestions from the listed
names, help for users (no developer notes), and validate without cffi naming the extra."""
import os
import subprocess
import sys

import pytest

import imufuse
from imufuse import catalogue
from imufuse.io import example_log


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "imufuse", *args], capture_output=True, text=True)


def test_version():
    p = _cli("--version")
    assert p.returncode == 0 and p.stdout.strip() == f"imufuse {imufuse.__version__}"


def test_help_is_for_users():
    p = _cli("--help")
    assert p.returncode == 0 and "Adding a subcommand" not in p.stdout and "export" in p.stdout


@pytest.mark.parametrize("given", ["madgwickahrs", "MADGWICKAHRS", "MadgwickAHRS"])
def test_filter_names_in_any_case(tmp_path, given):
    p = _cli("run", example_log(), "-f", given, "--dtype", "float32", "-o", str(tmp_path / "o.npz"))
    assert p.returncode == 0, p.stderr
    assert "MadgwickAHRS (c, float32" in p.stderr


def test_suggestions_come_from_the_listed_names():
    with pytest.raises(catalogue.FilterError) as e:
        catalogue.entry("madgwikahrs")
    msg = str(e.value)
    assert "did you mean MadgwickAHRS" in msg
    hinted = msg.split("did you mean ")[1].split("?")[0].split(", ")
    listed = msg.split("valid filters: ")[1].replace("; fixed point: ", ", ").split(", ")
    assert set(hinted) <= set(listed)
    assert catalogue.canonical_name("mahonyimuq") == "MahonyIMUQ"
    assert catalogue.canonical_name("nosuchfilter") == "nosuchfilter"


def test_validate_without_cffi_names_the_extra(tmp_path):
    """cffi hidden from the interpreter: exit 5 with the extra to install, not an internal error."""
    (tmp_path / "cffi.py").write_text("raise ImportError('cffi hidden by the test')\n")
    code = ("import sys; sys.path.insert(0, %r); from imufuse.cli import main; "
            "sys.exit(main(['validate', '--csrc', '-f', 'Kalman1D', '--duration', '1']))"
            % str(tmp_path))
    env = {**os.environ, "IMUFUSE_CACHE": str(tmp_path / "cache")}   # nothing built before
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert p.returncode == 5, p.stderr
    assert "pip install 'imufuse[firmware]'" in p.stderr and "internal error" not in p.stderr
