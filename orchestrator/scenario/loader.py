"""Scenarios: TOML files describing the system, the noise, the cost and the run.

A scenario is either the name of a built-in file in ``orchestrator/scenario/builtin/`` (``paper``
is the default) or a path to a ``.toml`` file. Sections and keys::

    name, description
    [simulation]  T (s), h (s), seed, estimator ("kalman" | "classical" | "ideal"),
                  tracking ("lq" | "regulator"), deployment ("stacked" | "per-vehicle"),
                  architecture ("centralized" | "distributed"), fmus ("python" | "native")
    [vehicles]    A, B1, B2, C, x0
    [disturbance] K, w0
    [reference]   F, H, z0
    [noise]       convention ("intensity" | "per_sample"), W_x, W_w, W_z, V_y, V_ybar
    [cost]        Q, R

A number where a square matrix is expected means that number times the identity.
A file with a ``[leader]`` or ``[graph]`` section describes a fleet of N vehicles on a
communication graph instead (:mod:`orchestrator.scenario.fleet`).
Each section is a pydantic model (:mod:`.schema`, :mod:`.schema_fleet`); every problem is
reported as a one-line :class:`ScenarioError` naming the file, section and key (:mod:`.errors`).
"""
from __future__ import annotations

import copy
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from controller_fmu.vehicle_law import DistributedSettings
from plant_model.acoustic.settings import NetworkSettings, check_network
from plant_model.discretization import check_step
from plant_model.fleet_model import Fleet
from plant_model.linalg_checks import ModelError
from plant_model.navigation import NavigationSensors
from plant_model.system import LinearSystem

from .errors import ScenarioError, validate_scenario
from .fleet import fleet_spec, is_fleet_scenario
from .nesting import check_nesting, loads_scenario_toml
from .schema import RunSettings, ScenarioFile, SystemScenario
from .size import check_fleet_model

__all__ = ["Scenario", "ScenarioError", "load_scenario", "builtin_scenarios", "SCENARIO_DIR",
           "relative_paths", "scenario_from_dict"]

SCENARIO_DIR = Path(__file__).resolve().parent / "builtin"

