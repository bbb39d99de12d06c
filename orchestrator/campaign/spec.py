"""The campaign spec: a TOML file naming a base scenario, seeds and sweep axes.

::

    name = "estimators"            # optional (default: the file's stem)
    base = "paper"                 # a built-in scenario, "grid-N" (N REMUS 100 vehicles from
                                   # the fleet generator) or a .toml path (relative to this file)
    seeds = "0-3"                  # '0-9', '1,4,7', one seed, or an array of seeds
    engine = "fmu"                 # "fmu" (default) or "numpy"; --engine overrides
    check = 2                      # numpy engine: points re-run through the FMUs (0: none)
    seeds_per_task = 4             # optional: seeds of one point per task (default: balanced)

    [sweep]                        # dotted scenario keys -> values: the full grid
    "simulation.estimator" = ["kalman", "classical"]
    "simulation.T" = [20.0]
    "noise.V_y" = [0.5, 2.0]
    "vehicles.count" = [4, 20, 50] # fleets: offsets, positions and graph from the generator
    "cosim.coupling" = ["gauss-seidel", "jacobi"]   # the master's coupling (not a scenario key)

    [[points]]                     # or (and) a list of points, each crossed with the grid
    "simulation.estimator" = "kalman"
    "noise.V_y" = 1.0

A key is ``section.key`` of the base scenario's schema (:mod:`orchestrator.scenario.schema`,
:mod:`orchestrator.scenario.schema_fleet`); deeper tables (``vehicles.params.cruise_speed``)
and the leader's path parameters are allowed where the schema has a table. The seed is not a
sweep key (``seeds`` is). Every problem is one line naming the file and the key
(:class:`SpecError`, exit status 2 at the command line).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any, Literal, get_args, get_origin

from annotated_types import Ge
from pydantic import BaseModel, ConfigDict, Field

from ..scenario.errors import ScenarioError, _model_at, validate_scenario
from ..scenario.fleet import is_fleet_scenario
from ..scenario.loader import SCENARIO_DIR, _resolve, relative_paths
from ..scenario.nesting import loads_scenario_toml

__all__ = ["SpecError", "CampaignSpec", "load_spec", "parse_seed_text", "base_mapping",
           "COSIM_KEYS", "ENGINES", "FMU_ENGINE", "NUMPY_ENGINE"]

#: the engines: the FMU co-simulation (the reference) and the vectorised numpy loop
FMU_ENGINE, NUMPY_ENGINE = "fmu", "numpy"
ENGINES = (FMU_ENGINE, NUMPY_ENGINE)
#: keys of the pseudo-section ``cosim``: settings of the master, not of the scenario
COSIM_KEYS = {"coupling": ("gauss-seidel", "jacobi")}
MAX_SEEDS = 100_000


class SpecError(ScenarioError):
    """A campaign spec is invalid; the message names the file and the key."""


class CampaignSpec(BaseModel):
    """The validated spec (module docstring); ``seeds`` is the expanded list."""

    model_config = ConfigDict(extra="forbid", strict=True)
    name: str | None = None
    base: str = Field(description="a built-in scenario, grid-N or a .toml path")
    seeds: str | int | list[int] = "0"
    engine: Literal["fmu", "numpy"] = "fmu"
    check: Annotated[int, Ge(0)] = 2
    seeds_per_task: Annotated[int, Ge(1)] | None = None
    sweep: dict[str, Any] = Field(default_factory=dict)
    points: list[dict[str, Any]] = Field(default_factory=list)


def parse_seed_text(text: str) -> list[int]:
    """'0-9' -> 0..9, '1,4,7' -> [1, 4, 7], '3' -> [3] (ValueError with the reason).

    Parameters
    ----------
    text : str
        Ranges and seeds separated by commas.

    Returns
    -------
    list[int]
        The seeds, in the order given.
    """
    seeds: list[int] = []
    for part in text.split(","):
        part = part.strip()
        a, dash, b = part.partition("-")
        if not a.strip().isdigit() or (dash and not b.strip().isdigit()):
            raise ValueError(f"{text!r}: expected a range '0-9', a list '1,4,7' or one seed")
        lo, hi = int(a), int(b) if dash else int(a)
        if hi < lo:
            raise ValueError(f"{text!r}: the range {part} is empty")
        if hi - lo + len(seeds) >= MAX_SEEDS:
            raise ValueError(f"{text!r}: more than {MAX_SEEDS} seeds")
        seeds.extend(range(lo, hi + 1))
    return seeds


def _seed_list(value: str | int | list[int], where: str) -> list[int]:
    try:
        seeds = parse_seed_text(value) if isinstance(value, str) else (
            [value] if isinstance(value, int) else list(value))
    except ValueError as exc:
        raise SpecError(f"{where}: seeds = {exc}") from None
    if not seeds:
        raise SpecError(f"{where}: seeds is empty")
    bad = [s for s in seeds if not 0 <= s <= 2**31 - 1]
    if bad:
        raise SpecError(f"{where}: seeds: {bad[0]} is not from 0 to 2^31 - 1 (a 32-bit FMI "
                        "Integer)")
    if len(set(seeds)) != len(seeds):
        twice = sorted({s for s in seeds if seeds.count(s) > 1})
        raise SpecError(f"{where}: seeds: {', '.join(map(str, twice[:5]))} given more than once")
    return seeds


def base_mapping(base: str, spec_dir: Path | None = None) -> tuple[dict[str, Any], str]:
    """The parsed base scenario (a fresh mapping, as read from TOML) and its description.

    Parameters
    ----------
    base : str
        A built-in name, ``grid-N`` (:func:`orchestrator.scenario.generator.grid_fleet`) or a
        path (relative paths are taken from ``spec_dir`` first).
    spec_dir : Path, optional
        The spec file's folder.

    Returns
    -------
    data : dict[str, Any]
        The scenario mapping.
    where : str
        Names the base in error messages.

    Raises
    ------
    ScenarioError
        If the base cannot be found or read.
    """
    if base.startswith("grid-") and base[5:].isdigit() and int(base[5:]) >= 1:
        from ..scenario.generator import grid_fleet
        return grid_fleet(int(base[5:])), f"generated scenario '{base}'"
    candidate = Path(base)
    if spec_dir is not None and not candidate.is_absolute() and (spec_dir / candidate).exists():
        candidate = spec_dir / candidate
    path = _resolve(candidate if candidate.exists() else base)
    where = str(path) if path.parent != SCENARIO_DIR else f"built-in scenario '{path.stem}'"
    try:
        return relative_paths(loads_scenario_toml(path.read_text(encoding="utf-8"), where),
                              path.parent), where
    except (UnicodeDecodeError, OSError) as exc:
        raise ScenarioError(f"{where}: cannot be read as TOML: {exc}") from None


def _free_table(model: Any, loc: list[str]) -> bool:
    """Whether ``loc`` is a table the schema takes as a free mapping (``dict[str, Any] |
    None``: [network], [sensors]), checked by its own validator."""
    parent = _model_at(model, loc[:-1]) if len(loc) > 1 else model
    if parent is None or loc[-1] not in parent.model_fields:
        return False
    annotation = parent.model_fields[loc[-1]].annotation
    return any(get_origin(a) is dict or a is dict
               for a in (annotation, *get_args(annotation)))


def _section_problem(data: dict[str, Any], name: str) -> str | None:
    """Why ``name`` is not a section a point may replace whole (None if it is)."""
    if is_fleet_scenario(data):
        from ..scenario.schema_fleet import FleetScenario as model
    else:
        from ..scenario.schema import SystemScenario as model
    if name in ("simulation", "name", "description"):
        return ("is not a dotted key 'section.key' (e.g. 'simulation.estimator'); only a "
                "model section (e.g. 'leader') may be replaced whole")
    if _model_at(model, [name]) is None and not _free_table(model, [name]):
        return (f"is not a dotted key 'section.key' (e.g. 'simulation.estimator'), nor a "
                f"section of the base scenario to replace with a table ({name!r} is none)")
    return None


def _key_problem(data: dict[str, Any], key: str) -> str | None:
    """Why ``key`` is not a dotted key of the scenario ``data``'s schema (None if it is)."""
    parts = key.split(".")
    if not all(parts):
        return "is not a dotted key 'section.key' (e.g. 'simulation.estimator')"
    if len(parts) == 1:                # a whole section, replaced by a table value
        return _section_problem(data, parts[0])
    if parts[0] == "cosim":
        if len(parts) != 2 or parts[1] not in COSIM_KEYS:
            return f"is unknown; the cosim keys are {', '.join(COSIM_KEYS)}"
        return None
    if parts[:2] == ["simulation", "seed"]:
        return "is set by 'seeds', not swept"
    if is_fleet_scenario(data):
        from ..scenario.schema_fleet import FleetScenario as model
    else:
        from ..scenario.schema import SystemScenario as model
    for i in range(1, len(parts)):
        table = _model_at(model, parts[:i])
        if table is None and _free_table(model, parts[:i]):
            return None                # [network], [sensors]: their validators check keys
        if table is None:
            return f"is unknown: {'.'.join(parts[:i])} is not a table of the base scenario"
        if table.model_config.get("extra") == "allow":        # the leader's path parameters
            return None
        if parts[i] not in table.model_fields:
            return (f"is unknown: {'.'.join(parts[:i])} has no key {parts[i]!r} (allowed: "
                    f"{', '.join(table.model_fields)})")
        if i + 1 < len(parts) and get_origin(table.model_fields[parts[i]].annotation) is dict:
            return None                # a free table (vehicles.params): its model checks it
    return None


