"""``auv-cosim envelope``: where a formation holds. A grid of leader speed, turn radius and
ocean-current strength around a fleet scenario; at each point one run of the scenario's
fleet (its vehicles, graph, design, sensors and estimator) behind a leader on a straight
line (radius ``inf``) or a circle of that radius at that speed, the current's stationary
standard deviation set to that strength, the vehicles started in formation. The formation
*holds* at a point when the largest tracking error over the statistics window,
``max_error`` (orchestrator.analysis.tracking_segments), stays within the tolerance.

Writes ``<out>/summary.json`` with ``envelope``: the tolerance and per point its leader
speed (m/s), radius (m, null for a straight line), current (m/s), ``holds``,
``max_error``, ``rms_error`` (over the window, m), ``actuator_saturation_fraction``, the
folder of its run (``points/<i>``, its own .rrd and summary.json) and ``failed`` (null, or
why the point could not run: that point only fails, the grid goes on); ``failed`` beside
the points counts them. Each point passes the checks ``auv-cosim run`` makes before it
starts (:func:`orchestrator.running.compare.simulate` calls
:func:`orchestrator.running.systems.check_run` first): a point ``run`` would refuse fails
at once with ``run``'s line, and ``auv-cosim envelope`` exits 3 when any point failed
(:mod:`orchestrator.exit_status`).
"""
from __future__ import annotations

import itertools
import json
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from plant_model.noise_factor import NOISE_STREAM

from ..atomic import write_text_atomically
from ..outputs import file_stem
from ..scenario import Scenario, scenario_from_dict
from ..scenario.variants import with_keys

__all__ = ["POINT_ERRORS", "envelope_params", "envelope_point", "envelope_spec", "failed_point",
           "run_envelope"]


#: the run settings a point carries over from the scenario it varies
RUN_KEYS = ("T", "h", "estimator", "tracking", "deployment", "architecture", "fmus")


def envelope_params(sc: Scenario, speed: float, radius: float, current: float
                    ) -> dict[str, Any]:
    """The keys one grid point sets on the scenario (:func:`orchestrator.scenario.variants.
    set_key`): the leader's whole table (a straight line for ``radius`` inf, else a circle,
    at the leader's depth, no path noise), the current's standard deviation, the vehicles
    started in formation, and the run settings the scenario was given (its links too)."""
    leader = sc.fleet.leader
    depth = float((leader.H @ leader.z0)[2])
    if math.isinf(radius):
        table = {"path": "straight", "speed": speed, "start": [0.0, 0.0, depth],
                 "noise": 0.0}
    else:
        table = {"path": "circle", "radius": radius, "speed": speed,
                 "center": [0.0, 0.0, depth], "noise": 0.0}
    out: dict[str, Any] = {"leader": table, "current.sigma": current,
                           "vehicles.start": "formation"}
    if sc.design is not None and (sc.raw or {}).get("design", {}).get("path_check") == "refuse":
        out["design.path_check"] = "warn"      # a verdict per point, not a refusal
    out.update({f"simulation.{k}": getattr(sc, k) for k in RUN_KEYS})
    if sc.network is not None:
        out["network"] = sc.network.to_mapping()
    return out


def envelope_point(sc: Scenario, speed: float, radius: float, current: float) -> Scenario:
    """The scenario of one grid point (module docstring); ``radius`` inf: a straight line.

    Raises
    ------
    ScenarioError
        If the point does not make a valid scenario (named by the loader).
    """
    where = f"{sc.source} (envelope: speed {speed:g} m/s, radius {radius:g} m, current " \
            f"{current:g} m/s)"
    params = envelope_params(sc, speed, radius, current)
    return scenario_from_dict(with_keys(sc.raw, params), where).with_run(seed=sc.seed)


def envelope_spec(sc: Scenario, speeds: Sequence[float], radii: Sequence[float],
                  currents: Sequence[float]) -> str:
    """The envelope's grid as a campaign spec (TOML): the scenario as its base, one
    ``[[points]]`` entry per grid point (:func:`envelope_params`), the scenario's seed.
    ``auv-cosim campaign`` runs it on local workers or a Dask cluster; each row's
    ``max_error`` is the envelope's figure at that point."""
    base = _base_name(sc)
    lines = [f"# auv-cosim envelope of {sc.name}: speeds {list(speeds)} m/s, radii "
             f"{[None if math.isinf(r) else r for r in radii]} m (none: a straight line), "
             f"currents {list(currents)} m/s",
             f"name = {_toml(f'{file_stem(sc.name)}-envelope')}", f"base = {_toml(base)}",
             f"seeds = {_toml(str(sc.seed))}", "seeds_per_task = 1", ""]
    for speed, radius, current in itertools.product(speeds, radii, currents):
        lines.append("[[points]]")
        for key, value in envelope_params(sc, speed, radius, current).items():
            lines.append(f"{_toml(key)} = {_toml(value)}")
        lines.append("")
    return "\n".join(lines)


def _base_name(sc: Scenario) -> str:
    """How a campaign spec names the scenario's file: a built-in name or the file's path."""
    from ..scenario import SCENARIO_DIR
    prefix = "built-in scenario '"
    if sc.source.startswith(prefix):
        return sc.source[len(prefix):].split("'")[0]
    path = Path(sc.source)
    return path.stem if path.parent == SCENARIO_DIR else str(path.resolve())