T_ = TypeVar("T_")


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
    #: the fleet, parsed once from its resolved spec (plant_model.fleet_model.Fleet: models,
    #: graph, leader, views, stacked system), if a fleet
    fleet: Fleet | None = None
    deployment: str = "stacked"             #: "stacked" or "per-vehicle" (fleets)
    architecture: str = "centralized"       #: "centralized" or "distributed" (per-vehicle)
    fmus: str = "python"                    #: "python" (pythonfmu) or "native" where linear
    #: gains of the distributed law ([distributed] of a fleet scenario)
    distributed: DistributedSettings = field(default_factory=DistributedSettings)
    #: the acoustic links' checked [network] table (per-vehicle fleets; None: perfect links)
    network: NetworkSettings | None = None
    #: the navigation sensors of the [sensors] table (None: a position fix every step)
    sensors: NavigationSensors | None = None
    #: [estimator] P0 as given (the time-varying Kalman filter's start covariance on the
    #: filter's state: [x; w; z], or one vehicle's [x; w] in a fleet; None: 0, the known
    #: start), checked against the system when the scenario is built
    estimator_P0: Any = None
    #: what [design] chose and found (orchestrator.analysis.weight_search.DesignResult;
    #: None without a [design] section)
    design: Any = None
    #: the parsed file the scenario was validated from (for variants of it)
    raw: Mapping[str, Any] | None = field(default=None, repr=False, compare=False)

    @property
    def nonlinear_vehicles(self) -> tuple[int, ...]:
        """The vehicles (1-based) of a nonlinear model (``remus100-6dof``), each its own FMU
        (plant_model.vehicle_models: ``nonlinear``)."""
        return () if self.fleet is None else self.fleet.nonlinear

    def with_vehicle_model(self, model: str) -> Scenario:
        """The same fleet scenario with every vehicle of ``model`` (e.g. the nonlinear
        ``remus100-6dof`` in place of ``remus100``): the model parameters the two REMUS
        models share (``cruise_speed``) are kept, the others dropped; the run settings
        are this scenario's.

        Raises
        ------
        ScenarioError
            If this is not a fleet scenario or the variant is invalid.
        """
        if self.fleet is None or self.raw is None:
            raise ScenarioError(f"{self.source}: a vehicle model variant needs a fleet "
                                "scenario read from a file")
        data = copy.deepcopy(dict(self.raw))
        shared = ("cruise_speed",)
        tables = [data["vehicles"], *data["vehicles"].get("overrides", [])]
        for table in tables:
            if "model" in table or table is data["vehicles"]:
                table["model"] = model
            if "params" in table:
                table["params"] = {k: v for k, v in table["params"].items() if k in shared}
        new = scenario_from_dict(data, f"{self.source} (vehicles: {model})")
        return replace(new, T=self.T, h=self.h, seed=self.seed, estimator=self.estimator,
                       tracking=self.tracking, deployment=self.deployment,
                       architecture=self.architecture, distributed=self.distributed,
                       network=self.network, fmus=self.fmus)

    @property
    def estimator_options(self) -> dict[str, Any]:
        """What the estimator builders take besides the model (estimator_fmu.registry):
        ``P0`` (None: 0) and ``fleet`` (P0 is one vehicle's)."""
        return {"P0": self.estimator_P0, "fleet": self.fleet is not None}

    @property
    def steps(self) -> int:
        """Number of communication steps: round(T / h)."""
        return int(round(self.T / self.h))

    def with_run(self, *, T: float | None = None, h: float | None = None,
                 seed: int | None = None, estimator: str | None = None,
                 tracking: str | None = None, deployment: str | None = None,
                 architecture: str | None = None, fmus: str | None = None,
                 network: Mapping[str, Any] | None = None) -> Scenario:
        """A copy with run settings overridden, checked like the file's [simulation];
        ``network`` keys (latency, period, loss, receiver, ...) override or start the
        [network] table."""
        new = replace(self, T=self.T if T is None else float(T),
                      h=self.h if h is None else float(h),
                      seed=self.seed if seed is None else int(seed),
                      estimator=self.estimator if estimator is None else estimator,
                      tracking=self.tracking if tracking is None else tracking,
                      deployment=self.deployment if deployment is None else deployment,
                      architecture=self.architecture if architecture is None else architecture,
                      fmus=self.fmus if fmus is None else fmus)
        if network:
            if new.fleet is None:
                raise ScenarioError(f"{self.source}: acoustic links (--latency, --period, "
                                    "--loss, --receiver) need a fleet scenario")
            try:
                new = replace(new, network=check_network(dict(network), new.fleet.N, new.h)
                              if self.network is None
                              else self.network.updated(network, new.fleet.N, new.h))
            except ModelError as exc:
                raise ScenarioError(f"{self.source}: {exc}") from None
        run = {"T": new.T, "h": new.h, "seed": new.seed, "estimator": new.estimator,
               "tracking": new.tracking, "deployment": new.deployment,
               "architecture": new.architecture, "fmus": new.fmus}
        validate_scenario(RunSettings, {"simulation": run}, new.source)
        if new.design is not None and new.T != self.T:      # the path over the run's horizon
            ld = new.fleet.leader
            try:
                new = replace(new, design=new.design.over(new.T, ld.F, ld.H, ld.z0))
            except ModelError as exc:                       # a horizon too long to sample
                raise ScenarioError(f"{self.source}: {exc}") from None
        _check_step(new)
        if new.h != self.h:
            _check_sampled(new, network_checked=bool(network))
        check_deployment(new)
        return new


def _check_sampled(sc: Scenario, network_checked: bool = False) -> None:
    """What the file's validation checked against its own h, checked again at a new h: the
    leader's turns (plant_model.leader.check_turn_rate), the [network] periods and cycle,
    the [sensors] periods and cycle."""
    if sc.fleet is None:
        return
    from plant_model.leader import check_turn_rate
    from plant_model.leader_paths import make_leader
    ld = sc.fleet.leader
    try:
        if ld.params is not None:
            check_turn_rate(make_leader(ld.kind, ld.params), sc.h)
        if sc.network is not None and not network_checked:
            check_network(sc.network, sc.fleet.N, sc.h)
        if sc.sensors is not None:
            sc.sensors.steps(sc.h)
    except ModelError as exc:
        raise ScenarioError(f"{sc.source}: {exc}") from None


def _check_step(sc: Scenario) -> None:
    """The step h can sample the model (:func:`plant_model.discretization.check_step`), and
    every nonlinear vehicle's RK4 sub-step divides it."""
    try:
        check_step(sc.system.augmented()[0], sc.h)
    except ModelError as exc:
        raise ScenarioError(f"{sc.source}: [simulation] h: {exc}") from None
    for i in sc.nonlinear_vehicles:
        substep = sc.fleet.vehicles[i - 1].params.get("substep")
        if substep is not None:
            from plant_model.remus100.plant import substep_count
            try:
                substep_count(sc.h, float(substep))
            except ModelError as exc:
                raise ScenarioError(f"{sc.source}: vehicle {i}: {exc}") from None


