"""A fleet spec parsed once: its vehicle models, its communication graph, each vehicle's
view of the loop and the stacked system, built on first use and kept.

A scenario's fleet (:attr:`orchestrator.scenario.Scenario.fleet_model`) is such a
:class:`Fleet`; code that needs the models or the graph asks it instead of parsing the
spec again (:func:`plant_model.fleet.fleet_vehicles` builds one model per distinct vehicle
table, :func:`plant_model.fleet.fleet_graph` validates the graph: done once here).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

from .fleet import fleet_graph, fleet_system, fleet_vehicles
from .graph import CommunicationGraph
from .per_vehicle import vehicle_views
from .system import LinearSystem
from .vehicle_models import ModelEntry, get
from .vehicles import VehicleModel

__all__ = ["Fleet"]


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

    @property
    def vehicles(self) -> list[Mapping[str, Any]]:
        """The vehicle tables of the spec, in vehicle order."""
        return self.spec["vehicles"]

    @property
    def leader(self) -> Mapping[str, Any]:
        """The leader table of the spec (F, H, z0, ...)."""
        return self.spec["leader"]

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
