"""Will a run's traces fit in memory? Checked before anything is built or written."""
from __future__ import annotations

from typing import TYPE_CHECKING

from ..scenario import ScenarioError

if TYPE_CHECKING:
    from ..scenario import Scenario

__all__ = ["available_memory", "check_memory"]


def available_memory() -> int | None:
    """Bytes of memory available to a new allocation (``MemAvailable`` of /proc/meminfo),
    or None where the kernel does not say."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def check_memory(sc: Scenario, n_methods: int, available: int | None = None) -> int:
    """Refuse a run whose traces cannot fit in memory, before anything is built.

    The traces of one run are ``steps`` rows of every output of every FMU, 8 bytes each;
    a run holds its own, plus the first seed's traces of every method for the .rrd, plus a
    copy in the recording child: bytes = 8 steps width (n_methods + 2).

    Parameters
    ----------
    sc : Scenario
        The scenario (its T, h and system).
    n_methods : int
        Methods simulated (estimator modes x tracking laws).
    available : int, optional
        Bytes available (default :func:`available_memory`).

    Returns
    -------
    int
        The estimated bytes.

    Raises
    ------
    ScenarioError
        Naming T, h, the number of steps and both sizes, if the estimate exceeds 80 % of
        the memory available.
    """
    from .systems import scenario_system
    width = sum(spec.size for _, spec in scenario_system(sc).outputs())
    need = 8 * sc.steps * width * (n_methods + 2)
    available = available_memory() if available is None else available
    if available is not None and need > 0.8 * available:
        raise ScenarioError(
            f"T = {sc.T:g} s with h = {sc.h:g} s is {sc.steps:.4g} steps: the traces "
            f"({width} values per step, {n_methods} method(s)) need about {need / 1e9:.3g} GB, "
            f"more than the {available / 1e9:.3g} GB of memory available; shorten T or "
            "lengthen h")
    return need
