"""How the commands print a number: :func:`sig`, a fixed count of significant figures
without a trailing dot.

Python's ``#g`` keeps the trailing zeros of a significant figure (``4.20``), but prints a
number that fills its figures before the point with a dangling point (``3789.``); plain
``g`` drops both. :func:`sig` keeps the zeros and drops the dangling point.
"""
from __future__ import annotations

__all__ = ["sig"]


def sig(value: float, digits: int = 4, width: int = 0) -> str:
    """``value`` with ``digits`` significant figures, trailing zeros kept, no trailing dot.

    Parameters
    ----------
    value : float
        The number (inf and nan print as ``inf`` and ``nan``).
    digits : int, optional
        Significant figures (at least 1).
    width : int, optional
        Right-aligned in this many characters (0: as long as it is).

    Returns
    -------
    str
        E.g. ``sig(3789.4) == "3789"``, ``sig(4.2, 3) == "4.20"``, ``sig(0.0648, 3) ==
        "0.0648"``, ``sig(1.5e6, 2) == "1.5e+06"``, ``sig(2e6, 1) == "2e+06"``.
    """
    text = format(float(value), f"#.{max(1, int(digits))}g")
    mantissa, e, exponent = text.partition("e")
    if mantissa.endswith("."):
        mantissa = mantissa[:-1]
    return f"{mantissa}{e}{exponent}".rjust(width)
