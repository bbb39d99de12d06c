"""The schema of a single-system scenario file: one pydantic model per section.

Every table refuses unknown keys (``extra="forbid"``) and is strict: a boolean is not a
number, ``"0.01"`` is not a number, ``1.5`` is not a seed. Matrices are checked by the
domain layer (:mod:`plant_model.linalg_checks`, :func:`plant_model.vehicles.generic`),
called from the validator of the section they belong to, so a wrong shape or a
non-symmetric covariance is reported under that section. A section whose sizes come from
another one ([disturbance], [reference], [noise], [cost] from [vehicles]) is checked by a
validator of the whole file, once [vehicles] is valid.

:mod:`.schema_fleet` reuses :class:`Section`, :class:`SimulationSection`,
:class:`CostSection` and the helpers for the fleet scenarios.
"""
from __future__ import annotations

import unicodedata
from collections.abc import Sequence
from typing import Annotated, Any, Self

import numpy as np
from annotated_types import Ge, Gt, Le
from pydantic import (
    AllowInfNan,
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationError,
    ValidationInfo,
    WrapValidator,
    field_validator,
    model_validator,
)

from controller_fmu.regulator import TRACKING_MODES
from controller_fmu.vehicle_law import ARCHITECTURES, DEPLOYMENTS
from estimator_fmu.registry import DEFAULT_ESTIMATOR, ESTIMATOR_MODES
from fmu_common.native_form import FMU_IMPLEMENTATIONS
from plant_model.linalg_checks import (
    as_matrix,
    as_number,
    as_vector,
    check_symmetric_pd,
    check_symmetric_psd,
)
from plant_model.system import NOISE_CONVENTIONS
from plant_model.vehicles import VehicleModel, generic

from .errors import bad_value, unknown_choice

__all__ = ["Section", "SimulationSection", "RunSettings", "CostSection", "ScenarioFile",
           "SystemScenario", "EstimatorSection", "Matrix", "Seconds", "expect", "one_of",
           "square_matrix", "check_covariance"]

#: a number or nested lists: checked by plant_model.linalg_checks in the section's validator
Matrix = Any


def expect(message: str) -> WrapValidator:
    """Report any failure of the type and constraints before it as ``key = value <message>``."""
    def check(value: Any, handler: Any) -> Any:
        try:
            return handler(value)
        except ValidationError:
            raise bad_value(message) from None
    return WrapValidator(check)


def one_of(choices: Sequence[str]) -> WrapValidator:
    """Accept exactly one of ``choices`` (strings), else ``key <value> is unknown; ...``."""
    def check(value: Any, handler: Any) -> Any:
        if not (isinstance(value, str) and value in choices):
            raise unknown_choice(choices)
        return handler(value)
    return WrapValidator(check)


def square_matrix(name: str, value: Any, size: int) -> np.ndarray:
    """A finite size x size matrix; a number (not a boolean) means that number times I."""
    if isinstance(value, (list, tuple, np.ndarray)):
        return as_matrix(name, value, (size, size))
    return as_number(name, value) * np.eye(size)


def check_covariance(name: str, value: Any, size: int) -> None:
    """``value`` is a symmetric positive semidefinite size x size matrix (or number)."""
    check_symmetric_psd(name, square_matrix(name, value, size))


class Section(BaseModel):
    """A table of a scenario file: unknown keys are refused and types are strict. Schemas
    are built at the first validation (``defer_build``): importing costs less, and a
    single-system file never builds the fleet's."""

    model_config = ConfigDict(extra="forbid", strict=True, defer_build=True)


Seconds = Annotated[float, Gt(0), AllowInfNan(False)]


