"""Every filter is in the matrix: no class escapes the bit-exact harness, and
each names its C twin."""
import glob
import os

import pytest

import imufuse.reference as reference
import imufuse_c
from imufuse.registry import FLOAT_CASES, FUSION_CASES

HEADERS = "\n".join(open(h).read() for h in glob.glob(
    os.path.join(os.path.dirname(__file__), "..", "csrc", "*.h")))


@pytest.mark.parametrize("name", reference.FILTERS)
def test_filter_is_registered_and_named(name):
    assert any(c.name == name for c in FLOAT_CASES), f"{name} has no entry in imufuse.registry"
    ref = getattr(reference, name)
    assert ref.c_name, f"{name}.c_name is empty"
    for fn in (f"{ref.c_name}_init", ref.c_update):
        assert f"void {fn}(" in HEADERS, f"{fn} not declared in csrc/"
    assert ref.c_update in (f"{ref.c_name}_update", f"{ref.c_name}_update_imu"), ref.c_update
    assert f"}} {ref.c_name}_t;" in HEADERS
    assert getattr(imufuse_c, name).state_names == ref.state_names


@pytest.mark.parametrize("name", reference.FILTERS_FUSION)
def test_fusion_class_is_registered_and_named(name):
    """The Fusion suite is outside the generic matrix (see registry.py) but in
    FUSION_CASES, with its C twin declared in csrc/."""
    assert any(c.name == name for c in FUSION_CASES), f"{name} has no entry in FUSION_CASES"
    ref = getattr(reference, name)
    for fn in ("init", "update"):
        assert f"void {ref.c_name}_{fn}(" in HEADERS
    assert f"}} {ref.c_name}_t;" in HEADERS
    assert getattr(imufuse_c, name).state_names == ref.state_names
