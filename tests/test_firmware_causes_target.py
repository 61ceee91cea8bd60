"""The planted causes of tests/test_firmware_causes.py named when the firmware runs on a target
(the Cortex-M0, `validate(..., target="cortex-m0")`): the target's own build causes first, then
the source's (imufuse.firmware.diagnostics: undefined behaviour from the host's UBSan/ASan run
of the same source, the data model, a changed constant confirmed by rebuilding for the target,
the warnings), and the class of the divergence:

- signed overflow: named with its sample, as on the host;
- a shift of a negative value: named;
- an out-of-bounds read: named with its sample;
- `long` width dependence: on the M0 `long` is 32 bits, so the fast inverse square root works
  there and the firmware is only a different formula; the data model still names the line;
- a double literal: the double arithmetic of the M0's build named and confirmed;
- a re-associated sum: a different computation, no build cause;
- a changed constant: named and confirmed by rebuilding for the M0, formula class.
"""
import re

import numpy as np
import pytest

from imufuse.firmware import validate
from imufuse.mcu import ensure_toolchains
from test_firmware_causes import (DOUBLE_LITERAL, INVSQRT, NEG_SHIFT, OUT_OF_BOUNDS, OVERFLOW,
                                  MB_PARAMS, PARAMS, _line, _only, _plant, reassociated)

TARGET = "cortex-m0"

pytestmark = pytest.mark.xdist_group("causes_target")
pytest.importorskip("cffi")


@pytest.fixture(scope="module", autouse=True)
def _toolchains():
    missing = ensure_toolchains(("m0",))
    assert not missing, f"MCU toolchains missing: {missing}"


@pytest.fixture(scope="module")
def inputs():
    from imufuse import sim
    d = sim.axis1d("fast", rate=200.0, duration=600 / 200.0, seed=3)
    return [d.gyr, d.acc_angle]


def _v(fw, inputs, name="Kalman1D", params=PARAMS):
    return validate(fw, name, params, inputs, target=TARGET)


def test_signed_overflow_on_the_target(tmp_path, inputs):
    fw, text = _plant(tmp_path, OVERFLOW)
    v = _v(fw, inputs)
    k = int(2 ** 31 // 5_000_000)
    assert not v.bit_exact and v.comparison.first_sample == k
    ub = _only(v, "undefined behaviour")
    assert re.fullmatch(rf"att\.c:{_line(text, 'att_t_ns +=')}:\d+", ub.where) and ub.sample == k


def test_negative_shift_on_the_target(tmp_path, inputs):
    fw, text = _plant(tmp_path, NEG_SHIFT)
    v = _v(fw, inputs)
    ub = _only(v, "undefined behaviour")
    assert re.fullmatch(rf"att\.c:{_line(text, 'q << 4')}:\d+", ub.where)
    assert ub.detail == "shift of a negative value"


def test_out_of_bounds_on_the_target(tmp_path, inputs):
    fw, text = _plant(tmp_path, OUT_OF_BOUNDS)
    v = _v(fw, inputs)
    k = int(np.flatnonzero(np.abs(np.float32(inputs[0])) >= 4)[0])
    ub = _only(v, "undefined behaviour")
    assert ub.sample == k and ub.detail == "index out of bounds"
    assert re.fullmatch(rf"att\.c:{_line(text, 'att_cal.gain[idx]')}:\d+", ub.where)


def test_long_width_on_the_target(tmp_path, inputs):
    """On the M0 the pun is right (32-bit long): the firmware is a close variant of a
    different formula; the data model names the line all the same."""
    fw, text = _plant(tmp_path, [("void att_begin", INVSQRT),
                                 ("att_k0 * acc_angle;",
                                  "att_k0 * acc_angle * (invSqrt(4.0f) * 2.0f);")])
    v = _v(fw, inputs)
    line = _line(text, "*(long*)&y")
    assert not v.bit_exact
    assert any(c.what == "data model" and c.where == f"att.c:{line}" for c in v.causes), v.text()
    assert v.classification is not None and v.classification.kind == "formula"


def test_double_literal_on_the_target(tmp_path, inputs):
    fw, text = _plant(tmp_path, DOUBLE_LITERAL)
    v = _v(fw, inputs)
    assert any(c.what == "double" and c.confirmed for c in v.causes), v.text()


def test_reassociated_sum_on_the_target(tmp_path, inputs):
    v = _v(reassociated(tmp_path), inputs, "Mahony1DBias", MB_PARAMS)
    assert not v.bit_exact
    assert not [c for c in v.causes if c.what not in ("warning",)], v.text()
    assert "none of the known build causes" in v.text()


def test_changed_constant_on_the_target(tmp_path, inputs):
    fw, text = _plant(tmp_path, [("att_omk0 = 1.0f - k0;", "att_omk0 = 0.981f;")])
    v = _v(fw, inputs)
    c = [c for c in v.causes if c.what == "constant"]
    assert c and c[0].confirmed and c[0].where.startswith("att.c:4:"), v.text()
    assert v.classification is not None and v.classification.kind == "formula"
