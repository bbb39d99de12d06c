"""The schema of a fleet scenario file (:mod:`.fleet`): one pydantic model per section.

As in :mod:`.schema`: unknown keys are refused, types are strict, and the domain layer
checks what it knows, called from the validator of the section it belongs to:

- [vehicles]: :func:`plant_model.fleet.fleet_vehicles` (known models and parameters, one
  state and output size for all), offsets / positions / x0 rows, per-vehicle overrides;
- [leader]: :func:`plant_model.leader_paths.make_leader` (known path, its parameters), then
  :func:`plant_model.vehicle_targets.leader_state_map` against every vehicle model;
- [graph]: :func:`plant_model.graph.communication_graph` (weights, self-loops,
  duplicates, a path from the leader to every vehicle), the coupling p x p;
- [current] / [disturbance] / [noise] / [cost]: sizes from the vehicle models, covariances
  symmetric positive semidefinite, Q and R positive definite.

Sections checked against [vehicles] are not checked while [vehicles] is invalid (its own
error is the one reported).
"""
from __future__ import annotations

from typing import Annotated, Any, Self

import numpy as np
from annotated_types import Ge, Gt
from pydantic import (
    AllowInfNan,
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationInfo,
    field_validator,
    model_validator,
)

from controller_fmu.distributed import REGULATOR_FORMS
from controller_fmu.vehicle_law import LEADER_INFORMATION
from plant_model.acoustic.settings import check_network
from plant_model.fleet import (
    CONSENSUS_FORMS,
    CURRENT_SPEED,
    check_current_speeds,
    fleet_vehicles,
)
from plant_model.graph import communication_graph
from plant_model.leader import LeaderPath, check_turn_rate
from plant_model.leader_paths import make_leader
from plant_model.linalg_checks import (
    ModelError,
    as_matrix,
    as_vector,
    first_non_number,
    not_a_number,
)
from plant_model.navigation import NavigationSensors
from plant_model.system import NOISE_CONVENTIONS
from plant_model.vehicle_models import DEFAULT_MODEL, get
from plant_model.vehicle_targets import leader_state_map, state_offset
from plant_model.vehicles import VehicleModel

from .errors import bad_value
from .schema import (
    CostSection,
    Matrix,
    ScenarioFile,
    Seconds,
    Section,
    check_covariance,
    expect,
    one_of,
)
from .schema_design import DesignSection

__all__ = ["FleetScenario", "CurrentSection", "VehicleNoise", "VehicleOverride"]


class CurrentSection(Section):
    """[current] (or a vehicle's override): an ocean current per axis, a first-order
    Gauss-Markov process: time_constant > 0 s and sigma >= 0 m/s finite, w0 of length r."""

    time_constant: Annotated[Seconds, expect("must be a positive number of seconds")] = 600.0
    sigma: Annotated[float, Ge(0), AllowInfNan(False),
                     expect("must be a non-negative speed in m/s")] = 0.0
    w0: Matrix = None

    @field_validator("sigma")
    @classmethod
    def below_the_strongest_current(cls, sigma: float) -> float:
        """sigma at most :data:`plant_model.fleet.MAX_CURRENT_SPEED`."""
        if not CURRENT_SPEED.holds(sigma):
            raise bad_value("m/s must be {interval} ({why})",
                            interval=CURRENT_SPEED.interval(), why=CURRENT_SPEED.why)
        return sigma

    def check(self, r: int, name: str = "w0") -> None:
        """w0 (if given) is a finite vector of length r, each axis within
        +-:data:`plant_model.fleet.MAX_CURRENT_SPEED`."""
        if "w0" in self.model_fields_set:
            check_current_speeds(name, as_vector(name, self.w0, r))


class FleetDisturbanceSection(Section):
    """[disturbance] (instead of [current]): the same w' = K w + m_w for every vehicle:
    K r x r, W_w a number or r x r positive semidefinite, w0 of length r."""

    K: Matrix = Field(description="r x r matrix: w' = K w")
    W_w: Matrix = 0.0
    w0: Matrix = None

    def check(self, r: int) -> None:
        """K r x r, W_w r x r symmetric positive semidefinite, w0 of length r, finite."""
        as_matrix("K", self.K, (r, r))
        check_covariance("W_w", self.W_w, r)
        if "w0" in self.model_fields_set:
            as_vector("w0", self.w0, r)


