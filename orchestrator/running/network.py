"""A per-vehicle fleet over acoustic links: the loop, its predictions and its reference.

:func:`network_setup` cuts the method's loop at its messages
(:mod:`orchestrator.analysis.acoustic.message_form`) and puts the scenario's links between them
(:class:`~orchestrator.analysis.acoustic.loop.NetworkedLoop`); the network FMUs are configured
from the same objects (:func:`orchestrator.cosim.per_vehicle_network.network_configs`), so
the co-simulation, the monolithic reference (:func:`network_reference`) and the
predictions (:func:`network_predictions`) share one description. Age of information:
:func:`age_summary`.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from controller_fmu.regulator import tracking_law
from controller_fmu.vehicle_law import centralized_rows
from plant_model.acoustic.schedule import connectivity, resolve_schedule

from ..analysis.acoustic.bursty import bursty_radius, bursty_window, critical_burst
from ..analysis.acoustic.loop import NetworkedLoop
from ..analysis.acoustic.message_form import (
    MessageForm,
    centralized_message_form,
    distributed_message_form,
    without_leader_links,
)
from ..analysis.acoustic.prediction import predict_window
from ..analysis.acoustic.stability import critical_loss, ms_spectral_radius
from ..analysis.per_vehicle import distributed_initial_state, distributed_loop_of, distributed_noise
from ..analysis.prediction import Prediction
from ..analysis.summary import stats_window
from ..cosim.per_vehicle import fleet_slots
from ..cosim.per_vehicle_network import fleet_links, receiver_slots
from .setup import NO_PREDICTION, Method

if TYPE_CHECKING:
    from ..scenario import Scenario

Log = Callable[[str], None]

__all__ = ["SLOW_STATES", "NetworkSetup", "age_summary", "modem_settings", "network_predictions",
           "network_reference", "network_setup", "network_summary", "schedule_settings",
           "too_many_states"]


@dataclass(frozen=True, eq=False)
class NetworkSetup:
    """One method's loop over the scenario's links."""

    form: MessageForm
    net: NetworkedLoop
    links: dict[tuple[Any, int], Any]
    slot_senders: list[list[Any]]
    X0: np.ndarray                       #: the form's initial state
    leader_size: int

    @property
    def launch(self) -> dict[tuple[Any, int], np.ndarray]:
        """Per link the value exchanged before launch."""
        return self.net.launch_messages(self.X0)

    @property
    def Z0(self) -> np.ndarray:
        """The networked loop's initial state."""
        return self.net.initial_state(self.X0)


def network_setup(sc: Scenario, method: Method) -> NetworkSetup:
    """The loop of one method over the scenario's ``[network]``.

    Parameters
    ----------
    sc : Scenario
        A per-vehicle fleet scenario with a network.
    method : Method
        Its architecture, estimator and tracking law.

    Returns
    -------
    NetworkSetup
        The pieces.
    """
    architecture, tracking = method.architecture, method.tracking
    loop = distributed_loop_of(sc, method.estimator, tracking, sc.distributed)
    X0 = distributed_initial_state(sc, loop)
    if architecture == "centralized":
        N = len(loop.sampled)
        p = loop.laws[0].Kx.shape[1]
        r, m = loop.sampled[0].Ad.shape[0] - p, loop.sampled[0].Bd.shape[1]
        rows = centralized_rows(tracking_law(sc.system, tracking).Ks, N, p, r, m,
                                loop.observer.Phi.shape[0])
        form = centralized_message_form(loop, rows)
    else:
        H = np.asarray(sc.fleet["leader"]["H"], float)
        offsets = [v.get("offset", np.zeros(H.shape[0])) for v in sc.fleet["vehicles"]]
        form = distributed_message_form(loop, H, offsets)
        if sc.distributed.leader == "planned":
            form = without_leader_links(form)
    links = fleet_links(sc, architecture)
    receiver = dict(sc.network).get("receiver", "propagate")
    schedule = resolve_schedule(sc.network, links, sc.h, len(sc.fleet["vehicles"]))
    net = NetworkedLoop(form, links, receiver, schedule)
    modem = modem_settings(sc)
    if modem is not None:
        net.set_modem_range(modem["range"], _positions(sc, loop, form, net, modem))
    return NetworkSetup(form=form, net=net, links=links,
                        slot_senders=receiver_slots(sc, architecture, fleet_slots(sc.fleet)),
                        X0=form.state_of(X0), leader_size=loop.observer.Phi.shape[0])


