"""x-io Fusion 1.3's C as published (the imufusion 1.3.3 sdist, pinned and hash-checked by
tests/fusion13_oracle.py), through examples/declarations/fusion-1.3.3.toml, unmodified:
bit-exact with imufuse's FusionAHRS13 on the host, the Cortex-M4F with -ffp-contract=off, the
Cortex-M0 and the ATmega328P (avr-libc's sinf, cosf, atan2f and asinf, the functions a
difference could come from, give the same bits on this run), every state member after every
sample; on the M4F with GCC's defaults the fused multiply-add is named.

Interim harness: imufuse.firmware's validate knows the 1.2.3 class (FusionAHRS) by name; the
fixture below teaches it FusionAHRS13 the same way (its entry: Fusion's units, the settings
as the C init values, the period given with every update) until validate reads every Fusion
class of the catalogue.
"""
import importlib
import os
import sys
import tarfile

import numpy as np
import pytest

import imufuse_c
from imufuse import reference, sim
from imufuse.catalogue import inputs_for
from imufuse.firmware import declfile, isolate, validate_isolated
from imufuse.firmware.declfile import load_declaration
from imufuse.mcu import ensure_toolchains

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)          # tests/fusion13_oracle.py
import fusion13_oracle  # noqa: E402

validate_mod = importlib.import_module("imufuse.firmware.validate")
DECLARATION = os.path.join(os.path.dirname(HERE), "examples", "declarations",
                           "fusion-1.3.3.toml")

pytestmark = [pytest.mark.xdist_group("declared_target"), pytest.mark.emulator,
              pytest.mark.slow]


class _Fusion13Entry(validate_mod._FusionEntry):
    name = "FusionAHRS13"

    def __init__(self):
        self.reference = reference.FusionAHRS13
        self.state_names = tuple(reference.FusionAHRS13.state_names)

    def make(self, backend, dtype, params):
        mod = imufuse_c if backend == "c" else reference
        return mod.FusionAHRS13(**self.settings(params), dtype=dtype)


@pytest.fixture(autouse=True)
def _validate_knows_fusion13(monkeypatch):
    entry = _Fusion13Entry()
    known = validate_mod._filter_entry

    def filter_entry(name):
        return entry if name == entry.name else known(name)

    monkeypatch.setattr(validate_mod, "_filter_entry", filter_entry)
    monkeypatch.setattr(isolate, "_filter_entry", filter_entry)
    monkeypatch.setattr(declfile, "_filter_entry", filter_entry)
    monkeypatch.setattr(declfile, "FUSION", entry.name)


@pytest.fixture(scope="module")
def fusion_dir(tmp_path_factory):
    sdist = fusion13_oracle.fetch_sdist()
    d = tmp_path_factory.mktemp("fusion13")
    with tarfile.open(sdist) as tar:
        for m in tar.getmembers():
            if m.name.startswith(f"imufusion-{fusion13_oracle.VERSION}/Fusion/") and m.isfile():
                (d / os.path.basename(m.name)).write_bytes(tar.extractfile(m).read())
    return str(d)


def _validate(fusion_dir, target, flags=None, seconds=3.0):
    d = load_declaration(DECLARATION, source_dir=fusion_dir)
    if flags is not None:
        d.firmware.cflags = d.firmware.cflags_given = list(flags)
    s = sim.imu("fast", rate=200.0, duration=seconds, seed=3)
    g, a, m = inputs_for("ahrs", s)
    return validate_isolated(d.firmware, d.filter, dict(d.params, dt=s.dt),
                             [np.degrees(g), a, m], target=target)


def test_fusion13_as_published_is_bit_exact_on_the_host(fusion_dir):
    v = _validate(fusion_dir, "host")
    assert v.bit_exact, v.text()
    assert len(v.comparison.names) == 23


@pytest.mark.parametrize("target,flags", [("cortex-m4f", ["-O2", "-ffp-contract=off"]),
                                          ("cortex-m0", None), ("atmega328p", None)])
def test_fusion13_as_published_on_the_mcus(fusion_dir, target, flags):
    missing = ensure_toolchains(("m4f", "m0", "avr"))
    assert not missing, f"MCU toolchains missing: {missing}"
    v = _validate(fusion_dir, target, flags)
    assert v.bit_exact, v.text()
    assert len(v.comparison.names) == 23


def test_fusion13_fma_is_named_on_the_m4f(fusion_dir):
    """Under GCC's defaults the M4F fuses multiply-adds: not bit-exact, and validate says why."""
    v = _validate(fusion_dir, "cortex-m4f", seconds=2.0)
    assert not v.bit_exact
    assert any(c.what == "fma" and c.confirmed for c in v.causes), v.text()
