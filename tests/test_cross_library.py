"""VQF's C++ as published (the vqf 2.1.2 sdist from PyPI, fetched and SHA-256 checked by
bench/mcu/peers.py, never committed), in single precision, through
examples/declarations/vqf-2.1.2.toml with no shim: the same C++ on the Cortex-M4F against the
host (firmware against firmware, imufuse.firmware.compare_firmware), the divergence and its
causes named (bench/mcu/cross_library.py puts the same comparison in its table, every core).

An unreachable PyPI skips, or fails with IMUFUSE_REQUIRE_ORACLE=1 (as tests/fusion_oracle.py).
"""
import os
from pathlib import Path

import numpy as np
import pytest

from imufuse import sim
from imufuse.firmware import compare_firmware, load_declaration, validate_isolated
from imufuse.mcu import ensure_toolchains

import peers  # bench/mcu/peers.py (on the suite's pythonpath: pyproject.toml)

VQF = "VQF 2.1.2 (float32)"


@pytest.fixture(scope="module")
def vqf_dir():
    missing = ensure_toolchains(["m4f"])
    assert not missing, f"MCU toolchains missing: {missing}"
    try:
        return str(peers.fetch(VQF))
    except peers.Unavailable as e:
        if os.environ.get("IMUFUSE_REQUIRE_ORACLE"):
            pytest.fail(str(e))
        pytest.skip(str(e))


@pytest.fixture(scope="module")
def motion():
    s = sim.imu("fast", rate=100.0, duration=3.0, seed=3)
    return s.dt, [np.asarray(s.gyr), np.asarray(s.acc), np.asarray(s.mag)]


def _run(vqf_dir, motion, target, flags=None):
    d = load_declaration(peers.PEERS[VQF].declaration_path, source_dir=vqf_dir)
    if flags is not None:
        d.firmware.cflags = d.firmware.cflags_given = list(flags)
    dt, ins = motion
    return validate_isolated(d.firmware, d.filter, dict(d.params, dt=dt), ins, target=target,
                             explain=False)


@pytest.fixture(scope="module")
def host(vqf_dir, motion):
    return _run(vqf_dir, motion, "host")


def test_the_sdist_is_the_pinned_one(vqf_dir):
    """The sources come from the pinned sdist (its SHA-256 checked) and are VQF's C++."""
    assert (Path(vqf_dir) / "vqf.cpp").is_file() and "VQF_SINGLE_PRECISION" in \
        (Path(vqf_dir) / "vqf.hpp").read_text()
    assert len(peers.PEERS[VQF].sha256) == 64


def test_gnu_defaults_on_the_m4f_diverge_by_fma_and_libm(vqf_dir, motion, host):
    """Built as a firmware build is (-O2, gnu defaults), VQF on the M4F differs from its host
    build (-O2 -ffp-contract=off) from the first sample, by rounding: the report names the
    M4F's vfma.f32 contraction and the transcendental functions of newlib."""
    m4f = _run(vqf_dir, motion, "cortex-m4f")
    v = compare_firmware(host, m4f, "host", "cortex-m4f")
    assert not v.bit_exact
    text = v.text()
    assert "rounding" in text
    assert any("fused multiply-add" in n and "vfma.f32" in n for n in v.notes), text
    assert any("libm" in n and "cosf" in n for n in v.notes), text
    assert 0 < v.max_angle_deg < 1e-3, text
    assert m4f.cost.unit == "instructions" and m4f.cost.median > 1000


def test_contraction_off_leaves_the_libm_difference(vqf_dir, motion, host):
    """With -ffp-contract=off on the M4F too the fused multiply-add is gone from the causes;
    newlib's cosf/sinf/atan2f against glibc's still differ in the last bit (a few ulps, no
    growth), which no flag removes."""
    m4f = _run(vqf_dir, motion, "cortex-m4f", ["-O2", "-ffp-contract=off"])
    v = compare_firmware(host, m4f, "host", "cortex-m4f")
    assert not v.bit_exact
    assert not any("fused multiply-add" in n for n in v.notes), v.text()
    assert any("libm" in n for n in v.notes), v.text()
    assert v.max_angle_deg < 1e-4, v.text()
