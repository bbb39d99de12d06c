"""A fleet spec parsed once: its vehicle models, its communication graph, each vehicle's
view of the loop and the stacked system, built on first use and kept.

A scenario's fleet (:attr:`orchestrator.scenario.Scenario.fleet`) is such a
:class:`Fleet`; code that needs the models, the graph, the leader or a vehicle's table asks
it instead of parsing the spec again (:func:`plant_model.fleet.fleet_vehicles` builds one
model per distinct vehicle table, :func:`plant_model.fleet.fleet_graph` validates the graph:
done once here). The spec itself is kept for what hands it on whole (the stacked FMUs'
configuration, a scenario's key).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from .fleet import FleetInfo, fleet_graph, fleet_info, fleet_system, fleet_vehicles
from .graph import CommunicationGraph
from .per_vehicle import vehicle_views
from .system import LinearSystem
from .vehicle_models import DEFAULT_MODEL, ModelEntry, get
from .vehicles import VehicleModel

__all__ = ["Fleet", "LeaderSpec", "VehicleSpec"]


@dataclass(frozen=True, eq=False)
class LeaderSpec:
    """The leader's table of a fleet spec, typed: its path (``kind``, ``params``: None for a
    leader given by its matrices) and its exosystem as float arrays."""

    kind: str | None
    params: Mapping[str, Any] | None
    F: np.ndarray                       #: l x l (1/s)
    H: np.ndarray                       #: s x l, the tracked output H z
    z0: np.ndarray                      #: (l,), zeros where the spec gives none
    W_z: Any                            #: the process noise intensity as given (0: none)

    @classmethod
    def of(cls, table: Mapping[str, Any]) -> LeaderSpec:
        """From a spec's ``leader`` table."""
        F = np.asarray(table["F"], dtype=float)
        z0 = table.get("z0")
        return cls(kind=table.get("kind"), params=table.get("params"), F=F,
                   H=np.asarray(table["H"], dtype=float),
                   z0=np.zeros(F.shape[0]) if z0 is None else np.asarray(z0, dtype=float),
                   W_z=table.get("W_z", 0.0))


@dataclass(frozen=True, eq=False)
class VehicleSpec:
    """One vehicle's table of a fleet spec, typed (what consumers read of it)."""

    number: int                         #: 1-based
    model: str                          #: the registry name (plant_model.vehicle_models)
    params: Mapping[str, Any]           #: the model's parameters as the spec gives them
    offset: np.ndarray                  #: (s,) formation offset d_i, zeros where none


@dataclass(frozen=True, eq=False)
class Fleet:
    """The parsed fleet (module docstring); immutable once made."""

    spec: Mapping[str, Any]                 #: the fleet spec it was parsed from
    models: tuple[VehicleModel, ...]        #: one per vehicle, in vehicle order
    graph: CommunicationGraph               #: the validated communication graph
    #: what analyses built on this fleet keep (e.g. the distributed law's agents), by key
    memo: dict[str, Any] = field(default_factory=dict, repr=False)

    @classmethod
    def of(cls, spec: Mapping[str, Any]) -> Fleet:
        """Parse ``spec`` (:mod:`plant_model.fleet`).

        Raises
        ------
        ModelError
            Naming the vehicle or graph entry that is invalid.
        """
        return cls(spec, tuple(fleet_vehicles(spec)), fleet_graph(spec))

    @property
    def N(self) -> int:
        """The number of vehicles."""
        return len(self.models)

    @cached_property
    def vehicles(self) -> tuple[VehicleSpec, ...]:
        """Each vehicle's table, typed, in vehicle order."""
        return tuple(VehicleSpec(
            number=i, model=str(v.get("model", DEFAULT_MODEL)), params=v.get("params", {}),
            offset=np.asarray(v.get("offset", np.zeros(mdl.s)), dtype=float))
            for i, (v, mdl) in enumerate(zip(self.spec["vehicles"], self.models), start=1))

    @property
    def model_names(self) -> tuple[str, ...]:
        """Each vehicle's model name, in vehicle order."""
        return tuple(v.model for v in self.vehicles)

    @property
    def offsets(self) -> tuple[np.ndarray, ...]:
        """Each vehicle's formation offset d_i (output space), in vehicle order."""
        return tuple(v.offset for v in self.vehicles)

    @cached_property
    def leader(self) -> LeaderSpec:
        """The leader's table, typed."""
        return LeaderSpec.of(self.spec["leader"])

    @property
    def consensus(self) -> str:
        """Where the consensus protocol acts: "in-plant" or "protocol"
        (plant_model.fleet.CONSENSUS_FORMS)."""
        return str(self.spec.get("graph", {}).get("consensus", "in-plant"))

    @property
    def edges(self) -> tuple[tuple[int, int, float], ...]:
        """The graph's edges (j, i, a_ij): vehicle i hears vehicle j."""
        return tuple((int(j), int(i), float(a)) for j, i, a in self.graph.edges)

    @property
    def pinning(self) -> tuple[tuple[int, float], ...]:
        """The graph's pins (i, a_i0): vehicle i hears the leader."""
        return tuple((int(i), float(a)) for i, a in self.graph.pinning)

    def info(self, system: LinearSystem | None = None) -> FleetInfo:
        """The layout of the stacked vectors (:func:`plant_model.fleet.fleet_info`; of
        ``system``, the stacked system, when given)."""
        return fleet_info(self.spec, system)

    @property
    def entries(self) -> tuple[ModelEntry, ...]:
        """Each vehicle's registry entry (plant_model.vehicle_models; not kept: an entry
        holds functions, and a fleet goes to worker processes)."""
        return tuple(get(m.name) for m in self.models)

    @cached_property
    def nonlinear(self) -> tuple[int, ...]:
        """The vehicles (1-based) of a nonlinear model, each its own FMU."""
        return tuple(i for i, e in enumerate(self.entries, start=1) if e.nonlinear)

    @cached_property
    def views(self) -> tuple[LinearSystem, ...]:
        """Each vehicle's view of the loop (:func:`plant_model.per_vehicle.vehicle_views`)."""
        return tuple(vehicle_views(self.spec, models=self.models))

    @cached_property
    def system(self) -> LinearSystem:
        """The stacked system (:func:`plant_model.fleet.fleet_system`)."""
        return fleet_system(self.spec, models=self.models, graph=self.graph)
