"""What bench/mcu/measure.py measures: one Case per filter configuration.

A filter joins by adding one entry to CASES (or calling register()): its C sources, the
harness Driver that steps it, and a function making inputs. The two entries here are the
harness's own test kernels; they show the shape.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path
from typing import Callable, Dict, List, Mapping, Optional, Sequence

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def load_mcu():
    """imufuse.mcu from the installed package, else from this source tree."""
    try:
        import imufuse.mcu as mcu
    except ImportError:
        src = ROOT / "python"
        sys.path.insert(0, str(src))
        import imufuse

        if str(src / "imufuse") not in list(imufuse.__path__):
            imufuse.__path__.append(str(src / "imufuse"))
        import imufuse.mcu as mcu
    return mcu


mcu = load_mcu()
EX = Path(mcu.__file__).resolve().parent / "examples"
CSRC = ROOT / "csrc"


@dataclasses.dataclass
class Case:
    sources: Sequence[Path]          # C files of the filter (sizes are reported per file)
    driver: "mcu.Driver"
    make_inputs: Callable[[int], Mapping[str, np.ndarray]]
    step_function: str               # C function whose -fstack-usage frame is reported
    include_dirs: Sequence[Path] = ()
    defines: Optional[Mapping[str, object]] = None
    targets: Sequence[str] = ("m4f", "m0", "avr")


def _imu_inputs(n: int) -> Dict[str, np.ndarray]:
    rng = np.random.default_rng(1)
    gyr = rng.normal(0, 0.5, (n, 3)).astype(np.float32)
    acc = (rng.normal(0, 0.05, (n, 3)) + [0, 0, 1]).astype(np.float32)
    return {"gyr": gyr, "acc": acc}


def _int_inputs(n: int) -> Dict[str, np.ndarray]:
    rng = np.random.default_rng(2)
    return {
        "rate": rng.integers(-2000, 2000, n).astype(np.int16),
        "angle": rng.integers(-8000, 8000, n).astype(np.int16),
    }


CASES: Dict[str, Case] = {
    "example_quat_f32": Case(
        sources=[EX / "imk_quat.c"],
        include_dirs=[EX],
        driver=mcu.Driver(
            prelude='#include "imk_quat.h"\nstatic imk_quat_t k;',
            init="imk_quat_init(&k, 1.0f / 512.0f, 2.0f);",
            step="imk_quat_update(&k, gyr, acc);",
            state=mcu.state_words("k.q", "f32", 4),
        ),
        make_inputs=_imu_inputs,
        step_function="imk_quat_update",
    ),
    "example_int16_i32": Case(
        sources=[EX / "imk_int.c"],
        include_dirs=[EX],
        driver=mcu.Driver(
            prelude='#include "imk_int.h"\nstatic imk_int_t k;',
            init="imk_int_init(&k);",
            step="imk_int_update(&k, rate, angle);",
            state=[("k.angle", "i32")],
        ),
        make_inputs=_int_inputs,
        step_function="imk_int_update",
    ),
}

# A library filter joins like this (once csrc/madgwick.c exists):
#
# CASES["MadgwickIMU_f32"] = Case(
#     sources=[CSRC / "madgwick.c"],
#     include_dirs=[CSRC],
#     driver=mcu.Driver(
#         prelude='#include "madgwick.h"\nstatic imf_madgwick_imu_t f;',
#         init="imf_madgwick_imu_init(&f, 1.0f / 512.0f, 0.1f);",
#         step="imf_madgwick_imu_update(&f, gyr, acc);",
#         state=mcu.state_words("f.q", "f32", 4),
#     ),
#     make_inputs=_imu_inputs,
#     step_function="imf_madgwick_imu_update",
# )


def register(name: str, case: Case) -> None:
    if name in CASES:
        raise ValueError(f"case {name!r} already registered")
    CASES[name] = case


def names() -> List[str]:
    return sorted(CASES)
