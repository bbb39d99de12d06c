"""The stacked deployment's setup: the paper's loop of three FMUs (plant, estimator,
controller) for a single system or a stacked fleet."""
from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from estimator_fmu.registry import estimator_kind

from ..cosim.system import SystemDescription
from ..scenario import Scenario
from .memory import DesignEstimate, check_design, design_estimate, stacked_states
from .setup import Method, Predictions, RunSetup

__all__ = ["StackedSetup", "stacked_phase"]


def stacked_phase(sc: Scenario, est: DesignEstimate) -> str:
    """``the stacked design (80 vehicles, 726 states)``: names the phase in messages."""
    who = f"{sc.fleet.N} vehicles, " if sc.fleet is not None else ""
    return f"the stacked design ({who}{est.states} states)"


class StackedSetup(RunSetup):
    """The paper's loop of three FMUs (plant, estimator, controller) for a single system or
    a stacked fleet.

    Raises
    ------
    ModelError
        From the constructor, when the stacked design is estimated too long or too large
        (:func:`~orchestrator.running.memory.check_design`).
    """

    deployment = "stacked"

    def __init__(self, sc: Scenario, fmu_dir: Path | str, methods: Sequence[Method] = (),
                 *, coupling: str = "gauss-seidel", predict: str = "stationary"):
        super().__init__(sc, fmu_dir, methods, coupling=coupling, predict=predict)
        # before anything is built
        self.estimate = check_design(sc, [m.estimator for m in self.methods], predict)
        from .fmus import scenario_config
        self.config = scenario_config(sc)
        self._fmus: dict[str, Path] | None = None
        self._model: Any = None
        self._law: Any = None

    def python_fmus(self, method: Method) -> dict[str, Path]:
        """The three FMUs (one build serves every method: they set their mode and law)."""
        if self._fmus is None:
            from ..cosim.build import build_fmus
            self._fmus = build_fmus(self.config, self.fmu_dir)
        return self._fmus

    def python_system(self, method: Method, seed: int) -> SystemDescription:
        """:func:`orchestrator.cosim.system.closed_loop_system` of the method and seed."""
        from ..cosim.system import closed_loop_system
        return closed_loop_system(dict(self.config, estimator=method.estimator, seed=int(seed),
                                       tracking=method.tracking), name=self.sc.name)

    def model(self) -> Any:
        """The sampled model (computed once)."""
        if self._model is None:
            from plant_model.discretization import discretize
            self._model = discretize(self.sc.system, self.sc.h)
        return self._model

    def _estimate(self, method: Method, predict: bool) -> DesignEstimate:
        return design_estimate(stacked_states(self.sc),
                               estimator_kind(method.estimator).solves_riccati, predict)

    def phase(self, method: Method) -> str:
        """``the stacked design (80 vehicles, 726 states)``."""
        return stacked_phase(self.sc, self._estimate(method, self.predict != "none"))

    def prepare(self, method: Method) -> None:
        """The sampled model, the tracking law and the estimator the FMUs solve in their
        initialization (then found in the process's design cache), announced when long."""
        from controller_fmu.regulator import tracking_law
        from estimator_fmu.registry import make_estimator
        if self._law is None:
            est = self._estimate(method, False)
            self.announce(f"solving {self.phase(method)}: {est.text()} ...", est.seconds)
        self._law = tracking_law(self.sc.system, method.tracking)
        make_estimator(self.sc.system, self.model(), method.estimator, self.sc.estimator_options)

    def _predict(self, method: Method, k0: int | None = None) -> Predictions:
        from controller_fmu.regulator import tracking_law
        from estimator_fmu.registry import make_estimator

        sc = self.sc
        cost = self._estimate(method, True)
        self.announce(f"solving {self.phase(method)} and predicting {method.name}: "
                      f"{cost.text()} ...", cost.seconds)
        kind = estimator_kind(method.estimator)
        est = make_estimator(sc.system, self.model(), method.estimator, sc.estimator_options)
        self._law = law = tracking_law(sc.system, method.tracking)
        Ks = law.Ks
        parts = Predictions.of(kind.predict(sc, self.model(), est, Ks, k0))
        if self.coupling != "jacobi":
            return parts
        if kind.time_varying:
            pred = dataclasses.replace(parts.stationary, rms_e=None, rms_u=None, cost_rate=None,
                                       reason="no prediction of the Jacobi coupling for the "
                                       "time-varying Kalman filter")
            return Predictions(pred, pred, None, parts.k0)
        from ..analysis.jacobi import predict_stationary_jacobi
        pj = predict_stationary_jacobi(sc.system, self.model(), est, Ks)
        pred = dataclasses.replace(parts.stationary, rms_e=pj["rms_e"], rms_u=pj["rms_u"],
                                   cost_rate=pj["cost_rate"], reason=pj["reason"])
        return Predictions(pred, pred, None, parts.k0)

    def design(self) -> Any:
        """The first method's tracking design (solved here unless a run or a prediction
        solved it already)."""
        from controller_fmu.regulator import tracking_law
        return tracking_law(self.sc.system, self.methods[0].tracking).design

    def __getstate__(self) -> dict[str, Any]:
        state = super().__getstate__()
        state["_model"] = None
        return state