def check_deployment(sc: Scenario, network: bool = True) -> None:
    """A per-vehicle deployment needs a fleet whose consensus protocol is a force; a
    [network] needs the per-vehicle deployment (``network``: checked once the run settings
    are known, so that --deployment per-vehicle can select it)."""
    if sc.deployment != "per-vehicle":
        if network and sc.nonlinear_vehicles:
            model = sc.fleet.vehicles[sc.nonlinear_vehicles[0] - 1].model
            raise ScenarioError(f"{sc.source}: vehicle model {model} needs [simulation] "
                                "deployment = \"per-vehicle\" (a nonlinear vehicle is its own "
                                f"FMU, not a block of the stacked linear plant), not "
                                f"{sc.deployment!r}")
        if network and sc.sensors is not None:
            raise ScenarioError(f"{sc.source}: [sensors] needs [simulation] deployment = "
                                "\"per-vehicle\" (the sensors are the vehicles' own), not "
                                f"{sc.deployment!r}")
        if network and sc.network is not None:
            raise ScenarioError(f"{sc.source}: [network] needs [simulation] deployment = "
                                "\"per-vehicle\" (acoustic links join the vehicles' own "
                                f"FMUs), not {sc.deployment!r}")
        return
    if network:
        check_estimator(sc)
    if sc.fleet is None:
        raise ScenarioError(f"{sc.source}: [simulation] deployment = \"per-vehicle\" needs a "
                            "fleet scenario (a [vehicles] count, a [graph] and a [leader]); "
                            "this one is a single stacked system")
    form = sc.fleet.consensus
    if form != "protocol":
        raise ScenarioError(f"{sc.source}: [simulation] deployment = \"per-vehicle\" needs "
                            f"[graph] consensus = \"protocol\" (the protocol as a force each "
                            f"controller applies), not {form!r}: a vehicle's plant holds only "
                            "its own physics")


def check_estimator(sc: Scenario) -> None:
    """The scenario's estimator is accepted where it runs (its registry row): by the
    distributed law, over acoustic links, with [sensors]; else one line naming both."""
    from estimator_fmu.registry import ESTIMATORS, estimator_kind
    kind = estimator_kind(sc.estimator)
    where = (("the distributed per-vehicle loop", "distributed",
              "its analysis and predictions cover a vehicle's own steady filter or the truth")
             if sc.architecture == "distributed" else None,
             ("[network] (acoustic links)", "over_links",
              "the links' message-form predictions need a time-invariant estimator")
             if sc.network is not None else None,
             ("[sensors] (navigation at their own rates)", "navigation",
              "it needs a position fix every step")
             if sc.sensors is not None else None)
    for what, attr, why in filter(None, where):
        if not getattr(kind, attr):
            ok = [k for k, e in ESTIMATORS.items() if getattr(e, attr)]
            raise ScenarioError(f"{sc.source}: {what} needs estimator {' or '.join(ok)}, not "
                                f"{sc.estimator!r} ({why})")


def builtin_scenarios() -> list[str]:
    """Names of the scenarios shipped with the package."""
    return sorted(p.stem for p in SCENARIO_DIR.glob("*.toml"))


def _built(where: str, build: Callable[..., T_], *args: Any) -> T_:
    """``build(*args)``; a ModelError the section checks did not foresee names the source."""
    try:
        return build(*args)
    except ModelError as exc:
        raise ScenarioError(f"{where}: {exc}") from None


def _scenario(file: ScenarioFile, where: str, system: LinearSystem,
              fleet: Fleet | None = None) -> Scenario:
    sim = file.simulation
    sc = Scenario(name=file.name if file.name is not None else Path(where).stem,
                  description=file.description, system=system, T=sim.T, h=sim.h,
                  seed=sim.seed, estimator=sim.estimator, source=where,
                  tracking=sim.tracking, fleet=fleet, deployment=sim.deployment,
                  architecture=sim.architecture, fmus=sim.fmus)
    dist = getattr(file, "distributed", None)
    if dist is not None:
        sc = replace(sc, distributed=DistributedSettings(
            mu=dist.mu, cohesion=dist.cohesion, regulator=dist.regulator, leader=dist.leader))
    if getattr(file, "network", None) is not None:    # checked by the schema (check_network)
        sc = replace(sc, network=NetworkSettings(dict(file.network)))
    if getattr(file, "sensors", None) is not None:
        sc = replace(sc, sensors=NavigationSensors.from_mapping(file.sensors))
    if file.estimator is not None and file.estimator.P0 is not None:
        sc = replace(sc, estimator_P0=_initial_covariance(sc, file.estimator.P0, where))
    _check_step(sc)
    check_deployment(sc, network=False)
    return sc


