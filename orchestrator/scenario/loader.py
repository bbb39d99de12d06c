"""Scenarios: TOML files describing the system, the noise, the cost and the run.

A scenario is either the name of a built-in file in ``orchestrator/scenario/builtin/`` (``paper``
is the default) or a path to a ``.toml`` file. Sections and keys::

    name, description
    [simulation]  T (s), h (s), seed, estimator ("kalman" | "classical" | "ideal"),
                  tracking ("lq" | "regulator")
    [vehicles]    A, B1, B2, C, x0
    [disturbance] K, w0
    [reference]   F, H, z0
    [noise]       convention ("intensity" | "per_sample"), W_x, W_w, W_z, V_y, V_ybar
    [cost]        Q, R

A number where a square matrix is expected means that number times the identity.
A file with a ``[leader]`` or ``[graph]`` section describes a fleet of N vehicles on a
communication graph instead (:mod:`orchestrator.scenario.fleet`).
Every problem is reported as a :class:`ScenarioError` naming the file, section and key.
"""
from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from controller_fmu.regulator import TRACKING_MODES
from estimator_fmu.estimators import ESTIMATOR_MODES
from plant_model.fleet import fleet_system, resolve_fleet_spec
from plant_model.linalg_checks import ModelError
from plant_model.system import LinearSystem

from .fleet import fleet_spec_from_dict, is_fleet_scenario, section_of_model_error

__all__ = ["Scenario", "ScenarioError", "load_scenario", "builtin_scenarios", "SCENARIO_DIR"]

SCENARIO_DIR = Path(__file__).resolve().parent / "builtin"

_SCHEMA: dict[str, dict[str, bool]] = {   # section -> key -> required
    "simulation": {"T": True, "h": True, "seed": False, "estimator": False, "tracking": False},
    "vehicles": {"A": True, "B1": True, "B2": True, "C": True, "x0": False},
    "disturbance": {"K": True, "w0": False},
    "reference": {"F": True, "H": True, "z0": False},
    "noise": {"convention": False, "W_x": False, "W_w": False, "W_z": False,
              "V_y": False, "V_ybar": False},
    "cost": {"Q": False, "R": False},
}
_TOP = {"name", "description", *_SCHEMA}


class ScenarioError(ValueError):
    """A scenario file is invalid; the message names the file and the key."""


@dataclass(frozen=True)
class Scenario:
    """A validated scenario."""

    name: str
    description: str
    system: LinearSystem
    T: float
    h: float
    seed: int
    estimator: str
    source: str
    tracking: str = "lq"
    fleet: dict[str, Any] | None = None     #: the fleet spec (plant_model.fleet), if a fleet

    @property
    def steps(self) -> int:
        """Number of communication steps: round(T / h)."""
        return int(round(self.T / self.h))

    def with_run(self, *, T: float | None = None, h: float | None = None,
                 seed: int | None = None, estimator: str | None = None,
                 tracking: str | None = None) -> "Scenario":
        """A copy with run settings overridden (checked like the file's)."""
        new = replace(self, T=self.T if T is None else float(T), h=self.h if h is None else float(h),
                      seed=self.seed if seed is None else int(seed),
                      estimator=self.estimator if estimator is None else estimator,
                      tracking=self.tracking if tracking is None else tracking)
        _check_run(new.T, new.h, new.estimator, new.source, new.tracking)
        return new


def builtin_scenarios() -> list[str]:
    """Names of the scenarios shipped with the package."""
    return sorted(p.stem for p in SCENARIO_DIR.glob("*.toml"))


def _check_run(T: float, h: float, estimator: str, where: str, tracking: str = "lq") -> None:
    if isinstance(h, bool) or not (isinstance(h, (int, float)) and math.isfinite(h) and h > 0):
        raise ScenarioError(f"{where}: [simulation] h = {h!r} must be a positive number of seconds")
    if isinstance(T, bool) or not (isinstance(T, (int, float)) and math.isfinite(T) and T >= h):
        raise ScenarioError(f"{where}: [simulation] T = {T!r} must be at least one step h = {h} s")
    if estimator not in ESTIMATOR_MODES:
        raise ScenarioError(
            f"{where}: [simulation] estimator {estimator!r} is unknown; "
            f"expected one of {', '.join(ESTIMATOR_MODES)}"
        )
    if tracking not in TRACKING_MODES:
        raise ScenarioError(
            f"{where}: [simulation] tracking {tracking!r} is unknown; "
            f"expected one of {', '.join(TRACKING_MODES)}"
        )