class VehicleNoise(Section):
    """A vehicle's noise: process (W_x, p x p), position (V_y, s x s), reference (V_ybar,
    s x s): numbers or symmetric positive semidefinite matrices."""

    process: Matrix = 0.0
    position: Matrix = 0.0
    reference: Matrix = 0.0

    def check(self, states: int, outputs: int, prefix: str = "") -> None:
        """Each covariance is square of its size, symmetric and positive semidefinite."""
        for name, size in (("process", states), ("position", outputs), ("reference", outputs)):
            check_covariance(f"{prefix}{name}", getattr(self, name), size)


class FleetNoiseSection(VehicleNoise):
    """[noise]: the convention, and the noise of every vehicle (:class:`VehicleNoise`)."""

    convention: Annotated[str, one_of(NOISE_CONVENTIONS)] = "intensity"


class LeaderSection(BaseModel):
    """[leader]: ``path`` and that path's parameters, checked by
    :func:`plant_model.leader_paths.make_leader` (which refuses unknown parameters, naming the
    accepted ones: the only table whose keys the domain layer defines); ``noise`` the
    intensity W_z of the leader's state, a number or an l x l positive semidefinite matrix."""

    model_config = ConfigDict(extra="allow", strict=True, defer_build=True)
    path: str = Field(description="straight, circle, lawnmower or explicit")
    noise: Matrix = 0.0
    _path: LeaderPath = PrivateAttr()

    @model_validator(mode="after")
    def is_a_leader_path(self) -> Self:
        """The path builds (plant_model.leader) and its noise fits its state."""
        self._path = make_leader(self.path, self.parameters)
        check_covariance("noise", self.noise, self._path.l)
        return self

    @property
    def parameters(self) -> dict[str, Any]:
        """The path's parameters: every key but path and noise."""
        return dict(self.model_extra or {})

    @property
    def leader_path(self) -> LeaderPath:
        """The validated leader path."""
        return self._path


class GraphSection(Section):
    """[graph]: edges [[j, i, a_ij], ...] (vehicle i hears vehicle j), pinning [[i, a_i0],
    ...] (vehicle i hears the leader), coupling Gamma (p x p, identity by default; the
    protocol form needs it within the actuators' reach), consensus ("protocol" or
    "in-plant")."""

    edges: list[Any] = Field(default_factory=list)
    pinning: Any = Field(default_factory=list)
    coupling: Matrix = None
    #: "protocol" (the default): a force the controller applies, the plant keeps only the
    #: vehicles' physics; "in-plant": the protocol in the plant's dynamics (the paper's
    #: stacked model) (plant_model.fleet.CONSENSUS_FORMS)
    consensus: Annotated[str, one_of(CONSENSUS_FORMS)] = "protocol"

    def check(self, count: int, p: int) -> None:
        """A valid communication graph of count vehicles (plant_model.graph) and a finite
        p x p coupling."""
        communication_graph(count, self.edges, self.pinning)
        if self.coupling is not None:
            as_matrix("coupling", self.coupling, (p, p))


class VehicleOverride(Section):
    """One entry of [vehicles] overrides: what differs for vehicle ``vehicle`` (1..count)."""

    vehicle: Annotated[int, expect("must be a vehicle number (an integer)")] = Field(
        description="the vehicle number, 1..count")
    model: str | None = None
    params: dict[str, Any] = Field(default_factory=dict)
    offset: Matrix = None
    position: Matrix = None
    x0: Matrix = None
    current: CurrentSection | None = None
    noise: VehicleNoise | None = None
    cost: CostSection | None = None