def _initial_covariance(sc: Scenario, value: Any, where: str) -> np.ndarray:
    """[estimator] P0 as a matrix on the filter's state (one vehicle's in a fleet), refused
    in one line naming the matrix and its shape or least eigenvalue."""
    from estimator_fmu.kalman_tv import check_initial_covariance, stacked_initial_covariance
    try:
        if sc.fleet is None:
            return check_initial_covariance(value, sc.system.n + sc.system.r + sc.system.l)
        N = sc.fleet.N
        P0 = check_initial_covariance(value, (sc.system.n + sc.system.r) // N)
        stacked_initial_covariance(sc.system, P0, per_vehicle=P0.shape[0])
        return P0
    except ModelError as exc:
        raise ScenarioError(f"{where}: {exc}") from None


def _design(fleet: Any, spec: dict[str, Any], where: str) -> Any:
    """[design] at work (orchestrator.analysis.weight_search): the limits, u_max, the
    searched R (set in ``spec`` for every vehicle) and the path check, which refuses here
    with ``path_check = "refuse"``."""
    from plant_model.path_feasibility import finding_lines

    from ..analysis.weight_search import apply_weight, design_fleet
    options = fleet.design.model_dump()
    sim = fleet.simulation
    try:
        sigma = 0.0 if fleet.current is None else float(fleet.current.sigma)
        result = design_fleet(spec, options, h=sim.h, T=sim.T, estimator=sim.estimator,
                              tracking=sim.tracking, regulator=fleet.distributed.regulator,
                              current_sigma=sigma)
    except ModelError as exc:
        text = str(exc)
        text = text if text.startswith("[design]") else f"[design] {text}"
        raise ScenarioError(f"{where}: {text}") from None
    if options["path_check"] == "refuse" and result.findings:
        lines = finding_lines(result.findings)
        raise ScenarioError(f"{where}: [design] path_check = \"refuse\": {lines[0]}"
                            + (f" (and {len(lines) - 1} more)" if len(lines) > 1 else ""))
    if result.R is not None:
        apply_weight(spec, result.R, [m.q for m in fleet.vehicles.models])
    return result


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
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise ScenarioError(f"{where}: not a text file (byte {exc.start} is not UTF-8); "
                            "a scenario is a TOML file") from None
    except IsADirectoryError:
        raise ScenarioError(f"{where} is a folder; a scenario is a .toml file") from None
    except OSError as exc:
        raise ScenarioError(f"{where}: cannot be read: {exc.strerror}") from None
    return scenario_from_dict(relative_paths(loads_scenario_toml(text, where), path.parent), where)


def relative_paths(data: dict[str, Any], folder: Path) -> dict[str, Any]:
    """The file paths a parsed scenario names made absolute, from the scenario file's
    ``folder``: ``[vehicles] params.fmu`` (and an override's; plant_model.vehicle_fmu).
    Every reader of a scenario file passes through here (the loader, a campaign's base)."""
    veh = data.get("vehicles")
    if not isinstance(veh, dict):
        return data
    tables = [veh, *(o for o in veh.get("overrides", []) if isinstance(o, dict))]
    for t in tables:
        par = t.get("params")
        if isinstance(par, dict) and isinstance(par.get("fmu"), str) and par["fmu"]:
            par["fmu"] = str(folder / Path(par["fmu"]).expanduser())
    return data


def scenario_from_dict(data: Mapping[str, Any], where: str = "scenario") -> Scenario:
    """Validate a parsed scenario mapping (see the module docstring for the keys): the
    sections by :mod:`.schema` / :mod:`.schema_fleet`, then the system is built; a mapping
    nested deeper than :data:`.nesting.MAX_DEPTH` is refused first."""
    check_nesting(data, where)
    if is_fleet_scenario(data):
        # fleets need networkx (graphs) and more: imported only for them
        from plant_model.fleet import fleet_system, resolve_fleet_spec

        from .schema_fleet import FleetScenario
        fleet = validate_scenario(FleetScenario, data, where)
        check_fleet_model(fleet, where)         # before the stacked model is allocated
        spec = fleet_spec(fleet)
        design = _design(fleet, spec, where) if fleet.design is not None else None
        system = _built(where, fleet_system, spec)
        sc = _scenario(fleet, where, system,
                       _built(where, lambda: Fleet.of(resolve_fleet_spec(spec))))
        return replace(sc, raw=copy.deepcopy(dict(data)), design=design)
    single = validate_scenario(SystemScenario, data, where)
    system = _built(where, LinearSystem.from_mapping, single.system_mapping())
    return replace(_scenario(single, where, system), raw=copy.deepcopy(dict(data)))