def modem_settings(sc: Scenario) -> dict[str, Any] | None:
    """The network FMUs' modem range settings (None without ``[network] range``): the range
    (m), the vehicles' state size and position states, the leader's position map H."""
    table = dict(sc.network or {})
    if "range" not in table:
        return None
    mdl = sc.fleet_model.models[0]
    return {"range": float(table["range"]), "state_size": int(mdl.p),
            "position_index": [int(i) for i in mdl.position_states],
            "leader_H": np.asarray(sc.fleet["leader"]["H"], float).tolist()}


def schedule_settings(setup: NetworkSetup) -> dict[str, Any] | None:
    """The network FMUs' switching schedule (None without): switch times and period (s),
    per link whether it is up in each graph."""
    sch, h = setup.net.schedule, setup.net.h
    if sch is None:
        return None
    return {"t": [k * h for k in sch.switch], "period": sch.period * h,
            "up": {k: list(v) for k, v in sch.up.items()}}


def _positions(sc: Scenario, loop: Any, form: MessageForm, net: NetworkedLoop,
               modem: dict[str, Any]) -> dict[Any, np.ndarray]:
    """Per vehicle and the leader the 3 x n matrix of its true NED position in Z."""
    keep = (np.flatnonzero(form.keep) if form.keep is not None
            else np.arange(loop.Phi.shape[0]))
    where = {int(x): c for c, x in enumerate(keep)}
    out = {}
    for i, sl in enumerate(loop.index["s"], start=1):
        P = np.zeros((3, net.n))
        for r, j in enumerate(modem["position_index"]):
            P[r, where[sl.start + j]] = 1.0
        out[i] = P
    P = np.zeros((3, net.n))
    v = loop.index["v"][0]
    P[:, [where[x] for x in range(v.start, v.stop)]] = np.asarray(modem["leader_H"], float)
    out["leader"] = P
    return out


#: a networked loop of more states than this says what it computes before its second
#: moment (the sparse cycle of formation-4, 361 states, takes well under a second)
SLOW_STATES = 600


def network_predictions(sc: Scenario, setup: NetworkSetup, log: Log | None = None,
                        k0: int | None = None
                        ) -> tuple[Prediction, Prediction, Prediction | None, int]:
    """(verdict, window prediction, same, k0) in the shape the workflow takes.

    The window prediction is exact: E[J] over k0 <= k < K from the known start. k0 (unless
    given: a compare's common window) leaves five time constants of the slowest mean-square
    mode, tau = -2 cycle / ln(rho), rho the second-moment radius per cycle
    (E|e|^2 ~ rho^(t / cycle), |e| ~ rho^(t / (2 cycle))).
    """
    net = setup.net
    if log is not None and net.n > SLOW_STATES:
        log(f"predicting the second moment over the links' message cycle (P = {net.period} "
            f"steps, {net.n} states): its radius and the expected cost over the window ...")
    rho = bursty_radius(net) if net.bursty else ms_spectral_radius(net)
    cycle = net.period * net.h
    tau = -2.0 * cycle / math.log(rho) if 0.0 < rho < 1.0 else math.inf
    settling = 5.0 * tau
    if k0 is None:
        k0 = stats_window(sc.T, sc.h, settling if math.isfinite(settling) else sc.T)
    verdict = Prediction(rms_e=None, rms_u=None, cost_rate=None, spectral_radius=rho,
                         settling_time=settling,
                         reason=None if rho < 1.0 else
                         f"not mean-square stable over the links: second-moment radius "
                         f"{rho:.6g} per {cycle:g} s message cycle")
    if rho >= 1.0:
        return verdict, verdict, None, k0
    if net.modem is not None:
        none = Prediction(rms_e=None, rms_u=None, cost_rate=None, spectral_radius=rho,
                          settling_time=settling,
                          reason="a modem range makes the links depend on the vehicles' "
                                 "positions: simulation only, no prediction")
        return verdict, none, None, k0
    cost = (bursty_window(net, setup.Z0, k0, sc.steps) if net.bursty else
            predict_window(net, setup.Z0, k0, sc.steps, rho).cost_rate)
    pred = Prediction(rms_e=None, rms_u=None, cost_rate=cost, spectral_radius=rho,
                      settling_time=settling,
                      reason="over acoustic links: the expected cost over the window from the "
                             "known start (second moment over the message cycle); no RMS "
                             "predictions")
    return verdict, pred, pred, k0


