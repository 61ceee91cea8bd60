"""The inner loop's guard (tests/conftest.py, _Spawns): what a test starts is classified as an
emulator, a build or neither, so that a test not marked slow that starts one fails."""
import os
import shutil
import subprocess
import sys

import pytest

import conftest

K = conftest._Spawns.kind


@pytest.mark.parametrize("args,want", [
    (["qemu-system-arm", "-M", "mps2-an386"], "emulator: qemu-system-arm"),
    (["/usr/bin/simavr", "-m", "atmega328p", "fw.elf"], "emulator: simavr"),
    (["/usr/bin/arm-none-eabi-gcc", "-c", "a.c"], "build: arm-none-eabi-gcc"),
    (["avr-objcopy", "-O", "ihex"], "build: avr-objcopy"),
    ("gcc -O2 -c a.c", "build: gcc"),
    ([b"cc", b"-c", b"a.c"], "build: cc"),
    ([sys.executable, "setup.py", "build_ext"], "build: setup.py"),
    ([sys.executable, "-m", "imufuse", "validate", "fw.json"], "build: imufuse validate"),
    ([sys.executable, "-m", "imufuse", "validate", "fw.json", "--target", "atmega328p"],
     "emulator: imufuse validate"),
    ([sys.executable, "-m", "imufuse", "run", "log.csv"], None),
    ([sys.executable, "-c", "print(1)"], None),
    (["git", "status"], None),
    ([], None),
])
def test_what_a_test_starts_is_classified(args, want):
    assert K(args) == want


def test_a_start_is_recorded_for_the_running_test():
    """Every Popen of this process goes through the guard: `cc --version` started here is in
    the running test's list (taken out again before the teardown reads it, or this test would
    fail as one that starts a compiler), `true` is not."""
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler to start (tools/install-toolchains.sh installs gcc)")
    subprocess.run(["true"], check=True)
    assert not conftest._SPAWNS.seen
    subprocess.run([cc, "--version"], check=True, capture_output=True)
    try:
        assert conftest._SPAWNS.seen == [f"build: {os.path.basename(cc)}"]
    finally:
        conftest._SPAWNS.seen.clear()
