"""Twin of csrc/imf_gate.h: the accelerometer-magnitude gate of Nair (2016).

Shared by the Madgwick and Mahony references: check() validates the
acc_gate/acc_1g keywords (one definition for both backends) and gives the C
init arguments; set() and passes() mirror imf_acc_gate_set and
imf_acc_gate_pass.
"""
from ..shared import checks as _checks

def check(acc_gate, acc_1g):
    """C init arguments (acc_gate_lo, acc_gate_hi, acc_1g); acc_gate_lo = -1
    (off) when acc_gate is None."""
    one_g = _checks.check_real("acc_1g", acc_1g, lo=0.0, lo_open=True)
    if acc_gate is None:
        return (-1.0, 0.0, one_g)
    try:
        lo, hi = acc_gate
    except (TypeError, ValueError):
        raise ValueError(f"acc_gate: must be None or (lo, hi) in units of acc_1g, "
                         f"got {acc_gate!r}") from None
    lo = _checks.check_real("acc_gate[0]", lo, lo=0.0)
    hi = _checks.check_real("acc_gate[1]", hi, lo=lo, lo_open=True,
                            why="hi must be above lo")
    return (lo, hi, one_g)


def lo(name, acc_gate, prior):
    """Settings record (_settings.setting): acc_gate_lo from the keyword acc_gate (-1: off)."""
    return check(acc_gate, 1.0)[0]


def hi(name, acc_gate, prior):
    """Settings record (_settings.setting): acc_gate_hi from the keyword acc_gate."""
    return check(acc_gate, 1.0)[1]


def set(R, lo, hi, one_g):
    """imf_acc_gate_set: (on, lo2, hi2)."""
    lo, hi, one_g = R(lo), R(hi), R(one_g)
    l = lo * one_g
    h = hi * one_g
    return (lo >= R(0.0), l * l, h * h)


def passes(R, gate, ax, ay, az):
    """imf_acc_gate_pass: True when the gate is off or lo2 <= |a|^2 <= hi2."""
    on, lo2, hi2 = gate
    if not on:
        return True
    n2 = ax * ax + ay * ay + az * az
    return n2 >= lo2 and n2 <= hi2