def too_many_states(n: int, path: str | None, steps: int) -> str:
    """What a large networked loop of n states gets instead of the dense second moment."""
    what = ("the expected cost over the window is computed with the second moment in blocks"
            if path == "blocks" else
            f"even in blocks the second moment over {steps} steps is estimated beyond 1e13 "
            "floating-point operations: no predicted cost")
    return (f"over acoustic links the loop has {n} states (messages in flight and held, per "
            f"link): {what}; the mean-square radius and the critical loss are not computed "
            "(the radius given is the perfect links')")


def network_summary(sc: Scenario, setup: NetworkSetup, *, critical: bool = True,
                    search: bool = True, predict: str = "full", log: Log | None = None
                    ) -> dict[str, Any]:
    """The summary's ``network`` entry of a method: the fleet-wide latency, period and loss,
    the receiver, the links, the message cycle and the critical loss probability (with
    ``predict`` "none", null and a note; ``log`` told before the search starts)."""
    table = dict(sc.network)
    out: dict[str, Any] = {
        "latency": float(table.get("latency", 0.0)),
        "period": float(table.get("period", sc.h)),
        "loss": float(table.get("loss", 0.0)),
        "loss_model": table.get("loss_model", "independent"),
        "tdma": bool(table.get("tdma", False)),
        "receiver": setup.net.receiver,
        "links": len(setup.links),
        "cycle_s": setup.net.period * setup.net.h,
    }
    if "range" in table:
        out["range"] = float(table["range"])
    if setup.net.bursty:
        out["bursty_links"] = {f"{k[0]} -> {k[1]}": {**m.parameters(), "pi_bad": m.pi_bad,
                                                      "mean_loss": m.mean_loss,
                                                      "mean_burst": m.mean_burst}
                               for k, m in setup.net.bursty.items()}
        out["loss"] = float(np.mean([setup.net.loss[k] for k in setup.links]))
    if setup.net.schedule is not None:
        out["schedule"] = schedule_summary(setup, radius=critical and predict != "none")
    if predict == "none":
        out["critical_loss"], out["critical_loss_note"] = None, NO_PREDICTION
    elif critical and not search:
        out["critical_loss"], out["critical_loss_note"] = None, (
            "not computed: the search evaluates the second-moment radius on a grid of losses "
            "and bisects (seconds for formation-4); --predict full computes it")
    elif critical and setup.net.modem is None and setup.net.bursty:
        out["critical_loss"], out["critical_loss_note"] = None, (
            "bursty links: the critical figure is the mean burst length (critical_burst)")
        out["critical_burst"], out["critical_burst_note"] = critical_burst(setup.net, log=log)
    elif critical and setup.net.modem is None:
        out["critical_loss"], out["critical_loss_note"] = critical_loss(setup.net, log=log)
    elif critical:
        out["critical_loss"], out["critical_loss_note"] = None, (
            "not computed with a modem range (the links depend on the vehicles' positions)")
    else:
        out["critical_loss"], out["critical_loss_note"] = None, (
            f"not computed: {setup.net.n} states (the dense second moment is too large)")
    return out


