"""The estimator registry: one row per estimator, holding everything its kind needs.

Adding an estimator is one module (its mathematics: a stacked builder and a per-vehicle
builder) plus one row here. Everything else asks the row (:func:`estimator_kind`) rather
than testing the name: how the gains are designed (``design``), whether it reads the truth
(``uses_truth``), whether the distributed law, acoustic links or navigation sensors accept
it, its FMU parameters, its native (C) form and its predictions. No module but this one
and the estimator's own tests an estimator's name (tests/test_estimator_names.py).

Rows (docs/theory.md section 5):

- ``kalman``: the steady-state Kalman filter (estimator_fmu.estimators);
- ``kalman-tv``: the time-varying Kalman filter from P0 (estimator_fmu.kalman_tv);
- ``classical``: the paper's comparison law on raw measurements (estimator_fmu.estimators);
- ``ideal``: the truth (estimator_fmu.estimators).
"""
from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from fmu_common.interface import ArraySpec
from plant_model.discretization import DiscreteModel
from plant_model.linalg_checks import ModelError
from plant_model.system import LinearSystem

from . import estimators as _est
from . import kalman_tv as _tv


class PredictedScenario(Protocol):
    """What an estimator's predictions read of a scenario
    (:class:`orchestrator.scenario.Scenario` is one): the system, the step, the horizon."""

    system: LinearSystem
    h: float
    T: float

    @property
    def steps(self) -> int: ...

__all__ = ["COMPARED_BY_DEFAULT", "DEFAULT_ESTIMATOR", "NAVIGATION_FILTER", "STEADY_FILTER",
           "TRUTH", "TRUTH_MODES", "ESTIMATORS", "ESTIMATOR_MODES", "EstimatorKind",
           "estimator_kind", "make_estimator", "make_vehicle_estimator", "options_of",
           "parameter_specs"]

#: FMU parameter names an estimator row may add (the FMUs' configuration key is the same)
OPTION_KEYS = ("P0",)


def _no_parameters(config: dict[str, Any]) -> list[ArraySpec]:
    return []


def _p0_parameter(config: dict[str, Any]) -> list[ArraySpec]:
    """P0 when the configuration carries one ([estimator] P0: on [x; w; z], or one
    vehicle's [x; w] in a fleet); without it the filter starts from P0 = 0."""
    if config.get("P0") is None:
        return []
    P0 = np.asarray(config["P0"], dtype=float)
    return [ArraySpec("P0", P0.shape, "parameter", "the time-varying Kalman filter's start "
                      "covariance of the prediction error (prior at t = 0; a fleet FMU: one "
                      "vehicle's, every vehicle starts from it)", start=P0)]


def parameter_specs(config: dict[str, Any]) -> list[ArraySpec]:
    """The estimator FMUs' parameters every row adds (each name once)."""
    out: dict[str, ArraySpec] = {}
    for kind in ESTIMATORS.values():
        for spec in kind.parameters(config):
            out.setdefault(spec.name, spec)
    return list(out.values())


def options_of(par: dict[str, Any], config: dict[str, Any]) -> dict[str, Any]:
    """The builders' options from an estimator FMU's parameter values: ``P0`` (None: 0)
    and ``fleet`` (a fleet FMU's P0 is one vehicle's)."""
    return {"P0": par.get("P0"), "fleet": config.get("fleet") is not None}


