"""What a validation reports: the comparison with imufuse bit for bit (imufuse.shared.bits), the
class of a divergence (rounding or formula, imufuse.firmware.report), the causes found,
notes, and on an MCU target the cost of one update."""
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

from ..shared.bits import Comparison
from .report import Classification, classify

__all__ = ["Cost", "Validation"]


@dataclass
class Cost:
    """What one update costs on the target (from the emulated run and the linked image)."""
    unit: str                      # "cycles" (AVR) or "instructions" (ARM)
    min: int
    median: float
    max: int
    flash: Optional[int]           # bytes of the firmware's objects in the image (None: -flto
                                   # inlined them into the harness's call)
    ram: int                       # static RAM of the firmware (its filter object included)
    stack: Optional[int]           # deepest stack an update reached, bytes
    library: List[str] = field(default_factory=list)   # library routines it calls
    library_flash: int = 0         # flash of the library code they pull in
    counts: Optional[np.ndarray] = None   # (N,) per update, in `unit`

    def text(self) -> str:
        libs = (f" + {self.library_flash} B of library code for {', '.join(self.library)}"
                if self.library else "")
        stack = f"{self.stack} B" if self.stack is not None else "beyond the painted band"
        fl = f"{self.flash} B" if self.flash is not None else \
            "not separable (-flto inlined the firmware into the call)"
        return (f"cost per update: {self.min} / {self.median:.0f} / {self.max} {self.unit} "
                f"(min / median / max)\n"
                f"flash {fl}{libs}; static RAM {self.ram} B; stack {stack}")


@dataclass
class Validation:
    filter: str
    backend: str
    comparison: Comparison
    got: np.ndarray
    want: np.ndarray
    target: str = "host"
    cflags: Tuple[str, ...] = ()
    causes: List[Any] = field(default_factory=list)
    notes: List[str] = field(default_factory=list)
    max_angle_deg: Optional[float] = None
    cost: Optional[Cost] = None
    timing: Dict[str, float] = field(default_factory=dict)
    # the imufuse filter's parameters, set by the callers that know them (imufuse validate,
    # imufuse.testing): the orientation of a fixed-point single-axis filter needs its scale
    params: Optional[Dict[str, Any]] = None
    # the first line of text() when the comparison is not firmware against imufuse
    # (imufuse.firmware.versus: firmware against firmware)
    title: Optional[str] = None
    # got and want are orientations made from states of different kinds (a float filter
    # against its fixed-point port, imufuse.firmware.versus): no ulps between them
    as_orientations: bool = False
    _classification: Optional[Classification] = field(default=None, init=False, repr=False,
                                                      compare=False)

    @property
    def bit_exact(self):
        return self.comparison.bit_exact

    @property
    def classification(self) -> Optional[Classification]:
        """Rounding or formula, with the error's growth (imufuse.firmware.report.classify);
        None when bit-exact."""
        if self.bit_exact:
            return None
        if self._classification is None:
            self._classification = classify(self)
        return self._classification

    def text(self):
        flags = " ".join(self.cflags) if self.cflags else "(none)"
        head = self.title or (f"firmware on {self.target} (flags {flags}) vs imufuse "
                              f"{self.filter} ({self.backend}, {self.comparison.dtype}):")
        lines = [head, self.comparison.text()]
        if not self.bit_exact and self.max_angle_deg is not None:
            lines.append(f"largest orientation difference over the run: {self.max_angle_deg:.3g} deg")
        if self.classification is not None:
            lines.append(self.classification.text())
        for c in self.causes:
            lines.append(c.text())
        if not self.bit_exact and self.title is None and not any(c.fix for c in self.causes):
            lines.append("cause: none of the known build causes (fused multiply-add, double "
                         "arithmetic, fast-math) was found in the objects: the firmware computes "
                         "something else (an operation, its order, or a constant)")
        lines += [f"note: {n}" for n in self.notes]
        if self.cost is not None:
            lines.append(self.cost.text())
        return "\n".join(lines)