def _rows(key: str, value: Any, count: int, width: int | None) -> list[list[float]]:
    """``value`` as count rows (of ``width`` finite numbers): one per vehicle."""
    want = f"{count} rows" + (f" of {width}" if width else "")
    if (item := first_non_number(value)) is not None:      # ["1", 0, 0]: text, not numbers
        raise ModelError(f"{key} must have one row per vehicle ({want}) of numbers; "
                         f"{not_a_number(item)}")
    try:
        arr = np.asarray(value, dtype=float) if not isinstance(value, str) else None
    except (TypeError, ValueError):
        # ragged rows or non-numbers: numpy's own message names neither section nor key
        raise ModelError(f"{key} must have one row per vehicle ({want}) of numbers; "
                         f"got {value!r}") from None
    if arr is None or arr.ndim != 2 or arr.shape[0] != count or (width and arr.shape[1] != width):
        got = "a string" if arr is None else f"shape {arr.shape}"
        raise ModelError(f"{key} must have one row per vehicle ({want}); got {got}")
    if not np.all(np.isfinite(arr)):
        raise ModelError(f"{key} has non-finite entries")
    return arr.tolist()


def _check_vehicle(name: str, v: dict[str, Any], mdl: VehicleModel) -> None:
    """One vehicle's start, offset and overrides fit its model (``name``: "vehicle i")."""
    if "position" in v:
        if mdl.position_states is None:
            raise ModelError(f"{name}: model {mdl.name} has no position states; give x0")
        if "x0" in v:
            raise ModelError(f"{name}: give position or x0, not both")
        as_vector(f"{name} position", v["position"], 3)
    if "x0" in v:
        as_vector(f"{name} x0", v["x0"], mdl.p)
    if "offset" in v:
        state_offset(mdl, as_vector(f"{name} offset", v["offset"], mdl.s))
    if "current" in v:
        v["current"].check(mdl.r, f"{name} current w0")
    if "noise" in v:
        v["noise"].check(mdl.p, mdl.s, f"{name} noise ")
    if "cost" in v:
        v["cost"].check(mdl.s, mdl.q, f"{name} cost ")


#: how a fleet's vehicles start ([vehicles] start)
VEHICLE_STARTS = ("given", "formation")


class FleetVehiclesSection(Section):
    """[vehicles]: ``count`` vehicles of ``model`` with ``params`` (plant_model.fleet:
    known models and parameters, one state and output size for all), offsets (count x s),
    positions (count x 3) or x0 (count x p), and per-vehicle ``overrides``."""

    count: Annotated[int, Ge(1), expect("must be a positive integer")] = Field(
        description="the number of vehicles, a positive integer")
    model: str = DEFAULT_MODEL
    params: dict[str, Any] = Field(default_factory=dict)
    offsets: Matrix = None
    positions: Matrix = None
    x0: Matrix = None
    #: "given": positions / x0 as given (in formation where none is); "formation": every
    #: vehicle starts in formation behind the leader, whatever positions or x0 say (a
    #: variant of a fleet with another leader path: envelope points, campaigns)
    start: Annotated[str, one_of(VEHICLE_STARTS)] = "given"
    overrides: list[VehicleOverride] = Field(default_factory=list)
    _merged: list[dict[str, Any]] = PrivateAttr(default_factory=list)
    _models: list[VehicleModel] = PrivateAttr(default_factory=list)

    @model_validator(mode="after")
    def are_valid_vehicles(self) -> Self:
        """Every vehicle (with its overrides) builds and fits its rows and overrides."""
        vehicles = self._with_overrides()
        models = fleet_vehicles({"vehicles": vehicles})
        if "positions" in self.model_fields_set and "x0" in self.model_fields_set:
            raise ModelError("give positions or x0, not both")
        for key, into, width in (("offsets", "offset", models[0].s),
                                 ("positions", "position", 3), ("x0", "x0", None)):
            if key in self.model_fields_set and (key == "offsets" or self.start == "given"):
                for v, row in zip(vehicles, _rows(key, getattr(self, key), self.count, width)):
                    v.setdefault(into, row)
        for i, (v, mdl) in enumerate(zip(vehicles, models), start=1):
            _check_vehicle(f"vehicle {i}", v, mdl)
        self._merged, self._models = vehicles, models
        return self

    def _with_overrides(self) -> list[dict[str, Any]]:
        """Per vehicle: model, params and the keys its overrides set (later entries win;
        a new model starts from empty params)."""
        vehicles = [{"model": self.model, "params": dict(self.params)} for _ in range(self.count)]
        for j, ov in enumerate(self.overrides, start=1):
            if not 1 <= ov.vehicle <= self.count:
                raise ModelError(f"overrides entry {j}: vehicle {ov.vehicle} does not exist; "
                                 f"vehicles are 1..{self.count}")
            target, given = vehicles[ov.vehicle - 1], ov.model_fields_set
            if "model" in given and ov.model != target["model"]:
                target["params"] = {}
            for key in ("model", "current", "x0", "offset", "position", "noise", "cost"):
                if key in given and (self.start == "given" or key not in ("x0", "position")):
                    target[key] = getattr(ov, key)
            target["params"].update(ov.params)
        return vehicles

    @property
    def merged(self) -> list[dict[str, Any]]:
        """Per vehicle: model, params, and offset / position / x0 / current / noise / cost
        where given (current, noise, cost as their section models)."""
        return self._merged

    @property
    def models(self) -> list[VehicleModel]:
        """The vehicle models, vehicle 1 first."""
        return self._models