@dataclass(frozen=True)
class EstimatorKind:
    """One estimator: what each part of the project needs of it."""

    name: str
    summary: str                        #: one line for --help and the docs
    #: how its gains are designed: "steady-riccati" (the discrete algebraic Riccati
    #: equation), "riccati-recursion" (the Riccati difference equation from P0, run with
    #: the filter), "pseudo-inverse" (C^+, H^+), "none" (the truth)
    design: str
    uses_truth: bool                    #: reads the plant's true x, w, z
    #: builds the stacked estimator: (system, model, options) -> estimator
    stacked: Callable[..., Any]
    #: builds one vehicle's estimator: (system, model, where, options) -> estimator
    vehicle: Callable[..., Any]
    #: the distributed law (orchestrator.analysis.distributed) accepts it: "steady" (a
    #: vehicle's own steady gain), "truth", or None (refused)
    distributed: str | None
    #: over acoustic links (orchestrator.analysis.acoustic): its message-form loop exists
    over_links: bool
    #: with [sensors] (navigation at their own rates): "filter" (the multi-rate Kalman
    #: filter), "truth", or None (refused: it needs a position fix every step)
    navigation: str | None
    #: the estimator FMUs' extra parameters: config -> specs
    parameters: Callable[[dict[str, Any]], list[ArraySpec]]
    #: its native (C) FMU: "linear" (fmu_common.native_form of a LinearEstimator) or
    #: "covariance" (the C Kalman recursion, orchestrator.cosim.native_multirate)
    native: str
    #: "module:function" of its predictions (stationary, window, from start, k0), called
    #: as f(sc, model, estimator, Ks, k0) (estimator_fmu carries no orchestrator code)
    predictions: str
    color: tuple[int, int, int]         #: its traces' colour in the recording (RGB)
    #: (line width, alpha) of its traces in the recording, when not the default's
    wide: tuple[float, int] | None = None
    #: ``compare --what estimators`` runs it without ``--methods``
    compared_by_default: bool = True

    @property
    def solves_riccati(self) -> bool:
        """Whether its design solves a Riccati equation (the design cost's filter phase)."""
        return self.design in ("steady-riccati", "riccati-recursion")

    @property
    def time_varying(self) -> bool:
        """Whether its gain changes from step to step (no time-invariant loop)."""
        return self.design == "riccati-recursion"

    @property
    def filters(self) -> bool:
        """Whether it is a Kalman filter whose internal state q is a copy of the filtered
        state (current-estimator form, a steady or time-varying gain)."""
        return self.solves_riccati

    def make(self, system: LinearSystem, model: DiscreteModel,
             options: dict[str, Any] | None = None) -> Any:
        """The stacked estimator of ``system`` sampled as ``model``."""
        return self.stacked(system, model, options or {})

    def make_vehicle(self, system: LinearSystem, model: DiscreteModel, where: str = "vehicle",
                     options: dict[str, Any] | None = None) -> Any:
        """One vehicle's estimator (per-vehicle deployment)."""
        return self.vehicle(system, model, where, options or {})

    def predict(self, sc: PredictedScenario, model: DiscreteModel, est: Any, Ks: np.ndarray,
                k0: int | None = None) -> tuple:
        """Its predictions of the stacked loop (:attr:`predictions`)."""
        module, func = self.predictions.split(":")
        return getattr(importlib.import_module(module), func)(sc, model, est, Ks, k0)


_LINEAR_PREDICTIONS = "orchestrator.analysis.prediction:method_predictions"

ESTIMATORS: dict[str, EstimatorKind] = {k.name: k for k in (
    EstimatorKind("kalman", "steady-state Kalman filter (current-estimator form)",
                  "steady-riccati", False, lambda s, m, o: _est.kalman_estimator(s, m),
                  lambda s, m, w, o: _est.kalman_vehicle_estimator(s, m, w),
                  distributed="steady", over_links=True, navigation="filter",
                  parameters=_no_parameters, native="linear",
                  predictions=_LINEAR_PREDICTIONS, color=(31, 119, 180)),
    EstimatorKind(_tv.NAME, "time-varying Kalman filter from the covariance P0 ([estimator] "
                  "P0)", "riccati-recursion", False,
                  lambda s, m, o: _tv.tv_estimator(s, m, o),
                  lambda s, m, w, o: _tv.tv_vehicle_estimator(s, m, w, o),
                  distributed=None, over_links=False, navigation=None,
                  parameters=_p0_parameter, native="covariance",
                  predictions="orchestrator.analysis.tv_prediction:tv_method_predictions",
                  color=(23, 105, 105), compared_by_default=False),
    EstimatorKind("classical", "the paper's classical law on raw measurements",
                  "pseudo-inverse", False, lambda s, m, o: _est.classical_estimator(s, m),
                  lambda s, m, w, o: _est.classical_vehicle_estimator(s, m, w),
                  distributed=None, over_links=True, navigation=None,
                  parameters=_no_parameters, native="linear",
                  predictions=_LINEAR_PREDICTIONS, color=(255, 127, 14)),
    EstimatorKind("ideal", "the true state", "none", True,
                  lambda s, m, o: _est.ideal_estimator(s, m),
                  lambda s, m, w, o: _est.ideal_vehicle_estimator(s, m, w),
                  distributed="truth", over_links=True, navigation="truth",
                  parameters=_no_parameters, native="linear",
                  predictions=_LINEAR_PREDICTIONS, color=(44, 160, 44), wide=(3.0, 150)),
)}

