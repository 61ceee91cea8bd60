"""The C house style: every file of csrc/ is as clang-format (.clang-format, the version pinned in
the test extra) writes it. tools/test.sh runs the same check before the suite."""
import glob
import os
import shutil
import subprocess
import sys

import pytest

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
FILES = sorted(glob.glob(os.path.join(ROOT, "csrc", "*.[ch]"))
               + glob.glob(os.path.join(ROOT, "csrc", "fixed", "*.[ch]"))
               + glob.glob(os.path.join(ROOT, "csrc", "hil", "*.[ch]")))
pytest.importorskip("clang_format", reason="clang-format is in the test extra "
                                           "(pip install 'imufuse[test]')")
# the wheel's binary, through its module (the venv's bin/ need not be on PATH)
TOOL = [sys.executable, "-c",
        "import clang_format, sys; sys.argv[0] = 'clang-format'; clang_format.clang_format()"]


def test_csrc_is_formatted():
    assert len(FILES) > 30
    version = subprocess.run([*TOOL, "--version"], capture_output=True, text=True).stdout
    assert "18.1.8" in version, version
    r = subprocess.run([*TOOL, "--dry-run", "-Werror", "--style=file", *FILES], cwd=ROOT,
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-3000:]


def test_the_check_can_fail(tmp_path):
    """A drifted continuation line is reported."""
    bad = tmp_path / "bad.c"
    bad.write_text("int f(int a,\n          int b)\n{\n    return a + b;\n}\n")
    shutil.copy(os.path.join(ROOT, ".clang-format"), tmp_path / ".clang-format")
    r = subprocess.run([*TOOL, "--dry-run", "-Werror", "--style=file", str(bad)], cwd=tmp_path,
                       capture_output=True, text=True)
    assert r.returncode != 0