def _valid_vehicles(info: ValidationInfo) -> FleetVehiclesSection | None:
    return info.data.get("vehicles")


class DistributedSection(Section):
    """[distributed]: the distributed law's observer gain mu (1/s, > 0), cohesion gain c
    (>= 0, 0: off), regulator equations ("continuous" or "sampled") and leader information
    ("messages": the pinned vehicles hear the leader; "planned": a path every vehicle
    knows from the start, no leader messages)."""

    mu: Annotated[float, Gt(0.0), AllowInfNan(False),
                  expect("must be a positive number (1/s)")] = 2.0
    cohesion: Annotated[float, Ge(0.0), AllowInfNan(False),
                        expect("must be a non-negative number")] = 0.0
    regulator: Annotated[str, one_of(REGULATOR_FORMS)] = "continuous"
    leader: Annotated[str, one_of(LEADER_INFORMATION)] = "messages"


class FleetScenario(ScenarioFile):
    """A fleet of vehicles on a communication graph following a virtual leader."""

    vehicles: FleetVehiclesSection
    leader: LeaderSection
    graph: GraphSection
    current: CurrentSection | None = None
    disturbance: FleetDisturbanceSection | None = None
    noise: FleetNoiseSection = Field(default_factory=FleetNoiseSection)
    cost: CostSection = Field(default_factory=CostSection)
    design: DesignSection | None = None
    distributed: DistributedSection = Field(default_factory=DistributedSection)
    network: dict[str, Any] | None = None
    sensors: dict[str, Any] | None = None

    @field_validator("sensors")
    @classmethod
    def sensors_fit_the_step(cls, sensors: dict[str, Any] | None,
                             info: ValidationInfo) -> dict[str, Any] | None:
        """[sensors]: kind = "position" (a fix every step, [noise] position: the default)
        or "remus" (acoustic fixes, DVL and depth at their rates, plant_model.navigation:
        periods whole numbers of steps, sigmas positive, dropouts in [0, 1)); REMUS models
        only."""
        vehicles, sim = _valid_vehicles(info), info.data.get("simulation")
        if sensors is None or vehicles is None or sim is None:
            return sensors
        kind = sensors.get("kind", "remus")
        if kind not in ("position", "remus"):
            raise ModelError(f"[sensors] kind = {kind!r} is not one of position, remus")
        if kind == "position":
            if len(sensors) > 1:
                raise ModelError("[sensors] kind = \"position\" takes no other key (its "
                                 "noise is [noise] position)")
            return None
        bad = next((i for i, m in enumerate(vehicles.models, 1)
                    if get(m.name).layout != "ned"), None)
        if bad is not None:
            raise ModelError(f"[sensors] kind = \"remus\" needs REMUS 100 vehicles; vehicle "
                             f"{bad} is {vehicles.models[bad - 1].name!r}")
        nav = NavigationSensors.from_mapping(sensors)
        nav.steps(sim.h)
        return nav.to_mapping()

    @field_validator("leader")
    @classmethod
    def leader_fits_the_vehicles(cls, leader: LeaderSection,
                                 info: ValidationInfo) -> LeaderSection:
        """Every vehicle model can follow the leader's path (its H has their outputs); the
        step h samples its turns (plant_model.leader.check_turn_rate)."""
        if (sim := info.data.get("simulation")) is not None:
            check_turn_rate(leader.leader_path, sim.h)
        if (vehicles := _valid_vehicles(info)) is not None:
            path = leader.leader_path
            for mdl in vehicles.models:
                leader_state_map(mdl, path.H, path.F)
        return leader

    @field_validator("graph")
    @classmethod
    def graph_connects_the_vehicles(cls, graph: GraphSection,
                                    info: ValidationInfo) -> GraphSection:
        """Edges and pinning between vehicles 1..count, a p x p coupling."""
        if (vehicles := _valid_vehicles(info)) is not None:
            graph.check(vehicles.count, vehicles.models[0].p)
        return graph

    @field_validator("current")
    @classmethod
    def current_fits_the_vehicles(cls, current: CurrentSection,
                                  info: ValidationInfo) -> CurrentSection:
        """w0 has one entry per disturbance input of every vehicle model."""
        if (vehicles := _valid_vehicles(info)) is not None:
            for r in sorted({mdl.r for mdl in vehicles.models}):
                current.check(r)
        return current

    @field_validator("disturbance")
    @classmethod
    def disturbance_replaces_the_current(cls, dist: FleetDisturbanceSection,
                                         info: ValidationInfo) -> FleetDisturbanceSection:
        """No [current] and no vehicle current next to [disturbance]; sizes of the models."""
        if info.data.get("current") is not None:
            raise ModelError("give [current] or [disturbance], not both")
        if (vehicles := _valid_vehicles(info)) is not None:
            for i, v in enumerate(vehicles.merged, start=1):
                if "current" in v:
                    raise ModelError(f"vehicle {i} has a current in [vehicles] overrides; "
                                     "give [current] or [disturbance], not both")
            for r in sorted({mdl.r for mdl in vehicles.models}):
                dist.check(r)
        return dist

    @field_validator("noise")
    @classmethod
    def noise_fits_the_vehicles(cls, noise: FleetNoiseSection,
                                info: ValidationInfo) -> FleetNoiseSection:
        """process is p x p, position and reference s x s (numbers or PSD matrices)."""
        if (vehicles := _valid_vehicles(info)) is not None:
            noise.check(vehicles.models[0].p, vehicles.models[0].s)
        return noise

    @field_validator("design")
    @classmethod
    def design_replaces_r(cls, design: DesignSection | None,
                          info: ValidationInfo) -> DesignSection | None:
        """A searched weight replaces R: no [cost] R or per-vehicle cost R beside it."""
        if design is None:
            return design
        cost, vehicles = info.data.get("cost"), _valid_vehicles(info)
        if design.chooses_weight and cost is not None and "R" in cost.model_fields_set:
            raise ModelError("[design] bandwidth / force_budget choose R: remove [cost] R")
        if design.chooses_weight and vehicles is not None:
            for ov in vehicles.overrides:
                if ov.cost is not None and "R" in ov.cost.model_fields_set:
                    raise ModelError(f"[design] bandwidth / force_budget choose R: remove the "
                                     f"cost R of vehicle {ov.vehicle} in [vehicles] overrides")
        return design

    @field_validator("network")
    @classmethod
    def network_fits_the_graph(cls, network: dict[str, Any] | None,
                               info: ValidationInfo) -> dict[str, Any] | None:
        """[network]: latency (s), period (s), loss, tdma, receiver and per-link overrides
        naming communication edges (plant_model.acoustic.settings.resolve_links); every error
        one line naming the link or entry."""
        vehicles, sim = _valid_vehicles(info), info.data.get("simulation")
        if network is None or vehicles is None or sim is None:
            return network
        return check_network(network, vehicles.count, sim.h).to_mapping()

    @field_validator("cost")
    @classmethod
    def cost_fits_the_vehicles(cls, cost: CostSection, info: ValidationInfo) -> CostSection:
        """Q is s x s and R q x q positive definite for every vehicle model."""
        if (vehicles := _valid_vehicles(info)) is not None:
            for q in sorted({mdl.q for mdl in vehicles.models}):
                cost.check(vehicles.models[0].s, q)
        return cost