#: the estimator names, in the order of the rows
ESTIMATOR_MODES = tuple(ESTIMATORS)
#: what ``compare --what estimators`` runs without ``--methods``
COMPARED_BY_DEFAULT = tuple(k.name for k in ESTIMATORS.values() if k.compared_by_default)
#: the estimator a scenario runs when it names none
DEFAULT_ESTIMATOR = ESTIMATOR_MODES[0]
#: the estimators that read the truth (the FMUs' ``mode`` values a truth connection is for)
TRUTH_MODES = tuple(k.name for k in ESTIMATORS.values() if k.uses_truth)
#: the estimator that is the truth (a reference point; the distributed analysis' default)
TRUTH = TRUTH_MODES[0]
#: the steady Kalman filter (the limit of the time-varying one; the design searches' filter)
STEADY_FILTER = next(k.name for k in ESTIMATORS.values() if k.design == "steady-riccati")
#: the estimator of the navigation sensors' multi-rate filter
NAVIGATION_FILTER = next(k.name for k in ESTIMATORS.values() if k.navigation == "filter")


def estimator_kind(name: str) -> EstimatorKind:
    """The row of ``name``.

    Raises
    ------
    ModelError
        ``unknown estimator mode 'x'; expected one of kalman, ...``.
    """
    try:
        return ESTIMATORS[name]
    except (KeyError, TypeError):
        raise ModelError(f"unknown estimator mode {name!r}; expected one of "
                         f"{', '.join(ESTIMATOR_MODES)}") from None


def make_estimator(system: LinearSystem, model: DiscreteModel, mode: str,
                   options: dict | None = None) -> Any:
    """Build the estimator of ``mode`` for ``system`` sampled as ``model``.

    Parameters
    ----------
    system : LinearSystem
        The validated model.
    model : DiscreteModel
        ``system`` sampled at the communication step h.
    mode : str
        An estimator of the registry (:mod:`estimator_fmu.registry`).
    options : dict or None, optional
        The row's options (``P0`` of the time-varying filter).

    Returns
    -------
    LinearEstimator or TimeVaryingKalman
        The estimator, reset to its initial internal state.

    Raises
    ------
    ModelError
        If the mode is unknown, a Kalman filter does not exist (:func:`steady_kalman`), or
        ``classical`` meets a C or H without full column rank.
    """
    return estimator_kind(mode).make(system, model, options)


def make_vehicle_estimator(system: LinearSystem, model: DiscreteModel, mode: str,
                           where: str = "vehicle", options: dict | None = None) -> Any:
    """One vehicle's own estimator of s = [x; w] from its own y (per-vehicle deployment).

    ``model`` is the vehicle alone (:func:`plant_model.per_vehicle.sample_vehicle`); the
    measurement vector is mvec = [y; x; w] (the truth read only by ``ideal``):

    - ``kalman``: est = q + L (y - [C, 0] q), q[k+1] = Ad est + Bd u, L the steady gain of
      the pair (Ad, [C, 0]) with Qd and V_y / h (:func:`steady_kalman`); q(0) = [x0; w0];
    - ``classical``: xhat = C^+ y, what = expm(K h)^k w0;
    - ``ideal``: est = [x; w].

    With the consensus protocol as a force the stacked filter on [x; w] of the whole fleet
    is block diagonal, so it equals the N vehicle filters (to the Riccati solver's
    precision).

    Parameters
    ----------
    system : LinearSystem
        The vehicle's view (:func:`plant_model.per_vehicle.vehicle_view`).
    model : DiscreteModel
        The vehicle sampled alone (l = 0).
    mode : str
        An estimator of the registry (:mod:`estimator_fmu.registry`).
    where : str, optional
        Names the vehicle in error messages.
    options : dict or None, optional
        The row's options (``P0`` of the time-varying filter).

    Returns
    -------
    LinearEstimator
        As :func:`make_estimator`.

    Raises
    ------
    ModelError
        If the mode is unknown, the Kalman filter does not exist or C lacks full column
        rank for ``classical``.
    """
    return estimator_kind(mode).make_vehicle(system, model, where, options)
