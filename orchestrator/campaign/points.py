"""Design points: the grid (or list) of a spec, each resolved to a validated scenario, and
the key of every run.

A point is a mapping of dotted keys to values (:mod:`.spec`), applied to a copy of the base
scenario's mapping; ``vehicles.count`` of a fleet takes the generator's offsets, positions,
edges and pinning for that many vehicles (:func:`orchestrator.scenario.generator.grid_fleet`),
so the formation and the graph follow the count. A point that does not make a valid scenario
is kept, with its error, and becomes rows with that message.

Run key = SHA-256 of the canonical JSON of (the whole resolved scenario without its seed:
system, fleet, deployment, architecture, links, sensors, distributed-law settings, FMU kind
and run settings; the coupling, the seed, the engine, the package versions): the same run in
any later campaign has the same key, and two points that differ in anything they run never
share one. A point that ``auv-cosim run`` would refuse (a [network] on the stacked deployment,
a design estimated past the limit, a T whose traces would not fit: :func:`orchestrator.
running.systems.check_run`) is refused before anything runs, as an error row with the same
one-line reason.
"""
from __future__ import annotations

import copy
import hashlib
import itertools
import json
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from plant_model.linalg_checks import ModelError

from ..scenario import Scenario, ScenarioError, scenario_from_dict
from ..scenario.fingerprint import resolved_scenario
from ..scenario.variants import set_key

if TYPE_CHECKING:
    from .spec import CampaignSpec

__all__ = ["DesignPoint", "expand_points", "resolve_point", "resolve_points", "run_key",
           "canonical_json", "param_text", "resolved_scenario"]


@dataclass(frozen=True)
class DesignPoint:
    """One point of a campaign: its index, its values, what it runs (or why it cannot)."""

    index: int
    params: dict[str, Any]          #: dotted key -> value, in the spec's order
    scenario: Scenario | None       #: None when the point does not make a valid scenario
    coupling: str                   #: the master's coupling (``cosim.coupling``)
    error: str | None               #: why the point cannot run
    resolved: str                   #: canonical JSON of what the point runs (run keys)
    sections: frozenset[str] = frozenset()   #: top-level keys of its scenario mapping


def canonical_json(value: Any) -> str:
    """JSON with sorted keys and no spaces (floats by repr: they round-trip exactly).

    Parameters
    ----------
    value : Any
        JSON-ready data.

    Returns
    -------
    str
    """
    return json.dumps(value, sort_keys=True, separators=(",", ":"), allow_nan=True)


def param_text(value: Any) -> str:
    """A swept value as short text (strings bare, others as JSON).

    Parameters
    ----------
    value : Any

    Returns
    -------
    str
    """
    return value if isinstance(value, str) else canonical_json(value)


def expand_points(spec: CampaignSpec) -> list[dict[str, Any]]:
    """The points of a spec: every ``points`` entry (one empty point if none) crossed with
    the full grid of ``[sweep]`` (the last axis varies fastest).

    Parameters
    ----------
    spec : CampaignSpec

    Returns
    -------
    list[dict[str, Any]]
        Dotted key -> value for each point.
    """
    axes = list(spec.sweep.items())
    grid = [dict(zip([k for k, _ in axes], combo))
            for combo in itertools.product(*[v for _, v in axes])]
    listed = spec.points or [{}]
    return [{**p, **g} for p in listed for g in grid]


def _regenerate_fleet(data: dict[str, Any], count: Any) -> None:
    """Offsets, positions, edges and pinning of ``count`` vehicles from the grid generator."""
    from ..scenario.generator import grid_fleet
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        return                                   # the schema reports the bad count
    gen = grid_fleet(count)
    vehicles = data.setdefault("vehicles", {})
    for k in ("offsets", "positions"):
        vehicles[k] = gen["vehicles"][k]
    vehicles.pop("x0", None)
    graph = data.setdefault("graph", {})
    for k in ("edges", "pinning"):
        graph[k] = gen["graph"][k]


def resolve_point(index: int, params: dict[str, Any], base: dict[str, Any],
                  base_where: str) -> DesignPoint:
    """Apply ``params`` to a copy of ``base`` and validate it.

    Parameters
    ----------
    index : int
        The point's number.
    params : dict[str, Any]
        Dotted key -> value.
    base : dict[str, Any]
        The base scenario mapping (not changed).
    base_where : str
        Names the base scenario.

    Returns
    -------
    DesignPoint
        With the scenario, or with the one-line error when it is not valid or fails one
        of the checks ``auv-cosim run`` makes (:func:`orchestrator.running.systems.
        check_run`: the combination, the stacked design's time and memory, native FMUs'
        compiler, the traces of T / h steps in memory), in the words ``run`` prints; a
        fleet whose stacked model would not fit in memory is refused before it is built.
    """
    data = copy.deepcopy(base)
    coupling = "gauss-seidel"
    for key, value in params.items():
        if key == "cosim.coupling":
            coupling = value
        elif key == "vehicles.count" and "leader" in data:
            set_key(data, key, value)
            _regenerate_fleet(data, value)
        else:
            set_key(data, key, value)
    where = f"{base_where} with " + ", ".join(f"{k} = {param_text(v)}"
                                              for k, v in params.items()) if params else base_where
    try:
        from ..cosim.native import NativeBuildError
        from ..running.systems import check_run
        sc = scenario_from_dict(data, where)    # refuses a stacked model too large first
        check_run(sc, coupling=coupling)        # run's checks: a point that would not finish
    except (ScenarioError, ModelError, NativeBuildError) as exc:
        resolved = canonical_json({"base": data, "coupling": coupling})
        return DesignPoint(index, params, None, coupling, str(exc), resolved, frozenset(data))
    resolved = canonical_json({"scenario": resolved_scenario(sc), "coupling": coupling})
    return DesignPoint(index, params, sc, coupling, None, resolved, frozenset(data))


def resolve_points(spec: CampaignSpec, base: dict[str, Any],
                   base_where: str) -> list[DesignPoint]:
    """Every point of ``spec`` resolved (:func:`expand_points`, :func:`resolve_point`).

    Parameters
    ----------
    spec : CampaignSpec
    base : dict[str, Any]
        The base scenario mapping.
    base_where : str
        Names the base scenario.

    Returns
    -------
    list[DesignPoint]
    """
    return [resolve_point(i, p, base, base_where) for i, p in enumerate(expand_points(spec))]


def run_key(point: DesignPoint, seed: int, engine: str, versions: dict[str, str],
            role: str = "run") -> str:
    """The key of one run (module docstring); a ``check`` run has its own key.

    Parameters
    ----------
    point : DesignPoint
    seed : int
    engine : str
        'fmu' or 'numpy': the engine that runs it.
    versions : dict[str, str]
        Package versions (:func:`orchestrator.analysis.summary.versions`).
    role : str, optional
        'run' (a row of results.parquet) or 'check' (an FMU re-run of a numpy run).

    Returns
    -------
    str
        32 hex digits.
    """
    text = canonical_json({"point": point.resolved, "seed": int(seed), "engine": engine,
                           "versions": versions, "role": role})
    return hashlib.sha256(text.encode()).hexdigest()[:32]
