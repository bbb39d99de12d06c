"""Command-line argument types of ``auv-cosim``: seed lists, positive seconds, counts,
fleet sizes.

Each raises :class:`argparse.ArgumentTypeError` with one line naming the value.
"""
from __future__ import annotations

import argparse
from collections import Counter

__all__ = ["current_speeds", "leader_speeds", "parse_floats", "parse_seeds", "positive_metres"]


#: the most seeds one compare takes
MAX_SEEDS = 100_000


def parse_seeds(text: str) -> list[int]:
    """'0-9' -> 0..9, '1,4,7' -> [1, 4, 7], '3' -> [3]."""
    seeds: list[int] = []
    try:
        for part in text.split(","):
            part = part.strip()
            if "-" in part:
                a, b = (int(x) for x in part.split("-", 1))
                if b < a:
                    raise ValueError
                if b - a + 1 > MAX_SEEDS:       # refused before the list is made
                    raise argparse.ArgumentTypeError(
                        f"seeds {text!r}: {b - a + 1} seeds is too many for one compare "
                        f"(at most {MAX_SEEDS})")
                seeds.extend(range(a, b + 1))
            else:
                seeds.append(int(part))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"seeds {text!r}: expected a range '0-9', a list '1,4,7' or one seed") from None
    if any(s < 0 or s > 2**31 - 1 for s in seeds):
        raise argparse.ArgumentTypeError(
            f"seeds {text!r}: seeds must be from 0 to 2^31 - 1 (a 32-bit FMI Integer)")
    if len(seeds) > MAX_SEEDS:
        raise argparse.ArgumentTypeError(f"seeds {text!r}: {len(seeds)} seeds is too many "
                                         f"for one compare (at most {MAX_SEEDS})")
    repeated = sorted(s for s, c in Counter(seeds).items() if c > 1)
    if repeated:
        raise argparse.ArgumentTypeError(
            f"seeds {text!r}: seed(s) {', '.join(map(str, repeated))} given more than once "
            "(each would count twice in the statistics)")
    return seeds


def _positive_finite(text: str, unit: str) -> float:
    """A positive finite number, or one line naming the value and the unit."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not 0 < v < float("inf"):
        raise argparse.ArgumentTypeError(f"{text!r} must be a positive number of {unit}")
    return v


def _positive(text: str) -> float:
    """A positive finite time, s."""
    return _positive_finite(text, "seconds")


def _count(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"{text!r} must be at least 1")
    return v


def parse_floats(text: str) -> list[float]:
    """'1,1.5,2' -> [1.0, 1.5, 2.0]; 'inf' allowed (a straight leader path); each value
    positive."""
    try:
        values = [float(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected numbers separated by commas, "
                                         "e.g. '1,1.5,2'") from None
    bad = [v for v in values if not v > 0]
    if not values or bad:
        raise argparse.ArgumentTypeError(f"{text!r}: every value must be a positive number"
                                         + (f" ({bad[0]:g} is not)" if bad else ""))
    return values


def _bounded(text: str, what: str, bound: object) -> list[float]:
    """:func:`parse_floats`, each value within ``bound`` (a plant_model.bounds.Bound), else
    one line naming the value, its unit and the bound."""
    from plant_model.linalg_checks import ModelError
    values = parse_floats(text)
    for v in values:
        try:
            bound.check(what, v)                         # type: ignore[attr-defined]
        except ModelError as exc:
            raise argparse.ArgumentTypeError(f"{text!r}: {exc}") from None
    return values


def leader_speeds(text: str) -> list[float]:
    """Leader speeds (m/s), each positive and at most plant_model.leader.MAX_LEADER_SPEED."""
    from plant_model.leader import LEADER_SPEED
    return _bounded(text, "speed", LEADER_SPEED)


def current_speeds(text: str) -> list[float]:
    """Current strengths (m/s), each positive and at most plant_model.fleet.MAX_CURRENT_SPEED."""
    from plant_model.fleet import CURRENT_SPEED
    return _bounded(text, "current", CURRENT_SPEED)


def positive_metres(text: str) -> float:
    """A positive finite distance, m."""
    return _positive_finite(text, "metres")


def _fleet_sizes(text: str) -> list[int]:
    try:
        sizes = [int(x) for x in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--fleet {text!r}: expected sizes like '1,5,20,50'") from None
    if not sizes or any(n < 1 for n in sizes):
        raise argparse.ArgumentTypeError(f"--fleet {text!r}: sizes must be positive")
    return sizes