def load_spec(path: Path | str) -> tuple[CampaignSpec, list[int], dict[str, Any], str]:
    """Read and validate a campaign spec.

    Parameters
    ----------
    path : Path or str
        The TOML file.

    Returns
    -------
    spec : CampaignSpec
        The validated spec.
    seeds : list[int]
        The expanded seeds.
    base : dict[str, Any]
        The base scenario mapping (:func:`base_mapping`).
    base_where : str
        Names the base scenario.

    Raises
    ------
    SpecError
        Naming the file and the key, for any problem.
    """
    path = Path(path)
    where = str(path)
    try:
        data = loads_scenario_toml(path.read_text(encoding="utf-8"), where)
    except ScenarioError as exc:                # not TOML, or nested too deep
        raise SpecError(str(exc)) from None
    except FileNotFoundError:
        raise SpecError(f"{where}: campaign spec not found") from None
    except IsADirectoryError:
        raise SpecError(f"{where} is a folder; a campaign spec is a .toml file") from None
    except UnicodeDecodeError as exc:
        raise SpecError(f"{where}: not valid TOML: {exc}") from None
    except OSError as exc:
        raise SpecError(f"{where}: cannot be read: {exc.strerror}") from None
    try:
        spec = validate_scenario(CampaignSpec, data, where)
    except ScenarioError as exc:
        raise SpecError(str(exc)) from None
    seeds = _seed_list(spec.seeds, where)
    try:
        base, base_where = base_mapping(spec.base, path.parent)
    except ScenarioError as exc:
        raise SpecError(f"{where}: base = {spec.base!r}: {exc}") from None
    tables = [("sweep", spec.sweep)] + [(f"points[{i + 1}]", p) for i, p in
                                         enumerate(spec.points)]
    for table, entries in tables:
        for key, value in entries.items():
            problem = _key_problem(base, key)
            if problem:
                raise SpecError(f"{where}: [{table}] key {key!r} {problem}")
            if table == "sweep" and not isinstance(value, list):
                raise SpecError(f"{where}: [sweep] key {key!r} = {value!r} must be an array "
                                "of values (the axis)")
            values = value if table == "sweep" else [value]
            if table == "sweep" and not values:
                raise SpecError(f"{where}: [sweep] key {key!r} has no values")
            if "." not in key and not all(isinstance(v, dict) for v in values):
                raise SpecError(f"{where}: [{table}] key {key!r} replaces a whole section: "
                                "its value must be a table, e.g. {path = \"circle\", ...}")
            for v in values:
                if isinstance(v, float) and not math.isfinite(v):
                    raise SpecError(f"{where}: [{table}] key {key!r}: {v} is not finite")
                if key.startswith("cosim.") and v not in COSIM_KEYS[key[6:]]:
                    raise SpecError(f"{where}: [{table}] key {key!r}: {v!r} is not one of "
                                    f"{', '.join(COSIM_KEYS[key[6:]])}")
    return spec, seeds, base, base_where