class SimulationSection(Section):
    """[simulation]: h > 0 and T >= h finite numbers of seconds, T a whole number of steps
    h, seed a non-negative 32-bit integer, estimator and tracking one of the modes the FMUs
    implement."""

    # h before T: fields are validated in this order, and T's check reads the valid h
    h: Annotated[Seconds, expect("must be a positive number of seconds")] = Field(
        description="the communication step in s, positive")
    T: Annotated[float, AllowInfNan(False)] = Field(
        description="the horizon in s, at least one step h")
    # the FMUs' seed is an FMI Integer: 32 bits, signed
    seed: Annotated[int, Ge(0), Le(2**31 - 1),
                    expect("must be a non-negative integer below 2^31 (the FMUs' seed is a "
                           "32-bit FMI Integer)")] = 0
    estimator: Annotated[str, one_of(ESTIMATOR_MODES)] = DEFAULT_ESTIMATOR
    tracking: Annotated[str, one_of(TRACKING_MODES)] = "lq"
    #: fleets: one set of FMUs for the stacked fleet, or one per vehicle
    deployment: Annotated[str, one_of(DEPLOYMENTS)] = "stacked"
    #: per-vehicle fleets: the stacked law cut by vehicle, or neighbour-only information
    architecture: Annotated[str, one_of(ARCHITECTURES)] = "centralized"
    #: the FMUs that run: pythonfmu, or native (C) where a component has a linear form
    fmus: Annotated[str, one_of(FMU_IMPLEMENTATIONS)] = "python"

    @field_validator("T", mode="wrap")
    @classmethod
    def at_least_one_step(cls, value: Any, handler: Any, info: ValidationInfo) -> float:
        """T is a finite number of seconds, at least one step h (when h is valid)."""
        h = info.data.get("h")
        try:
            T = handler(value)
        except ValidationError:
            T = None
        if T is None or (h is not None and T < h):
            raise bad_value("must be at least one step h = {h} s", h=h)
        if h is not None:
            n = T / h
            if abs(n - round(n)) > 1e-9 * n:
                raise bad_value("is not a whole number of steps h = {h} s ({n} steps); "
                                "the run would stop at {stop} s", h=h, n=f"{n:.6g}",
                                stop=f"{round(n) * h:.6g}")
        return T


class RunSettings(Section):
    """The [simulation] section alone: :meth:`Scenario.with_run` checks overrides with it."""

    simulation: SimulationSection


class CostSection(Section):
    """[cost]: Q (tracking error) and R (control) positive definite, numbers or matrices."""

    Q: Matrix = 1.0
    R: Matrix = 1.0

    def check(self, outputs: int, inputs: int, prefix: str = "") -> None:
        """Q is outputs x outputs and R inputs x inputs, both symmetric positive definite."""
        check_symmetric_pd(f"{prefix}Q", square_matrix(f"{prefix}Q", self.Q, outputs))
        check_symmetric_pd(f"{prefix}R", square_matrix(f"{prefix}R", self.R, inputs))


class EstimatorSection(Section):
    """[estimator]: the options of the estimators that take some (estimator_fmu.registry).

    ``P0``: the time-varying Kalman filter's start covariance (``kalman-tv``): a number
    (times I) or a symmetric positive semidefinite matrix on the filter's state, [x; w; z]
    ((n + r + l) square) for a single system, one vehicle's [x; w] for a fleet (every
    vehicle starts from it); its shape and eigenvalues are checked when the scenario is
    built (:func:`estimator_fmu.kalman_tv.check_initial_covariance`). Default 0: the
    known start."""

    P0: Matrix = None


class ScenarioFile(Section):
    """The keys common to every scenario file: name, description, [simulation] and the
    optional [estimator]."""

    name: str | None = None
    description: str = ""
    simulation: SimulationSection
    estimator: EstimatorSection | None = None

    @field_validator("name")
    @classmethod
    def printable_name(cls, value: str | None) -> str | None:
        """The name labels the recording and (sanitised) names the output files: printable
        text, no control characters, at most 200 characters."""
        if value is None:
            return value
        if not value.strip() or len(value) > 200 or any(
                unicodedata.category(c).startswith("C") for c in value):
            raise bad_value("must be printable text of 1 to 200 characters without control "
                            "characters (it names the recording and the output files)")
        return value


# the single stacked system ----------------------------------------------------------
class VehiclesSection(Section):
    """[vehicles] x' = A x + B1 u + B2 w, y = C x: a valid plant_model.vehicles.generic
    model (finite A n x n, B1 n x m, B2 n x r, C p x n) and x0 of length n."""

    A: Matrix = Field(description="n x n matrix")
    B1: Matrix = Field(description="n x m matrix")
    B2: Matrix = Field(description="n x r matrix")
    C: Matrix = Field(description="p x n matrix")
    x0: Matrix = None
    _model: VehicleModel = PrivateAttr()

    @model_validator(mode="after")
    def is_a_linear_model(self) -> Self:
        """Build the vehicle model (plant_model's shape and finiteness checks) and check x0."""
        self._model = generic(self.A, self.B1, self.B2, self.C)
        if "x0" in self.model_fields_set:
            as_vector("x0", self.x0, self._model.p)
        return self

    @property
    def sizes(self) -> dict[str, int]:
        """n states, m inputs, r disturbances, p outputs."""
        mdl = self._model
        return {"n": mdl.p, "m": mdl.q, "r": mdl.r, "p": mdl.s}


