"""The command line in the test's own process: ``imf_here(*args, cwd=None)`` runs
imufuse.cli.main() (what the console script and ``python -m imufuse`` run) and returns a
CompletedProcess with its exit code, stdout and stderr, for the tests that check messages and
exit codes; a test that needs what only a process shows (a crash, a signal, a closed pipe, the
entry point itself, a loaded firmware) starts one."""
import contextlib
import io as _io
import os
import subprocess

from imufuse import cli

__all__ = ["imf_here"]


def imf_here(*args, cwd=None):
    """The command line in this process: its main(), what the console script and `python -m
    imufuse` run, for the many files and arguments whose message and exit code are checked
    (0.4 s less each than a new interpreter, more with a plot); `imf` keeps what only a
    process shows (crashes, signals, a closed pipe, the entry point itself, a firmware
    loaded). cwd: the directory main() runs in."""
    out, errs = _io.StringIO(), _io.StringIO()
    with contextlib.chdir(cwd or os.getcwd()), contextlib.redirect_stdout(out), \
            contextlib.redirect_stderr(errs):
        rc = cli.main([str(a) for a in args])
    return subprocess.CompletedProcess(args, rc, out.getvalue(), errs.getvalue())
