"""What bench/mcu/measure.py measures (imufuse and imufuse.mcu of the checkout: an editable
install, or PYTHONPATH=python).

FILTER_SPECS: every library filter configuration of imufuse.registry in each precision
(float32, float64; fixed-point profiles), derived generically. CASES: hand-written Cases (C
sources, a harness Driver, an input maker); the two entries are the harness's own test kernels.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Callable, Dict, List, Mapping, Optional, Sequence

import numpy as np

import imufuse.mcu as mcu
from imufuse import registry
from imufuse.mcu import filters as mf

ROOT = Path(__file__).resolve().parents[2]
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
    targets: Sequence[str] = ("m4f", "m0", "avr", "m3", "m7", "m33", "m55", "rv32imac",
                              "rv32imafc")


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


# ---- the Fusion suite (Longbin's Fusion walkthrough): its update takes dt and Fusion's units, so it is a
# hand-written case (imufuse.registry keeps it out of the generic matrix, see FUSION_CASES)

def _fusion_inputs(n: int) -> Dict[str, np.ndarray]:
    rng = np.random.default_rng(3)
    gyr = rng.normal(0, 30.0, (n, 3)).astype(np.float32)            # deg/s
    acc = (rng.normal(0, 0.2, (n, 3)) + [0, 0, 1]).astype(np.float32)  # g
    mag = (rng.normal(0, 0.1, (n, 3)) + [0.4, 0, -0.8]).astype(np.float32)
    return {"gyr": gyr, "acc": acc, "mag": mag}


_FUSION_STATE = (mcu.state_words("((const float *)(const void *)&k.x)", "f32", 14)
                 + [(f"((const int32_t *)(const void *)&k.x)[{14 + j}]", "i32") for j in range(8)]
                 + [("k.skipped", "u32")])

CASES["fusion_ahrs_f32"] = Case(
    sources=[CSRC / "fusion_ahrs.c"],
    include_dirs=[CSRC],
    driver=mcu.Driver(
        prelude='#include "fusion_ahrs.h"\nstatic imf_fusion_ahrs_t k;',
        init=("imf_fusion_ahrs_settings_t s;\nimf_fusion_ahrs_default_settings(&s);\n"
              "s.gain = 0.5f; s.gyroscope_range = 2000.0f; s.acceleration_rejection = 10.0f;\n"
              "s.magnetic_rejection = 10.0f; s.recovery_trigger_period = 500;\n"
              "imf_fusion_ahrs_init(&k, &s, IMF_FUSION_INVSQRT_EXACT);"),
        step=("imf_fusion_ahrs_update(&k, gyr[0], gyr[1], gyr[2], acc[0], acc[1], acc[2], "
              "mag[0], mag[1], mag[2], 0.01f);"),
        state=_FUSION_STATE,
    ),
    make_inputs=_fusion_inputs,
    step_function="imf_fusion_ahrs_update",
)

#: hand-written cases that are library filters (not harness examples): measure.py runs them
#: with the generic filters, under this class name
LIBRARY_CASES = {"fusion_ahrs_f32": "FusionAHRS"}

# ---- every filter configuration of imufuse.registry, generically -------------------------
#
# Each (configuration, precision) becomes a FilterSpec (imufuse.mcu.filters): the driver, the
# sources and the inputs come from the reference class (c_name, kind, state_names, _params) and
# the C headers. A filter joins by appearing in imufuse.registry, nothing here.

FILTER_SPECS: Dict[str, "mf.FilterSpec"] = {
    s.label: s
    for s in mf.specs_from_cases([*registry.FLOAT_CASES, *registry.FIXED_CASES,
                                  *registry.CASES_VARIO[:2]])
}


def register(name: str, case: Case) -> None:
    if name in CASES:
        raise ValueError(f"case {name!r} already registered")
    CASES[name] = case


def names() -> List[str]:
    """The harness's own example kernels (CASES)."""
    return sorted(CASES)


def filter_names() -> List[str]:
    """Every library filter configuration and precision, in registry order."""
    return list(FILTER_SPECS)
