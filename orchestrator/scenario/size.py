"""Will a loaded scenario fit in memory? A fleet's stacked model is refused by its size
before it is built (:func:`check_fleet_model`); the run's own checks (traces, design time)
are in :mod:`orchestrator.running.memory`."""
from __future__ import annotations

from typing import TYPE_CHECKING

from .errors import ScenarioError

if TYPE_CHECKING:
    from .schema_fleet import FleetScenario

__all__ = ["MEMORY_SHARE", "MODEL_BYTES_PER_STATE2", "available_memory", "check_fleet_model",
           "memory_short"]

#: the share of the memory available an estimate may take
MEMORY_SHARE = 0.8
#: bytes per state^2 of a loaded fleet scenario's stacked model (about 14 dense n x n
#: float64 matrices: the resident set after loading, measured on grid fleets of 20-80
#: vehicles with the stacked design's calibration, orchestrator.running.memory)
MODEL_BYTES_PER_STATE2 = 14 * 8


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


def memory_short(need: float, available: int | None = None) -> int | None:
    """The bytes available, when ``need`` (bytes) exceeds :data:`MEMORY_SHARE` of them;
    None when it fits or the kernel does not say (``available``: default
    :func:`available_memory`). Every size check refuses on this one rule."""
    available = available_memory() if available is None else available
    return available if available is not None and need > MEMORY_SHARE * available else None


def check_fleet_model(fleet: FleetScenario, where: str, available: int | None = None) -> int:
    """Refuse, before it is built, a fleet whose stacked model would not fit in memory:
    bytes = MODEL_BYTES_PER_STATE2 x states^2, states = sum over vehicles of (p + r) plus
    the leader's path states plus one.

    Parameters
    ----------
    fleet : FleetScenario
        The validated sections (validation allocates nothing of that size).
    where : str
        Names the scenario in the message.
    available : int, optional
        Bytes available (default :func:`available_memory`).

    Returns
    -------
    int
        The stacked model's estimated bytes.

    Raises
    ------
    ScenarioError
        One line with the vehicles, the states, the estimate and the memory available.
    """
    models = fleet.vehicles.models
    states = sum(m.p + m.r for m in models) + len(fleet.leader.leader_path.z0) + 1
    need = int(MODEL_BYTES_PER_STATE2 * states * states)
    available = memory_short(need, available)
    if available is not None:
        raise ScenarioError(
            f"{where}: the stacked model of {len(models)} vehicles ({states} states) needs "
            f"about {need / 1e9:.3g} GB (estimated: {MODEL_BYTES_PER_STATE2 // 8} dense "
            f"{states} x {states} matrices), more than {MEMORY_SHARE:.0%} of the "
            f"{available / 1e9:.3g} GB of memory available; use fewer vehicles")
    return need
