"""The stacked deployment's setup: the paper's loop of three FMUs (plant, estimator,
controller) for a single system or a stacked fleet."""
from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..cosim.system import SystemDescription
from ..scenario import Scenario
from .setup import Method, Predictions, RunSetup

__all__ = ["StackedSetup"]


class StackedSetup(RunSetup):
    """The paper's loop of three FMUs (plant, estimator, controller) for a single system or
    a stacked fleet."""

    deployment = "stacked"

    def __init__(self, sc: Scenario, fmu_dir: Path | str, methods: Sequence[Method] = (),
                 *, coupling: str = "gauss-seidel", predict: str = "stationary"):
        super().__init__(sc, fmu_dir, methods, coupling=coupling, predict=predict)
        from .fmus import scenario_config
        self.config = scenario_config(sc)
        self._fmus: dict[str, Path] | None = None
        self._model: Any = None

    def python_fmus(self, method: Method) -> dict[str, Path]:
        """The three FMUs (one build serves every method: they set their mode and law)."""
        if self._fmus is None:
            from ..cosim.build import build_fmus
            self._fmus = build_fmus(self.config, self.fmu_dir)
        return self._fmus

    def python_system(self, method: Method, seed: int) -> SystemDescription:
        """:func:`orchestrator.cosim.system.closed_loop_system` of the method and seed."""
        from ..cosim.system import closed_loop_system
        return closed_loop_system(dict(self.config, mode=method.estimator, seed=int(seed),
                                       tracking=method.tracking), name=self.sc.name)

    def model(self) -> Any:
        """The sampled model (computed once)."""
        if self._model is None:
            from plant_model.discretization import discretize
            self._model = discretize(self.sc.system, self.sc.h)
        return self._model

    def _predict(self, method: Method) -> Predictions:
        from controller_fmu.regulator import tracking_law
        from estimator_fmu.estimators import make_estimator

        from ..analysis.prediction import method_predictions
        sc = self.sc
        est = make_estimator(sc.system, self.model(), method.estimator)
        Ks = tracking_law(sc.system, method.tracking).Ks
        parts = Predictions.of(method_predictions(sc, self.model(), est, Ks))
        if self.coupling != "jacobi":
            return parts
        from ..analysis.jacobi import predict_stationary_jacobi
        pj = predict_stationary_jacobi(sc.system, self.model(), est, Ks)
        pred = dataclasses.replace(parts.stationary, rms_e=pj["rms_e"], rms_u=pj["rms_u"],
                                   cost_rate=pj["cost_rate"], reason=pj["reason"])
        return Predictions(pred, pred, None, parts.k0)

    def design(self) -> Any:
        from controller_fmu.regulator import tracking_law
        return tracking_law(self.sc.system, self.methods[0].tracking).design

    def __getstate__(self) -> dict[str, Any]:
        state = super().__getstate__()
        state["_model"] = None
        return state