def schedule_summary(setup: NetworkSetup, radius: bool = True) -> dict[str, Any]:
    """The summary's ``schedule`` entry: the switch times and period (s), whether each graph
    and their union let the leader's information reach every vehicle (necessary, not
    sufficient), and the verdict, the mean-square spectral radius over one schedule period
    (rho per cycle ** (period / cycle); None when the loop is too large for it)."""
    net = setup.net
    sch = net.schedule
    out: dict[str, Any] = {"switch_times": [k * net.h for k in sch.switch],
                           "period": sch.period * net.h if sch.period else None,
                           **connectivity(sch, setup.links)}
    rho = ms_spectral_radius(net) if radius else None
    span = sch.period or net.period                 # without a period: the message cycle
    out["spectral_radius_per_period"] = (None if rho is None else
                                         float(rho ** (span / net.period)))
    out["mean_square_stable"] = None if rho is None else bool(rho < 1.0)
    return out


def network_reference(sc: Scenario, setup: NetworkSetup, seed: int, steps: int
                      ) -> dict[str, np.ndarray]:
    """The networked loop simulated as one recursion with the FMUs' noise and loss draws:
    traces x, u, e in the stacked layout.

    Parameters
    ----------
    sc : Scenario
        The fleet scenario.
    setup : NetworkSetup
        The method's loop.
    seed : int
        Noise and loss seed.
    steps : int
        Samples.

    Returns
    -------
    dict[str, np.ndarray]
        ``Z`` (the augmented state), ``u``, ``e``.
    """
    zeta = distributed_noise(sc, seed, steps)
    Z = setup.net.simulate(setup.Z0, zeta, seed)
    return {"Z": Z, "u": Z @ setup.net.Gx.T + zeta @ setup.form.Geta.T,
            "e": Z @ setup.net.Ce.T}


def age_summary(runs: list[Mapping[str, tuple[float, int, float]]], setup: NetworkSetup
                ) -> dict[str, dict[str, dict[str, float]]]:
    """Per receiving vehicle and sender the age of the newest information it holds over the
    window, over every seed: mean and max (s), and the mean predicted for independent losses,
    D h + (P - 1) h / 2 + P h p / (1 - p) (D the delay and P the period in steps; None
    when a schedule switches links on and off).

    Parameters
    ----------
    runs : list of mappings
        Per seed, per link ("j -> i") its age over the window: (sum, count, max), s
        (:meth:`orchestrator.running.statistics.RunStatistics.link_ages`).
    setup : NetworkSetup
        The links' timing.

    Returns
    -------
    dict
        {receiver: {sender: {"mean", "max", "predicted_mean"}}}.
    """
    net = setup.net
    by_link: dict[str, list[float]] = {}
    for ages in runs:
        for name, (total, count, largest) in ages.items():
            acc = by_link.setdefault(name, [0.0, 0, -math.inf])
            acc[0] += total
            acc[1] += count
            acc[2] = max(acc[2], largest)
    out: dict[str, dict[str, dict[str, float]]] = {}
    for name, (total, count, largest) in by_link.items():
        j, i = (x.strip() for x in name.split("->"))
        key = ("leader" if j == "leader" else int(j), int(i))
        g = net.groups[net.link_group[key]]
        p = net.loss[key]
        predicted = (None if net.schedule is not None or key in net.bursty else  # switched,
                     # or bursty (losses correlated: the formula is independent losses')
                     (g.D + (g.P - 1) / 2 + g.P * p / (1 - p)) * net.h)
        out.setdefault(i, {})[j] = {"mean": float(total / count), "max": float(largest),
                                    "predicted_mean": predicted}
    return out
