"""Build and run the fixed-point C test drivers (gcc, optionally UBSan)."""
from __future__ import annotations

import functools
import os
import pathlib
import shutil
import subprocess
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[2]
FIXED = ROOT / "csrc" / "fixed"
HERE = pathlib.Path(__file__).resolve().parent

CFLAGS = ["-std=c99", "-O2", "-ffp-contract=off", "-Wall", "-Wextra", "-Werror",
          "-Wconversion", "-Wshadow"]
UBSAN = ["-fsanitize=undefined", "-fsanitize=signed-integer-overflow,shift",
         "-fno-sanitize-recover"]
# IMF_FIXED_UBSAN=0 builds the drivers without the sanitizer (faster runs).
USE_UBSAN = os.environ.get("IMF_FIXED_UBSAN", "1") != "0"


def have_gcc() -> bool:
    return shutil.which("gcc") is not None


@functools.lru_cache(maxsize=None)
def build(driver: str, ubsan: bool = USE_UBSAN) -> pathlib.Path:
    out = pathlib.Path(tempfile.mkdtemp(prefix="imf_fixed_")) / driver
    srcs = [str(HERE / f"{driver}.c")] + sorted(str(p) for p in FIXED.glob("*.c"))
    cmd = ["gcc", *CFLAGS, *(UBSAN if ubsan else []), f"-I{FIXED}", *srcs, "-o", str(out), "-lm"]
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    return out


def run(driver: str, text: str) -> str:
    exe = build(driver)
    p = subprocess.run([str(exe)], input=text, capture_output=True, text=True)
    if p.returncode != 0 or "runtime error" in p.stderr:
        raise AssertionError(f"{driver} failed (rc={p.returncode}):\n{p.stderr[-4000:]}")
    return p.stdout