def _in_section(where: str, section: str, msg: str) -> ScenarioError:
    """``<file>: [section] message``, without repeating a "section: " the message has."""
    if section and msg.startswith(f"{section}: "):
        msg = msg[len(section) + 2:]
    return ScenarioError(f"{where}: {f'[{section}] ' if section else ''}{msg}")


def _fleet_scenario(data: dict[str, Any], where: str) -> Scenario:
    try:
        spec, sim = fleet_spec_from_dict(data)
    except ValueError as exc:
        raise _in_section(where, getattr(exc, "section", ""), str(exc)) from None
    for key in ("T", "h"):
        if key not in sim:
            raise ScenarioError(f"{where}: missing key(s) in [simulation]: {key}")
    seed = sim.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ScenarioError(f"{where}: [simulation] seed = {seed!r} must be a non-negative integer")
    estimator, tracking = sim.get("estimator", "kalman"), sim.get("tracking", "lq")
    _check_run(sim["T"], sim["h"], estimator, where, tracking)
    try:
        system = fleet_system(spec)
        spec = resolve_fleet_spec(spec)
    except ModelError as exc:
        raise _in_section(where, section_of_model_error(str(exc)), str(exc)) from None
    return Scenario(name=str(data.get("name", Path(where).stem)),
                    description=str(data.get("description", "")), system=system,
                    T=float(sim["T"]), h=float(sim["h"]), seed=int(seed), estimator=estimator,
                    source=where, tracking=tracking, fleet=spec)


def _resolve(spec: str | Path) -> Path:
    p = Path(spec)
    if p.suffix == ".toml" or p.exists():
        if not p.exists():
            raise ScenarioError(f"scenario file {p} does not exist")
        return p
    builtin = SCENARIO_DIR / f"{spec}.toml"
    if not builtin.exists():
        raise ScenarioError(
            f"unknown scenario {spec!r}: not a file, and not one of the built-in scenarios "
            f"({', '.join(builtin_scenarios())})"
        )
    return builtin


def load_scenario(spec: str | Path = "paper") -> Scenario:
    """Load and validate a scenario by built-in name or path."""
    path = _resolve(spec)
    where = str(path) if path.parent != SCENARIO_DIR else f"built-in scenario '{path.stem}'"
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{where}: not valid TOML: {exc}") from None
    return scenario_from_dict(data, where)


def scenario_from_dict(data: dict[str, Any], where: str = "scenario") -> Scenario:
    """Validate a parsed scenario mapping (see the module docstring for the keys)."""
    if is_fleet_scenario(data):
        return _fleet_scenario(data, where)
    unknown = sorted(set(data) - _TOP)
    if unknown:
        raise ScenarioError(f"{where}: unknown section(s) or key(s): {', '.join(unknown)}")
    for section, keys in _SCHEMA.items():
        sec = data.get(section, {})
        if not isinstance(sec, dict):
            raise ScenarioError(f"{where}: [{section}] must be a table")
        bad = sorted(set(sec) - set(keys))
        if bad:
            raise ScenarioError(
                f"{where}: unknown key(s) in [{section}]: {', '.join(bad)} "
                f"(allowed: {', '.join(keys)})"
            )
        missing = [k for k, req in keys.items() if req and k not in sec]
        if missing:
            raise ScenarioError(f"{where}: missing key(s) in [{section}]: {', '.join(missing)}")
    sim = data["simulation"]
    T, h = sim["T"], sim["h"]
    seed = sim.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ScenarioError(f"{where}: [simulation] seed = {seed!r} must be a non-negative integer")
    estimator = sim.get("estimator", "kalman")
    tracking = sim.get("tracking", "lq")
    _check_run(T, h, estimator, where, tracking)
    mapping: dict[str, Any] = {}
    section_of: dict[str, str] = {"noise_convention": "noise"}   # LinearSystem key -> section
    for section in ("vehicles", "disturbance", "reference", "cost", "noise"):
        section_of.update(dict.fromkeys(data.get(section, {}), section))
    for section in ("vehicles", "disturbance", "reference", "cost"):
        mapping.update(data.get(section, {}))
    noise = dict(data.get("noise", {}))
    if "convention" in noise:
        mapping["noise_convention"] = noise.pop("convention")
    mapping.update(noise)
    try:
        system = LinearSystem.from_mapping(mapping)
    except ModelError as exc:
        # a ModelError message starts with the name of the offending entry: add its section
        key = re.match(r"\w+", str(exc))
        section = section_of.get(key.group(0)) if key else None
        raise _in_section(where, section or "", str(exc)) from None
    return Scenario(name=str(data.get("name", Path(where).stem)),
                    description=str(data.get("description", "")), system=system,
                    T=float(T), h=float(h), seed=int(seed), estimator=estimator, source=where,
                    tracking=tracking)
