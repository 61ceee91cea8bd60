"""A firmware team's own tests with imufuse.testing (docs/firmware.md).

Run from this directory:  pytest test_cf_firmware.py
cf.c is the firmware under test: Eq. 2.2 of the article, as firmware writes it. Each test
builds it for a target with the flags of the firmware's build and compares every state
variable after every sample with imufuse's Complementary1D.
"""
import os

import pytest

from imufuse.testing import target_missing, validate_firmware

HERE = os.path.dirname(os.path.abspath(__file__))
FIRMWARE = dict(sources=[os.path.join(HERE, "cf.c")], headers=["cf.h"], include_dirs=[HERE],
                init="cf_init", update="cf_update", state={"theta": "theta"},
                filter="Complementary1D", params={"T": 0.5}, rate=200.0, duration=20.0)


@pytest.mark.parametrize("target", ["host", "cortex-m4f", "cortex-m0", "atmega328p"])
def test_bit_exact_with_the_release_flags(target):
    why = target_missing(target)
    if why:
        pytest.skip(why)
    r = validate_firmware(**FIRMWARE, target=target, cflags="-O2 -ffp-contract=off")
    r.assert_bit_exact()
    if target != "host":
        r.assert_cost(max_per_update=2000, max_stack=128)


def test_gnu_defaults_on_the_m4f_stay_within_a_microdegree():
    """Plain -O2 (gnu17) fuses multiply-adds on the Cortex-M4F: not bit-exact, but close."""
    why = target_missing("cortex-m4f")
    if why:
        pytest.skip(why)
    r = validate_firmware(**FIRMWARE, target="cortex-m4f", cflags="-O2")
    assert not r.bit_exact
    r.assert_within(deg=1e-4)