class DisturbanceSection(Section):
    """[disturbance] w' = K w: K r x r and w0 of length r (r = columns of B2)."""

    K: Matrix = Field(description="r x r matrix")
    w0: Matrix = None

    def check(self, r: int) -> None:
        """K is a finite r x r matrix, w0 a finite vector of length r."""
        as_matrix("K", self.K, (r, r))
        if "w0" in self.model_fields_set:
            as_vector("w0", self.w0, r)


class ReferenceSection(Section):
    """[reference] z' = F z, ybar = H z: F l x l, H p x l (p = rows of C), z0 of length l."""

    F: Matrix = Field(description="l x l matrix")
    H: Matrix = Field(description="p x l matrix")
    z0: Matrix = None

    def check(self, p: int) -> None:
        """F square, H p x l, z0 of length l, all finite."""
        F = as_matrix("F", self.F)
        l_ = as_matrix("F", F, (F.shape[0], F.shape[0])).shape[0]
        as_matrix("H", self.H, (p, l_))
        if "z0" in self.model_fields_set:
            as_vector("z0", self.z0, l_)

    @property
    def l(self) -> int:  # noqa: E743 - the paper's name
        """Number of reference states (rows of F); valid once the section is checked."""
        return as_matrix("F", self.F).shape[0]


class NoiseSection(Section):
    """[noise]: the convention and the intensities (or per-sample covariances) W_x (n),
    W_w (r), W_z (l), V_y (p), V_ybar (p): symmetric positive semidefinite, or numbers."""

    convention: Annotated[str, one_of(NOISE_CONVENTIONS)] = "intensity"
    W_x: Matrix = 0.0
    W_w: Matrix = 0.0
    W_z: Matrix = 0.0
    V_y: Matrix = 0.0
    V_ybar: Matrix = 0.0

    def check(self, n: int, r: int, l_: int, p: int) -> None:
        """Each covariance is square of its size, symmetric and positive semidefinite."""
        for name, size in (("W_x", n), ("W_w", r), ("W_z", l_), ("V_y", p), ("V_ybar", p)):
            check_covariance(name, getattr(self, name), size)


#: a single system's section -> the vehicle sizes its ``check`` takes
SECTION_SIZES = {"disturbance": ("r",), "reference": ("p",), "cost": ("p", "m")}


class SystemScenario(ScenarioFile):
    """A single stacked system (:class:`plant_model.system.LinearSystem`) and its run."""

    vehicles: VehiclesSection
    disturbance: DisturbanceSection
    reference: ReferenceSection
    cost: CostSection = Field(default_factory=CostSection)
    noise: NoiseSection = Field(default_factory=NoiseSection)

    @field_validator("disturbance", "reference", "cost")
    @classmethod
    def section_fits(cls, section: DisturbanceSection | ReferenceSection | CostSection,
                     info: ValidationInfo) -> DisturbanceSection | ReferenceSection | CostSection:
        """The section's sizes agree with the vehicles' (:data:`SECTION_SIZES`): K is r x r
        and w0 of length r (r = columns of B2); F is square, H has p rows (p = rows of C)
        and l columns, z0 length l; Q is p x p and R m x m, positive definite."""
        if (vehicles := info.data.get("vehicles")) is not None:
            section.check(*(vehicles.sizes[k] for k in SECTION_SIZES[info.field_name]))
        return section

    @field_validator("noise")
    @classmethod
    def noise_fits(cls, noise: NoiseSection, info: ValidationInfo) -> NoiseSection:
        """W_x n x n, W_w r x r, W_z l x l, V_y and V_ybar p x p, positive semidefinite
        (checked once [vehicles] and [reference] are valid)."""
        vehicles, ref = info.data.get("vehicles"), info.data.get("reference")
        if vehicles is not None and ref is not None:
            sz = vehicles.sizes
            noise.check(sz["n"], sz["r"], ref.l, sz["p"])
        return noise

    def system_mapping(self) -> dict[str, Any]:
        """The entries of :meth:`LinearSystem.from_mapping`, as given in the file."""
        mapping: dict[str, Any] = {}
        for section in (self.vehicles, self.disturbance, self.reference, self.cost):
            mapping.update(section.model_dump(exclude_unset=True))
        noise = self.noise.model_dump(exclude_unset=True)
        if "convention" in noise:
            mapping["noise_convention"] = noise.pop("convention")
        mapping.update(noise)
        return mapping

