"""Measurements: code size, stack usage, host instruction counts."""
from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import Dict, Mapping, Optional, Sequence, Union

import numpy as np

from .programs import _as_paths, _compile, _define_flags, _run_cmd, build
from .driver import Driver
from .toolchains import HarnessError, ToolchainMissing, _require, _target

def code_size(
    target: str,
    sources: Sequence[Union[str, os.PathLike]],
    include_dirs: Sequence[Union[str, os.PathLike]] = (),
    defines: Optional[Mapping[str, object]] = None,
    workdir: Union[str, os.PathLike, None] = None,
) -> Dict[str, Dict[str, int]]:
    """text/data/bss bytes of each source's object (keys: file names) and ``"total"``.

    Built with the harness flags plus -ffunction-sections; library calls (soft float, sqrtf)
    are not included: they are linked from libgcc/libm.
    """
    tgt = _target(target)
    _require(tgt, [tgt.cc, tgt.size_tool])
    own = workdir is None
    wd = Path(tempfile.mkdtemp(prefix=f"imf_size_{target}_")) if workdir is None else Path(workdir)
    wd.mkdir(parents=True, exist_ok=True)
    try:
        objs = []
        for i, src in enumerate(_as_paths(sources)):
            obj = wd / f"s{i}_{src.stem}.o"
            _compile(tgt, src, obj, _as_paths(include_dirs), _define_flags(defines))
            objs.append((src.name, obj))
        out = _run_cmd([tgt.size_tool, "-B", *[str(o) for _, o in objs]]).stdout
        result: Dict[str, Dict[str, int]] = {}
        total = {"text": 0, "data": 0, "bss": 0}
        lines = [ln.split() for ln in out.strip().splitlines()[1:]]
        for (name, _), cols in zip(objs, lines):
            d = {"text": int(cols[0]), "data": int(cols[1]), "bss": int(cols[2])}
            result[name] = d
            for k in total:
                total[k] += d[k]
        result["total"] = total
        return result
    finally:
        if own:
            shutil.rmtree(wd, ignore_errors=True)


def stack_usage(
    target: str,
    sources: Sequence[Union[str, os.PathLike]],
    include_dirs: Sequence[Union[str, os.PathLike]] = (),
    defines: Optional[Mapping[str, object]] = None,
    workdir: Union[str, os.PathLike, None] = None,
) -> Dict[str, Dict[str, object]]:
    """Static stack use per function from -fstack-usage: {function: {"bytes": n, "kind": q}}.

    kind is GCC's qualifier ("static", "dynamic", "dynamic,bounded"). Callees are not added:
    the figure is each function's own frame.
    """
    tgt = _target(target)
    _require(tgt, [tgt.cc])
    own = workdir is None
    wd = Path(tempfile.mkdtemp(prefix=f"imf_stack_{target}_")) if workdir is None else Path(workdir)
    wd.mkdir(parents=True, exist_ok=True)
    try:
        result: Dict[str, Dict[str, object]] = {}
        for i, src in enumerate(_as_paths(sources)):
            obj = wd / f"k{i}_{src.stem}.o"
            _compile(tgt, src, obj, _as_paths(include_dirs), _define_flags(defines), ["-fstack-usage"])
            for line in obj.with_suffix(".su").read_text().splitlines():
                parts = line.split("\t")
                if len(parts) != 3:
                    continue
                func = parts[0].rsplit(":", 1)[-1]
                result[func] = {"bytes": int(parts[1]), "kind": parts[2], "file": src.name}
        return result
    finally:
        if own:
            shutil.rmtree(wd, ignore_errors=True)


def callgrind_instructions(
    sources: Sequence[Union[str, os.PathLike]] = (),
    include_dirs: Sequence[Union[str, os.PathLike]] = (),
    defines: Optional[Mapping[str, object]] = None,
    driver: Union[Driver, str, None] = None,
    inputs: Optional[Mapping[str, np.ndarray]] = None,
    n: Optional[int] = None,
    workdir: Union[str, os.PathLike, None] = None,
    timeout: float = 300.0,
) -> Dict[str, float]:
    """Host instructions per update: the host build under valgrind --tool=callgrind.

    Counts the instructions executed inside the driver's step wrapper (imf_step, the
    user's step and everything it calls), for all samples. Returns
    {"total": Ir, "samples": N, "per_update": Ir / N}.
    """
    if shutil.which("valgrind") is None:
        raise ToolchainMissing("valgrind not found; run tools/install-toolchains.sh")
    own = workdir is None
    wd = Path(tempfile.mkdtemp(prefix="imf_cg_")) if workdir is None else Path(workdir)
    try:
        if n is None and inputs:
            n = len(np.asarray(next(iter(inputs.values()))))
        # -fno-inline-functions-called-once keeps imf_step a separate function to toggle on.
        exe = build("host", sources, include_dirs, defines, driver, inputs, n, wd)
        outfile = wd / "callgrind.out"
        cmd = [
            "valgrind", "--tool=callgrind", f"--callgrind-out-file={outfile}",
            "--collect-atstart=no", "--toggle-collect=imf_step", str(exe),
        ]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=wd)
        if proc.returncode != 0:
            raise HarnessError(f"callgrind failed: {proc.stderr[-2000:]}")
        total = None
        for line in outfile.read_text().splitlines():
            if line.startswith("totals:") or line.startswith("summary:"):
                total = int(line.split()[1])
        if total is None:
            raise HarnessError("callgrind output has no totals")
        return {"total": total, "samples": int(n or 0), "per_update": total / float(n or 1)}
    finally:
        if own:
            shutil.rmtree(wd, ignore_errors=True)
