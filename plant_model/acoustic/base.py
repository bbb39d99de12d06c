"""What the acoustic modules share: a number, a vehicle or "leader", seconds as whole steps.

The checks shared by the links and their settings (:mod:`.links`, :mod:`.settings`) and by
the switching schedule (:mod:`.schedule`), which therefore need not import each other; every
error is one line naming the value. Pure Python, no FMI.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..linalg_checks import ModelError

__all__ = ["MAX_MESSAGE_CYCLE_STEPS", "_number", "_vehicle", "whole_steps"]


#: the longest message cycle (steps h) of a network: the links' periods and the schedule's
#: period repeat together every lcm of them; the predictions and the loop's patterns
#: unroll one cycle step by step
MAX_MESSAGE_CYCLE_STEPS = 100_000


def _number(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ModelError(f"{name} = {value!r} is not a number")
    v = float(value)
    if not math.isfinite(v):
        raise ModelError(f"{name} = {v} is not finite")
    return v


def _vehicle(N: int, value: Any, where: str) -> int | str:
    if value == "leader":
        return "leader"
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ModelError(f"{where}: {value!r} is not a vehicle number or \"leader\"")
    if not 1 <= int(value) <= N:
        raise ModelError(f"{where}: vehicle {value} does not exist (vehicles are 1..{N})")
    return int(value)


def whole_steps(name: str, value: float, h: float) -> int:
    """``value`` (s) as a whole number of steps h, or a one-line error naming it; a positive
    value below one step (which would round to 0 steps: a period of 1e-12 s) is refused."""
    n = float(value) / h
    if float(value) > 0.0 and round(n) == 0:
        raise ModelError(f"{name} = {value:g} s is below one step h = {h:g} s (messages "
                         "leave on the co-simulation's steps, at most one per step)")
    if abs(n - round(n)) > 1e-9 * max(1.0, abs(n)):
        raise ModelError(f"{name} = {value:g} s is not a whole number of steps h = {h:g} s "
                         "(messages leave on the co-simulation's steps)")
    return int(round(n))

