"""Physical bounds: the interval a quantity must lie in, checked and quoted in one place.

A :class:`Bound` is defined once, next to the data it bounds (e.g.
:data:`plant_model.remus100.dynamics.REMUS_BOUNDS`), and both checks a value and writes
the refusal: the key, the value with its unit, the interval and why::

    thrust_deduction = 1.5 must be in [0, 1) (the share of the thrust the hull's suction
    takes back)
    delta_max = 2 rad (115 deg) must be in (0, 90) deg (a fin deflection)

Pure Python, no FMI.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from .linalg_checks import ModelError, as_number

__all__ = ["Bound", "nonnegative", "positive"]


@dataclass(frozen=True)
class Bound:
    """``lo < x`` (``lo <= x`` when ``lo_closed``) and ``x < hi`` (``x <= hi`` when
    ``hi_closed``), in ``unit``; ``shown`` (unit, factor) states the interval in another
    unit (e.g. deg for a value in rad); ``why`` says in a few words what the quantity is."""

    lo: float = -math.inf
    hi: float = math.inf
    lo_closed: bool = False
    hi_closed: bool = False
    unit: str = ""
    why: str = ""
    shown: tuple[str, float] | None = None

    def holds(self, x: float) -> bool:
        """Is ``x`` (finite) within the bound?"""
        above = x >= self.lo if self.lo_closed else x > self.lo
        below = x <= self.hi if self.hi_closed else x < self.hi
        return above and below

    def interval(self) -> str:
        """The bound in words: "positive", "non-negative", "in [0, 1)", "at most 10 m/s"."""
        unit, k = self.shown or (self.unit, 1.0)
        tail = f" {unit}" if unit else ""
        if math.isinf(self.hi) and self.lo == 0.0:
            return "non-negative" if self.lo_closed else "positive"
        if math.isinf(self.lo):
            return f"at most {self.hi * k:g}{tail}" if self.hi_closed else \
                f"below {self.hi * k:g}{tail}"
        if math.isinf(self.hi):
            return f"at least {self.lo * k:g}{tail}" if self.lo_closed else \
                f"above {self.lo * k:g}{tail}"
        return (f"in {'[' if self.lo_closed else '('}{self.lo * k:g}, {self.hi * k:g}"
                f"{']' if self.hi_closed else ')'}{tail}")

    def check(self, name: str, value: Any) -> float:
        """``value`` as a float within the bound, else one line naming ``name``, the value
        with its unit, the interval and what the quantity is.

        Raises
        ------
        ModelError
            If ``value`` is not a finite number (a string or a boolean included) or lies
            outside the bound.
        """
        x = as_number(name, value)
        if not self.holds(x):
            raise ModelError(f"{self.describe(name, x)} must be {self.interval()}"
                             + (f" ({self.why})" if self.why else ""))
        return x

    def describe(self, name: str, x: float) -> str:
        """``name = x unit`` (and the value in the shown unit)."""
        text = f"{name} = {x:g}" + (f" {self.unit}" if self.unit else "")
        if self.shown is not None:
            text += f" ({x * self.shown[1]:.3g} {self.shown[0]})"
        return text


def positive(unit: str = "", why: str = "") -> Bound:
    """x > 0 (a length, a mass, a time constant)."""
    return Bound(lo=0.0, unit=unit, why=why)


def nonnegative(unit: str = "", why: str = "") -> Bound:
    """x >= 0 (a damping, a drag coefficient)."""
    return Bound(lo=0.0, lo_closed=True, unit=unit, why=why)
