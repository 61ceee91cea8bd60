"""Building harness programs for a target."""
from __future__ import annotations

import os
import subprocess
import tempfile
from pathlib import Path
from typing import Dict, Iterable, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from .driver import Driver
from .inputs import _inputs_header
from .toolchains import (DATA_DIR, HarnessError, Target, ToolchainMissing, _SECTION_FLAGS, _require,
                         _target, cflags, linker_script)

def _run_cmd(cmd: Sequence[str], cwd: Optional[Path] = None, timeout: float = 300) -> subprocess.CompletedProcess:
    try:
        proc = subprocess.run(list(cmd), cwd=cwd, capture_output=True, text=True, timeout=timeout)
    except FileNotFoundError as e:
        raise ToolchainMissing(f"{cmd[0]} not found; run tools/install-toolchains.sh") from e
    if proc.returncode != 0:
        raise HarnessError(
            f"command failed ({proc.returncode}): {' '.join(map(str, cmd))}\n{proc.stdout}{proc.stderr}"
        )
    return proc


def _as_paths(xs: Optional[Iterable[Union[str, os.PathLike]]]) -> List[Path]:
    return [Path(x).resolve() for x in (xs or [])]


def _define_flags(defines: Optional[Mapping[str, object]]) -> List[str]:
    out = []
    for k, v in (defines or {}).items():
        out.append(f"-D{k}" if v is None or v is True else f"-D{k}={v}")
    return out


def _compile(
    tgt: Target,
    src: Path,
    obj: Path,
    include_dirs: Sequence[Path],
    defines: Sequence[str],
    extra: Sequence[str] = (),
    objects: Optional[Dict[Tuple[str, ...], Tuple[bytes, bytes]]] = None,
    generated: Optional[Path] = None,
) -> None:
    """Compile src to obj (and obj's .su with -fstack-usage).

    objects: the objects compiled before by the same command, {command: (object, .su)}: a
    source compiled again with the same compiler, flags, defines and include directories is
    copied from there. The directory of the generated headers (``generated``: a program's
    imf_inputs.h and imf_driver.h) is left out of the command compared; only sources that
    include neither header (the code under test, the port files) may be given a cache."""
    cmd = [tgt.cc, *cflags(tgt.name), *_SECTION_FLAGS, *extra, *defines]
    cmd += [f"-I{d}" for d in include_dirs]
    cmd += ["-c", str(src)]
    key = tuple(c for c in cmd if generated is None or c != f"-I{generated}")
    su = obj.with_suffix(".su")
    if objects is not None and key in objects:
        obj.write_bytes(objects[key][0])
        su.write_bytes(objects[key][1])
        return
    _run_cmd([*cmd, "-o", str(obj)], cwd=obj.parent)
    if objects is not None:
        objects[key] = (obj.read_bytes(), su.read_bytes() if su.exists() else b"")


def build(
    target: str,
    sources: Sequence[Union[str, os.PathLike]] = (),
    include_dirs: Sequence[Union[str, os.PathLike]] = (),
    defines: Optional[Mapping[str, object]] = None,
    driver: Union[Driver, str, None] = None,
    inputs: Optional[Mapping[str, np.ndarray]] = None,
    n: Optional[int] = None,
    workdir: Union[str, os.PathLike, None] = None,
    extra_cflags: Sequence[str] = (),
    objects: Optional[Dict[Tuple[str, ...], Tuple[bytes, bytes]]] = None,
) -> Path:
    """Build the driver program for ``target``; returns the path of the ELF (host: executable).

    sources: the C files under test (compiled with the harness flags, e.g. csrc/madgwick.c).
    driver:  a ``Driver`` or C source text defining imf_user_init/step/dump.
    inputs:  {name: array}; see ``Driver`` for how they appear in C.
    workdir: where objects, .su files and the ELF go (default: a new temporary directory).
    objects: a cache of compiled sources and port files shared by builds of the same sources
             with the same flags ({}: empty; run_filters' programs), see _compile; the driver
             (which includes the inputs) is compiled every time.
    """
    tgt = _target(target)
    _require(tgt, [tgt.cc])
    if driver is None:
        raise ValueError("driver is required (a Driver or C source text)")
    wd = Path(workdir) if workdir is not None else Path(tempfile.mkdtemp(prefix=f"imf_mcu_{target}_"))
    wd.mkdir(parents=True, exist_ok=True)
    header, n = _inputs_header(inputs or {}, target, n)
    (wd / "imf_inputs.h").write_text(header)
    drv_src = driver.c_source() if isinstance(driver, Driver) else str(driver)
    (wd / "imf_driver.h").write_text(drv_src)
    incs = [wd, DATA_DIR, *_as_paths(include_dirs)]
    defs = _define_flags(defines)

    objs: List[Path] = []
    for i, src in enumerate(_as_paths(sources)):
        obj = wd / f"u{i}_{src.stem}.o"
        _compile(tgt, src, obj, incs, defs, ["-fstack-usage", *extra_cflags], objects, wd)
        objs.append(obj)
    for name in (*tgt.sources, "imf_driver_main.c"):
        obj = wd / f"h_{Path(name).stem}.o"
        _compile(tgt, DATA_DIR / name, obj, incs, defs, ["-fstack-usage", *extra_cflags],
                 None if name == "imf_driver_main.c" else objects, wd)
        objs.append(obj)

    elf = wd / f"imf_{target}.elf"
    cmd = [tgt.cc, *tgt.arch_flags, *tgt.link_flags]
    script = linker_script(tgt)
    if script is not None:
        ld = wd / "imf.ld"
        ld.write_text(script)
        cmd += [f"-T{ld}"]
    cmd += [str(o) for o in objs] + ["-o", str(elf), "-lm"]
    try:
        _run_cmd(cmd, cwd=wd)
    except HarnessError as e:
        if "overflowed" in str(e) or "will not fit" in str(e):
            raise HarnessError(
                f"{e}\n{target}: the program does not fit ({tgt.flash} bytes flash, {tgt.ram} bytes "
                "RAM); inputs are stored in flash: pass fewer samples (or int16 inputs)"
            ) from None
        raise
    return elf