def _toml(value: Any) -> str:
    """A TOML value (strings, numbers, booleans, arrays, inline tables)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(float(value)) if isinstance(value, float) else str(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_toml(k)} = {_toml(v)}" for k, v in value.items()) + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    raise TypeError(f"no TOML for {type(value).__name__}")


def _point_errors() -> tuple[type[BaseException], ...]:
    """What makes one grid point fail (and only that point): a variant the loader refuses,
    a design or an FMU that refuses it, a numerical failure of its design."""
    from plant_model.linalg_checks import ModelError

    from ..cosim.instance import CosimError
    from ..cosim.native import NativeBuildError
    from ..scenario import ScenarioError
    return (ScenarioError, ModelError, CosimError, NativeBuildError, np.linalg.LinAlgError)


POINT_ERRORS = _point_errors()


def failed_point(speed: float, radius: float, current: float, exc: BaseException,
                 out: Path, folder: Path) -> dict[str, Any]:
    """The summary entry of a grid point that failed: its grid values, ``failed`` the
    one-line reason, no figures; ``folder`` only if the point wrote anything."""
    reason = " ".join(str(exc).split()) or type(exc).__name__
    return {"speed": speed, "radius": None if math.isinf(radius) else radius,
            "current": current, "holds": False, "max_error": None, "rms_error": None,
            "actuator_saturation_fraction": None, "path_feasible": None,
            "path_findings": None,
            "folder": str(folder) if (out / folder).exists() else None, "failed": reason}


def run_envelope(sc: Scenario, speeds: Sequence[float], radii: Sequence[float],
                 currents: Sequence[float], tolerance: float, out: Path, *,
                 log: Callable[[str], None]) -> dict[str, Any]:
    """Run every grid point (module docstring) on the scenario's seed.

    A point whose variant or run fails (:data:`POINT_ERRORS`) is recorded with its reason
    (``failed``) and the grid goes on: the other points reach the summary.

    Returns
    -------
    dict[str, Any]
        The summary (also ``out / summary.json``).
    """
    from ..analysis.weight_search import path_verdict
    from .compare import simulate

    points = []
    grid = list(itertools.product(speeds, radii, currents))
    for i, (speed, radius, current) in enumerate(grid, start=1):
        folder = Path("points") / str(i)
        where = (f"{i:3d}/{len(grid)} speed {speed:g} m/s, radius "
                 f"{'straight' if math.isinf(radius) else format(radius, 'g') + ' m'}, "
                 f"current {current:g} m/s")
        try:
            variant = envelope_point(sc, speed, radius, current)
            s = simulate(variant, [sc.estimator], [sc.seed], out / folder, progress=False,
                         log=lambda _: None)
        except POINT_ERRORS as exc:           # this point only: the grid goes on
            points.append(failed_point(speed, radius, current, exc, out, folder))
            log(f"{where}: failed: {points[-1]['failed']}")
            continue
        (m,) = s["methods"].values()
        rms = [v for v in (m.get("rms_error_straight"), m.get("rms_error_turns"))
               if v is not None]
        point = {"speed": speed, "radius": None if math.isinf(radius) else radius,
                 "current": current, "holds": m.get("max_error") is not None
                 and m["max_error"] <= tolerance, "max_error": m.get("max_error"),
                 "rms_error": max(rms) if rms else None,
                 "actuator_saturation_fraction": m.get("actuator_saturation_fraction"),
                 **path_verdict(variant.design), "folder": str(folder), "failed": None}
        points.append(point)
        log(f"{where}: "
            + ("no statistics (empty window)" if point["max_error"] is None else
               f"max error {point['max_error']:.3g} m")
            + " -> "
            f"{'holds' if point['holds'] else 'does not hold'}"
            + ("" if point["path_feasible"] is None else
               "; path check: " + ("feasible" if point["path_feasible"] else
                                   point["path_findings"].split(" (beyond")[0])))
        if s.get("interrupted"):
            break
    judged = [p for p in points if p["path_feasible"] is not None]
    verdicts = None if not judged else {
        "points_judged": len(judged),
        "agree": sum(p["path_feasible"] == p["holds"] for p in judged),
        "feasible": sum(bool(p["path_feasible"]) for p in judged),
        "feasible_and_hold": sum(bool(p["path_feasible"]) and p["holds"] for p in judged),
        "rejected_and_fail": sum((not p["path_feasible"]) and not p["holds"]
                                 for p in judged)}
    if verdicts:
        log(f"path check beside the runs: {verdicts['agree']} of {len(judged)} points agree; "
            f"{verdicts['feasible_and_hold']} of {verdicts['feasible']} feasible points hold, "
            f"{verdicts['rejected_and_fail']} of {len(judged) - verdicts['feasible']} "
            "rejected points do not")
    summary = {"scenario": sc.name, "T": sc.T, "h": sc.h, "seed": sc.seed,
               "noise_stream": NOISE_STREAM,
               "estimator": sc.estimator, "architecture": sc.architecture,
               "models": sorted(set(sc.fleet.model_names)),
               "envelope": {"tolerance_m": tolerance, "points": points,
                            "failed": sum(p["failed"] is not None for p in points),
                            "path_check": verdicts},
               "interrupted": len(points) < len(grid)}
    write_text_atomically(out / "summary.json", json.dumps(summary, indent=2) + "\n")
    return summary
