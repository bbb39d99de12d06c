"""The per-vehicle deployment's setup (:class:`PerVehicleSetup`): build, systems, predictions.

The FMUs of each architecture are built once (one per kind, vehicle 1's values as start
values; in a subfolder per architecture when several run); every run sets each vehicle's
parameters (:mod:`orchestrator.cosim.per_vehicle`).
Traces come back in the stacked layout, so the statistics, formation figures and recording
of the stacked deployment apply unchanged; predictions are the stacked one (centralized)
or the Lyapunov prediction of the distributed loop (:mod:`orchestrator.analysis.per_vehicle`).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from controller_fmu.regulator import tracking_law
from estimator_fmu.registry import NAVIGATION_FILTER, estimator_kind, make_estimator
from plant_model.discretization import discretize
from plant_model.linalg_checks import ModelError

from ..analysis.acoustic.blocks import predict_window_blocks
from ..analysis.acoustic.prediction import prediction_work
from ..analysis.distributed_verdict import predict_cost
from ..analysis.per_vehicle import distributed_initial_state, distributed_loop_of
from ..analysis.prediction import Prediction
from ..analysis.summary import stats_window
from ..cosim.build import build_fmus
from ..cosim.per_vehicle import (
    LINK_STATISTICS,
    build_configs,
    link_traces,
    per_vehicle_configs,
    per_vehicle_system,
    stacked_traces,
)
from ..cosim.per_vehicle_network import network_configs
from ..cosim.system import SystemDescription
from .memory import DesignEstimate, check_design, design_estimate, stacked_states
from .network import (
    NetworkSetup,
    age_summary,
    modem_settings,
    network_predictions,
    network_setup,
    network_summary,
    schedule_settings,
    too_many_states,
)
from .phases import phase
from .setup import Method, Predictions, RunSetup
from .stacked import stacked_phase

if TYPE_CHECKING:
    from ..scenario import Scenario

__all__ = ["PerVehicleSetup", "TRANSIENT_LIMIT"]

#: largest loop state for which the window-average prediction from the start is computed
TRANSIENT_LIMIT = 1500
#: largest networked loop (messages in flight and held as states) whose second moment is
#: propagated as one dense matrix, with its mean-square radius and critical loss; beyond,
#: in blocks (formation-20 distributed has 721 states, centralized 5271)
NETWORK_PREDICTION_LIMIT = 3000
#: the most floating-point work a window prediction may take (about ten minutes here)
NETWORK_PREDICTION_WORK = 1e13


def prediction_path(net: Any, steps: int) -> str | None:
    """How the window prediction of a networked loop is computed: "dense" (up to
    NETWORK_PREDICTION_LIMIT states), "blocks", or None when the estimated work
    (:func:`orchestrator.analysis.acoustic.prediction.prediction_work`) exceeds
    NETWORK_PREDICTION_WORK (long latencies at a message every step, all-to-all links)."""
    if net.n <= NETWORK_PREDICTION_LIMIT and prediction_work(net, steps) <= NETWORK_PREDICTION_WORK:
        return "dense"
    if prediction_work(net, steps, blocks=True) <= NETWORK_PREDICTION_WORK:
        return "blocks"
    return None


def _prediction(p: Any) -> Prediction:
    return Prediction(rms_e=p.rms_e, rms_u=p.rms_u, cost_rate=p.cost_rate,
                      spectral_radius=p.spectral_radius, settling_time=p.settling_time)


class PerVehicleSetup(RunSetup):
    """The per-vehicle FMUs of a fleet scenario, their systems and their predictions."""

    deployment = "per-vehicle"

    def __init__(self, sc: Scenario, fmu_dir: Path | str, methods: Any = (), *,
                 coupling: str = "gauss-seidel", predict: str = "stationary"):
        super().__init__(sc, fmu_dir, methods, coupling=coupling, predict=predict)
        self._fmus: dict[str, dict[str, Path]] = {}
        self._network: dict[tuple[str, str, str], NetworkSetup] = {}
        self._central = [m.estimator for m in self.methods if m.architecture == "centralized"]
        if self._central:
            self._check_centralized()       # before anything is built: refused in one line

    def _check_centralized(self) -> DesignEstimate:
        return check_design(self.sc, self._central, self.predict, "centralized")

    def phase(self, method: Method) -> str:
        """The stacked design of a centralized method, else the predictions."""
        if method.architecture != "centralized":
            return super().phase(method)
        return stacked_phase(self.sc, design_estimate(
            stacked_states(self.sc), estimator_kind(method.estimator).solves_riccati,
            self.predict != "none"))

    def _configs(self, method: Method, seed: int) -> list[dict[str, dict[str, Any]]]:
        with phase("design"):
            return self._configs_of(method, seed)

    def _configs_of(self, method: Method, seed: int) -> list[dict[str, dict[str, Any]]]:
        """Every vehicle's FMU configurations (their designs solved here)."""
        sc = self.sc
        gain = None
        if method.architecture == "centralized":
            with self.interruptible(stacked_phase(sc, self._check_centralized())):
                gain = tracking_law(sc.system, method.tracking).Ks
        net = None
        if sc.network is not None:
            setup = self.network(method)
            net = network_configs(setup.form.senders, setup.links, setup.slot_senders,
                                  setup.net.receiver, setup.launch, setup.leader_size,
                                  modem_settings(sc), schedule_settings(setup))
        return per_vehicle_configs(sc, method.architecture, estimator=method.estimator, seed=seed,
                                   tracking=method.tracking, settings=sc.distributed,
                                   gain=gain, network=net)

    def network(self, method: Method) -> NetworkSetup:
        """The loop over the scenario's acoustic links for one method (built once per
        architecture, estimator and tracking law).

        Parameters
        ----------
        method : Method

        Returns
        -------
        NetworkSetup
            Its message form, networked loop, links and launch values.
        """
        key = (method.architecture, method.estimator, method.tracking)
        if key not in self._network:
            self._network[key] = network_setup(self.sc, method)
        return self._network[key]

    def python_fmus(self, method: Method) -> dict[str, Path]:
        """The FMUs of the method's architecture (built on first use, in
        ``fmu_dir/<architecture>`` when the methods use several architectures: their
        network FMUs differ).

        Returns
        -------
        dict[str, Path]
            FMU kind -> .fmu path.
        """
        arch = method.architecture
        if arch not in self._fmus:
            sc = self.sc
            several = len({m.architecture for m in self.methods}) > 1
            cfgs = self._configs(replace(method, estimator=sc.estimator,
                                         tracking=sc.tracking), sc.seed)
            self._fmus[arch] = build_fmus(None, self.fmu_dir / arch if several
                                          else self.fmu_dir, kinds=build_configs(cfgs))
        return self._fmus[arch]

    def python_system(self, method: Method, seed: int) -> SystemDescription:
        """The per-vehicle system of one method and seed (every vehicle's parameters):
        1 + 3 N components (and N network components over acoustic links)."""
        return per_vehicle_system(
            self.sc, self._configs(method,
                                   seed), method.architecture)

    def stacked(self, system: SystemDescription, traces: dict[str, Any],
                info: dict[str, Any]) -> dict[str, Any]:
        """The traces in the stacked layout, and per link its statistics (``link_age``,
        ...; ``info["links"]`` names the links)."""
        out = stacked_traces(self.sc, system, traces)
        links = link_traces(system, traces)
        if links:                   # per link (in info["links"] order) its network statistics
            order = sorted(links, key=lambda k: (k[1], str(k[0])))
            info["links"] = [f"{j} -> {i}" for j, i in order]
            for s in LINK_STATISTICS:
                out[f"link_{s}"] = np.column_stack([links[k][s] for k in order])
        return out

    def __getstate__(self) -> dict[str, Any]:
        state = super().__getstate__()
        state["_network"] = {}                 # a worker gets its systems made
        return state

    def design(self) -> Any:
        """The stacked design of the first centralized method (None: all distributed)."""
        central = [m for m in self.methods if m.architecture == "centralized"]
        return (tracking_law(self.sc.system, central[0].tracking).design if central
                else None)

    def _predict(self, method: Method, k0: int | None = None) -> Predictions:
        """(stationary, over the window with the mean motion, window average from the
        known start, first sample of the window) of one method; the window from ``k0``
        (a compare's common window) or, None, the method's own.

        Raises
        ------
        ModelError
            If the estimator or the design does not exist or the loop is unstable (named).
        """
        sc = self.sc
        if sc.sensors is not None and estimator_kind(method.estimator).navigation == "filter":
            return Predictions.of(self._multirate(method, k0))
        if sc.network is not None:
            setup = self.network(method)
            path = prediction_path(setup.net, sc.steps)
            if path == "dense":
                return Predictions.of(network_predictions(sc, setup, self.log, k0))
            # many links: the second moment in blocks (held values apart), or none when
            # even that is too long; the perfect links' window and margin
            pred0, _, _, k0 = self._perfect(method, k0)
            if path == "blocks" and self.log is not None:
                self.log(f"predicting the expected cost over the window with the second "
                         f"moment in blocks ({setup.net.n} states, {len(setup.net.R)} links; "
                         f"the message cycle is {setup.net.period} steps) ...")
            if setup.net.bursty:        # the blocks keep no tilt per bursty link
                path = None
            cost = (predict_window_blocks(setup.net, setup.Z0, k0, sc.steps,
                                          float("nan")).cost_rate if path == "blocks" else None)
            pred = Prediction(rms_e=None, rms_u=None, cost_rate=cost,
                              spectral_radius=pred0.spectral_radius,
                              settling_time=pred0.settling_time,
                              reason=too_many_states(setup.net.n, path, sc.steps))
            return Predictions(pred0, pred, pred if cost is not None else None, k0)
        return Predictions.of(self._perfect(method, k0))

    def _multirate(self, method: Method, k0: int | None = None
                   ) -> tuple[Prediction, Prediction, Prediction | None, int]:
        """:meth:`predictions` with the multi-rate filter of [sensors]: the periodic loop's
        (distributed, no dropouts; orchestrator.analysis.multirate_prediction), else the
        steady filter's window and margin and no cost, saying why."""
        from ..analysis.multirate_prediction import predict_multirate_cost
        sc = self.sc
        sensors = sc.sensors
        reason = ("no prediction for the multi-rate Kalman filter of [sensors] with the "
                  "centralized architecture")
        if method.architecture == "distributed":
            loop = distributed_loop_of(sc, NAVIGATION_FILTER, method.tracking, sc.distributed)
            try:
                stat = predict_multirate_cost(sc, loop, sensors)
                if k0 is None:
                    k0 = stats_window(sc.T, sc.h, stat.settling_time)
                win = predict_multirate_cost(sc, loop, sensors, (k0, sc.steps),
                                             distributed_initial_state(sc, loop))
                return _prediction(stat), _prediction(win), None, k0
            except ModelError as exc:
                reason = f"no prediction for the multi-rate Kalman filter: {exc}"
        # the steady filter's window and margin
        pred0, _, _, k0 = self._perfect(replace(method, estimator=NAVIGATION_FILTER), k0)
        pred = Prediction(rms_e=None, rms_u=None, cost_rate=None,
                          spectral_radius=pred0.spectral_radius,
                          settling_time=pred0.settling_time,
                          reason=reason + "; the figures are the simulation's")
        return pred0, pred, None, k0

    def _perfect(self, method: Method, k0: int | None = None
                 ) -> tuple[Prediction, Prediction, Prediction | None, int]:
        """:meth:`predictions` with perfect links (the window from ``k0``, or the own)."""
        sc, estimator, tracking = self.sc, method.estimator, method.tracking
        if method.architecture == "centralized":            # the stacked loop's predictions
            self._check_centralized()
            kind = estimator_kind(estimator)
            cost = design_estimate(stacked_states(sc), kind.solves_riccati, True)
            self.announce(f"solving {stacked_phase(sc, cost)} and predicting the "
                          f"centralized loop: {cost.text()} ...", cost.seconds)
            model = discretize(sc.system, sc.h)
            return kind.predict(sc, model, make_estimator(sc.system, model, estimator,
                                                          sc.estimator_options),
                                tracking_law(sc.system, tracking).Ks, k0)
        loop = distributed_loop_of(sc, estimator, tracking, sc.distributed)
        pred0 = predict_cost(loop)
        if k0 is None:
            k0 = stats_window(sc.T, sc.h, pred0.settling_time)
        X0 = distributed_initial_state(sc, loop)
        win = (k0, sc.steps)
        # the window average from a known start needs powers of the dense loop matrix:
        # left out above TRANSIENT_LIMIT states (formation-100: 3417), where the window
        # starts after five time constants of the slowest mode anyway
        transient = (_prediction(predict_cost(loop, win, X0, transient=True))
                     if loop.Phi.shape[0] <= TRANSIENT_LIMIT else None)
        return _prediction(pred0), _prediction(predict_cost(loop, win, X0)), transient, k0

    def method_entries(self, method: Method,
                       runs: list[Mapping[str, tuple[float, int, float]]]) -> dict[str, Any]:
        """The summary's ``network`` and ``age_of_information`` of a method over links.

        Parameters
        ----------
        method : Method
        runs : list of mappings
            Per seed, per link its age of information over the statistics window (sum,
            count, max; :meth:`orchestrator.running.statistics.RunStatistics.link_ages`).

        Returns
        -------
        dict[str, Any]
            ``network`` (latency, period, loss, receiver, critical loss, ...) and
            ``age_of_information`` ({receiver: {sender: mean, max, predicted_mean}}).
        """
        if not runs:
            return {}
        setup = self.network(method)
        return {"network": network_summary(self.sc, setup,
                                           critical=prediction_path(setup.net, self.sc.steps)
                                           == "dense", search=self.predict == "full",
                                           predict=self.predict, log=self.log),
                "age_of_information": age_summary(runs, setup)}
