"""The registry of vehicle models: every name a scenario's ``[vehicles] model`` may take,
with what the rest of the code asks about it.

One :class:`ModelEntry` per name: how to build its :class:`~plant_model.vehicles.VehicleModel`
from a parameter table (:func:`make_vehicle` dispatches through it), which parameters it
accepts and which it makes explicit in a resolved fleet spec, its state layout, whether it is
nonlinear (its own vehicle FMU, per-vehicle deployment only) and which per-vehicle FMU kind
(:data:`orchestrator.cosim.build.FMU_KINDS`) runs it, whether it has a native (linear) form,
its family and linear design counterpart (``compare --what plants`` runs the linear and
the nonlinear models of one family, :func:`plants_of`), and the FMU kinds that stand between
the formation controller and its vehicle FMU (``stack``: none, the vehicle takes the force;
``("guidance", "autopilot")`` for ``remus100-6dof-guided``, whose vehicle FMU takes
actuator commands from an ``AuvAutopilot`` fed by an ``AuvGuidance``, docs/guidance.md).
A model that flies another model's vehicle through another stack names it
(``variant_of``): it shares that model's parameters and limits, and ``plants_of`` leaves
it out.

A new model is one module (its constructor from parameters) and one entry of
:data:`REGISTRY`. Code outside a model's own module asks the registry (:func:`get`,
:func:`find`) and never tests a model by its name.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .linalg_checks import ModelError
from .remus100.limits import VehicleLimits, remus_limits
from .remus100.models import (
    REMUS100_6DOF_PARAMS,
    remus100_6dof_design,
    remus100_6dof_explicit_params,
    remus100_fitted_from_params,
    remus_from_parameters,
)
from .vehicle_fmu import FMU_PARAMS, GUIDED_FMU_STACK, fmu_explicit_params, fmu_stack
from .vehicle_fmu_identification import fmu_vehicle_from_params
from .vehicles import (
    GENERIC_PARAMS,
    REMUS100_MAX_SPEED,
    REMUS100_PARAMS,
    VehicleModel,
    generic_from_params,
    remus100_from_params,
)

__all__ = ["DEFAULT_MODEL", "LAYOUTS", "REGISTRY", "VEHICLE_MODELS", "ModelEntry", "family_of",
           "find", "get", "listed_params", "make_vehicle", "plants_of", "vehicle_of"]

#: state layouts: ``ned`` x = [n, e, d, v_n, v_e, v_d] (m, m/s), NED forces in (N), NED
#: positions out (the leader's position and velocity are a vehicle's target, navigation
#: sensors fit); ``outputs`` any A, B1, B2, C (targets through pinv(C))
LAYOUTS = ("ned", "outputs")
#: the model of a ``[vehicles]`` table that names none
DEFAULT_MODEL = "remus100"

#: a stacked fleet FMU's parameter documentation: parameter -> (unit, description)
ParamDocs = Mapping[str, tuple[str | None, str]]

_REMUS100_DOCS: ParamDocs = {
    "mass": ("kg", "rigid-body mass"), "added_mass": ("kg", "added mass per NED axis"),
    "time_constant": ("s", "low-speed damping time constant per NED axis"),
    "drag_coefficient": (None, "parasitic drag coefficient on the frontal area"),
    "cruise_speed": ("m/s", "speed at which quadratic drag is linearized (secant)"),
}
_GENERIC_DOCS: ParamDocs = {
    "A": (None, "vehicle state matrix A_ii"), "B1": (None, "control input matrix B1_i"),
    "B2": (None, "disturbance input matrix B2_i"), "C": (None, "output matrix C_i"),
}


@dataclass(frozen=True)
class ModelEntry:
    """What the code asks about one vehicle model."""

    name: str                                       #: the scenario's model name
    doc: str                                        #: one line for docs and listings
    #: the model from a parameter table (raises ModelError without a location prefix)
    build: Callable[[Mapping[str, Any]], VehicleModel]
    params: tuple[str, ...]                         #: the parameters it accepts
    #: its parameters with every default made explicit (a resolved fleet spec)
    explicit_params: Callable[[VehicleModel], dict[str, Any]]
    family: str                                     #: e.g. "remus100", "generic"
    layout: str                                     #: one of :data:`LAYOUTS`
    nonlinear: bool = False                         #: its own vehicle FMU (per-vehicle only)
    fmu_kind: str = "vehicle"                       #: the per-vehicle FMU kind that runs it
    native: bool = True                             #: has a native (linear) FMU form
    #: a nonlinear model's linear design counterpart (the model its family compares it with)
    design: str | None = None
    #: the per-vehicle FMU kinds between the controller's force and the vehicle FMU, in
    #: signal order (keys of orchestrator.cosim.build.FMU_KINDS); () the vehicle takes u
    stack: tuple[str, ...] = ()
    #: the model whose vehicle (and parameters) this one flies through its own stack
    variant_of: str | None = None
    #: the parameters a stacked fleet FMU exposes (:mod:`plant_model.fleet_parameters`),
    #: unit and description; a nonlinear model has none (per-vehicle deployment only)
    param_docs: ParamDocs = dataclasses.field(default_factory=dict)
    #: the vehicle's limits (top speed, turn radius, depth rate) for the [design] checks;
    #: None: none known
    limits: Callable[[VehicleModel], VehicleLimits] | None = None
    #: its design model drives the guidance and autopilot FMUs (exported beside a fleet's
    #: FMUs: docs/guidance.md)
    guidance: bool = False
    #: the stack of one vehicle when it depends on its parameters (a vehicle FMU's port
    #: map: set-points go through the guidance, a force does not); None: :attr:`stack`
    stack_of: Callable[[VehicleModel], tuple[str, ...]] | None = None

    def stack_for(self, model: VehicleModel) -> tuple[str, ...]:
        """The FMU kinds between the controller and the vehicle FMU of ``model``."""
        return self.stack_of(model) if self.stack_of is not None else self.stack

    def __post_init__(self) -> None:
        if not self.nonlinear and set(self.params) - set(self.param_docs):
            raise ValueError(f"{self.name}: parameters without documentation for the fleet "
                             f"FMU: {sorted(set(self.params) - set(self.param_docs))}")
        if self.layout not in LAYOUTS:
            raise ValueError(f"{self.name}: layout {self.layout!r} is not one of {LAYOUTS}")
        if self.nonlinear and self.design is None:
            raise ValueError(f"{self.name}: a nonlinear model needs its linear design model")
        if self.stack and not self.nonlinear:
            raise ValueError(f"{self.name}: a stack between controller and vehicle needs a "
                             "nonlinear vehicle FMU")


def listed_params(keys: tuple[str, ...]) -> Callable[[VehicleModel], dict[str, Any]]:
    """An ``explicit_params`` that lists ``keys`` from the model's parameters (or its
    matrices of that name), as JSON-ready lists and numbers."""
    def explicit(model: VehicleModel) -> dict[str, Any]:
        return {k: (np.asarray(model.parameters[k]).tolist() if k in model.parameters
                    else getattr(model, k).tolist())
                for k in keys}
    return explicit


def _guided(build: Callable[[Mapping[str, Any]], VehicleModel]
            ) -> Callable[[Mapping[str, Any]], VehicleModel]:
    """``build``, its model named ``remus100-6dof-guided``."""
    def guided(params: Mapping[str, Any]) -> VehicleModel:
        return replace(build(params), name="remus100-6dof-guided")
    return guided


def _linear_remus_limits(model: VehicleModel) -> VehicleLimits:
    """A linear REMUS 100 model: the top speed of its range, nothing else."""
    return VehicleLimits(REMUS100_MAX_SPEED, None, None,
                         f"{model.name}: top speed {REMUS100_MAX_SPEED:g} m/s of the linear "
                         "model's range; no turn radius or depth rate")


def _remus6dof_limits(model: VehicleModel) -> VehicleLimits:
    """The nonlinear REMUS 100 of the model's data: top speed, turn radius, depth rate
    (:func:`plant_model.remus100.limits.remus_limits`)."""
    return remus_limits(remus_from_parameters(dict(model.parameters["nonlinear"])))


REGISTRY: dict[str, ModelEntry] = {e.name: e for e in (
    ModelEntry("remus100", "the linear REMUS 100 in NED, quadratic drag linearized at "
               "cruise_speed (plant_model.vehicles.remus100)",
               remus100_from_params, REMUS100_PARAMS, listed_params(REMUS100_PARAMS),
               family="remus100", layout="ned", param_docs=_REMUS100_DOCS,
               limits=_linear_remus_limits, guidance=True),
    ModelEntry("remus100-6dof", "the nonlinear 6-DOF REMUS 100 behind the same force "
               "interface, per-vehicle deployment only (docs/remus100-6dof.md)",
               remus100_6dof_design, REMUS100_6DOF_PARAMS, remus100_6dof_explicit_params,
               family="remus100", layout="ned", nonlinear=True, fmu_kind="remus6dof",
               native=False, design="remus100", limits=_remus6dof_limits, guidance=True),
    ModelEntry("remus100-fitted", "the first-order model fitted to remus100-6dof's "
               "frequency responses at 1.5 m/s (plant_model.remus100.models)",
               remus100_fitted_from_params, (), listed_params(()),
               family="remus100", layout="ned", limits=_linear_remus_limits, guidance=True),
    ModelEntry("generic", "any linear model A, B1, B2, C (plant_model.vehicles.generic)",
               generic_from_params, GENERIC_PARAMS, listed_params(GENERIC_PARAMS),
               family="generic", layout="outputs", param_docs=_GENERIC_DOCS),
    ModelEntry("remus100-6dof-guided", "remus100-6dof's vehicle and parameters flown through "
               "the guidance FMUs: force -> AuvGuidance -> AuvAutopilot -> the vehicle's "
               "actuators, per-vehicle deployment only (docs/guidance.md)",
               _guided(remus100_6dof_design), REMUS100_6DOF_PARAMS,
               remus100_6dof_explicit_params, family="remus100", layout="ned",
               nonlinear=True, fmu_kind="remus6dof_actuated", native=False,
               design="remus100", stack=("guidance", "autopilot"),
               variant_of="remus100-6dof", limits=_remus6dof_limits, guidance=True),
    ModelEntry("fmu", "a vehicle the user brings as an FMI 2.0 co-simulation FMU, with a "
               "port map; its design model identified from the FMU's frequency responses; "
               "per-vehicle deployment only (plant_model.vehicle_fmu, docs/scenarios.md)",
               fmu_vehicle_from_params, FMU_PARAMS, fmu_explicit_params, family="fmu",
               layout="ned", nonlinear=True, fmu_kind="vehicle_fmu", native=False,
               design="fmu", stack=GUIDED_FMU_STACK, stack_of=fmu_stack),
)}

#: the model names, in the registry's order
VEHICLE_MODELS: tuple[str, ...] = tuple(REGISTRY)


def find(name: Any) -> ModelEntry | None:
    """The entry of model ``name``, or None if there is none."""
    return REGISTRY.get(name) if isinstance(name, str) else None


def get(name: str) -> ModelEntry:
    """The entry of model ``name``.

    Raises
    ------
    ModelError
        If no model has that name (listing the known ones).
    """
    entry = find(name)
    if entry is None:
        raise ModelError(f"unknown vehicle model {name!r}; known models: "
                         f"{', '.join(VEHICLE_MODELS)}")
    return entry


def family_of(name: Any) -> str | None:
    """The family of model ``name`` (None for an unknown name)."""
    entry = find(name)
    return None if entry is None else entry.family


def vehicle_of(name: Any) -> str | None:
    """The model whose vehicle model ``name`` flies: its ``variant_of``, else itself (None
    for an unknown name); e.g. "remus100-6dof" for "remus100-6dof-guided"."""
    entry = find(name)
    return None if entry is None else entry.variant_of or entry.name


def plants_of(family: str) -> tuple[str, ...]:
    """The models ``compare --what plants`` runs for ``family``: each nonlinear model of the
    family (not a variant of another) after its linear design model, e.g. ("remus100",
    "remus100-6dof")."""
    out: list[str] = []
    for e in REGISTRY.values():
        if e.family == family and e.nonlinear and e.variant_of is None:
            out += [n for n in (e.design, e.name) if n not in out]
    return tuple(out)


def make_vehicle(model: str, params: Mapping[str, Any], where: str) -> VehicleModel:
    """Build a vehicle model by name from a parameter mapping (e.g. a scenario table).

    Parameters
    ----------
    model : str
        One of :data:`VEHICLE_MODELS`.
    params : Mapping[str, Any]
        The model's parameters (:attr:`ModelEntry.params`): the keyword arguments of
        :func:`plant_model.vehicles.remus100` (all optional) or of
        :func:`plant_model.vehicles.generic` (all required), those of
        :func:`plant_model.remus100.models.remus100_6dof_design` (also for
        ``remus100-6dof-guided``), none for ``remus100-fitted``.
    where : str
        Prefix of every error message (e.g. "vehicle 3").

    Returns
    -------
    VehicleModel
        The model.

    Raises
    ------
    ModelError
        If the model or a parameter is unknown, a generic matrix is missing or a value
        is invalid.
    """
    entry = find(model)
    if entry is None:
        raise ModelError(
            f"{where}: unknown vehicle model {model!r}; known models: {', '.join(VEHICLE_MODELS)}"
        )
    if not isinstance(params, Mapping):
        raise ModelError(f"{where}: the {model} parameters must be a table, got {params!r}")
    try:
        return entry.build(params)
    except ModelError as exc:
        raise ModelError(f"{where}: {exc}") from None
