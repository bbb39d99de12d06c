"""The acoustic network of a per-vehicle fleet: which links exist, their FMU configurations
and how they are wired.

Each vehicle has one ``AuvNetwork`` FMU (:mod:`plant_model.acoustic.auv_network_slave`): its modem's
inbox, every link that ends at it. One FMU per receiver rather than one per link keeps the
component count at 1 + 4 N and gives every vehicle's links one place for their state (in
flight, held, loss streams); one FMU for the whole fleet would put every vehicle's inbox in
one process and grow with N^2 inputs in the centralized architecture.

Links of an architecture (:func:`fleet_links`):

- distributed: the graph's edges j -> i, carrying [eta_j; eps_j] (eps only with cohesion),
  and leader -> i for the pinned vehicles (none for a planned path);
- centralized: every ordered pair j -> i, carrying [xhat_j; what_j; u_j], and leader -> i
  for every vehicle.

Their timing comes from the scenario's ``[network]`` table
(:func:`plant_model.acoustic.settings.resolve_links`), the message layouts, launch values and
propagation matrices from the loop's message form
(:mod:`orchestrator.analysis.acoustic.message_form`), so the FMUs and the predictions share them.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from plant_model.acoustic.link_models import MODEL_KEY, model_code
from plant_model.acoustic.links import LinkTiming, link_key
from plant_model.acoustic.settings import resolve_links

from .system import Connection

if TYPE_CHECKING:
    from ..scenario import Scenario

__all__ = ["fleet_links", "network_configs", "network_connections", "receiver_slots"]


def fleet_links(sc: Scenario, architecture: str) -> dict[tuple[Any, int], LinkTiming]:
    """Every link that carries a message in this architecture, with its timing.

    Parameters
    ----------
    sc : Scenario
        A per-vehicle fleet scenario with a ``network`` table.
    architecture : str
        ``centralized`` or ``distributed``.

    Returns
    -------
    dict[tuple[Any, int], LinkTiming]
        (sender, receiver) -> timing; the sender a vehicle number or "leader".
    """
    N = sc.fleet.N
    if architecture == "centralized":
        edges = [(j, i, 1.0) for i in range(1, N + 1) for j in range(1, N + 1) if j != i]
        pins = [(i, 1.0) for i in range(1, N + 1)]
    else:
        edges = list(sc.fleet.edges)
        pins = [] if sc.distributed.leader == "planned" else list(sc.fleet.pinning)
    timing = {} if sc.network is None else sc.network.timing      # None: perfect links
    return resolve_links(N, edges, pins, timing, sc.h)


def receiver_slots(sc: Scenario, architecture: str, slots: Any) -> list[list[int | None]]:
    """Per vehicle, the sender of each neighbour slot (None: unused).

    distributed: the controller's slots (:func:`orchestrator.cosim.per_vehicle.fleet_slots`);
    centralized: the other vehicles in order, N - 1 slots.
    """
    N = sc.fleet.N
    if architecture == "centralized":
        return [[j for j in range(1, N + 1) if j != i] for i in range(1, N + 1)]
    return [[int(slots.neighbours[i, k]) if slots.weights[i, k] > 0.0 else None
             for k in range(slots.S)] for i in range(N)]


def _settings(sender: Any, timing: LinkTiming | None, key: int, M: np.ndarray,
              rx0: np.ndarray, up: Any = None) -> dict[str, Any]:
    t = timing or LinkTiming(latency=0.0, period=1.0, loss=0.0)
    out = {"sender": sender, "latency": t.latency, "period": t.period, "loss": t.loss,
           "offset": t.offset, "key": int(key), "M": np.asarray(M, float).tolist(),
           "rx0": np.asarray(rx0, float).tolist()}
    if t.bursts is not None:            # the row's own parameters (link_models)
        out[MODEL_KEY] = model_code(t.bursts)
        out.update(t.bursts.parameters())
    if up is not None:
        out["up"] = [int(bool(u)) for u in up]
    return out


def network_configs(senders: Mapping[Any, Any], links: Mapping[tuple[Any, int], LinkTiming],
                    slot_senders: list[list[Any]], receiver: str,
                    launch: Mapping[tuple[Any, int], np.ndarray], leader_size: int,
                    modem: Mapping[str, Any] | None = None,
                    schedule: Mapping[str, Any] | None = None) -> list[dict[str, Any]]:
    """The ``AuvNetwork`` build configuration of every vehicle (all of one interface).

    Parameters
    ----------
    senders : Mapping[Any, Sender]
        The message form's senders (fields, propagation matrix).
    links : Mapping[tuple[Any, int], LinkTiming]
        :func:`fleet_links`.
    slot_senders : list[list[Any]]
        :func:`receiver_slots`.
    receiver : str
        ``hold`` or ``propagate``.
    launch : Mapping[tuple[Any, int], np.ndarray]
        Per link the value exchanged before launch.
    leader_size : int
        Size of the leader's state (the leader link's message).
    modem : Mapping[str, Any] or None, optional
        With a modem range: ``range`` (m), ``state_size``, ``position_index`` (the
        vehicles' position states) and ``leader_H`` (the leader's position H z).
    schedule : Mapping[str, Any] or None, optional
        A switching schedule: ``t`` (switch times, s), ``period`` (s, 0: none) and ``up``
        ({link: 0/1 per graph}); an unused slot is up in every graph.

    Returns
    -------
    list[dict[str, Any]]
        Vehicle i's entries at index i - 1 (without ``h``, ``T``, ``seed``, which
        :func:`orchestrator.cosim.per_vehicle.per_vehicle_configs` adds). An unused slot or
        leader link (no such link) gets neutral settings; nothing is wired to its output.
    """
    vehicle = next(s for k, s in senders.items() if k != "leader")
    fields = [list(f) for f in vehicle.fields]
    w = vehicle.width
    lead = senders.get("leader")
    up = dict(schedule["up"]) if schedule else {}
    every = [1] * len(schedule["t"]) if schedule else None
    extra = dict(modem or {})
    if any(t.bursts is not None for t in links.values()):
        extra["loss_models"] = True
    if schedule:
        extra["schedule"] = {"t": [float(t) for t in schedule["t"]],
                             "period": float(schedule["period"])}
    out = []
    for i, row in enumerate(slot_senders, start=1):
        slots = []
        for j in row:
            key = (j, i)
            if key in links:
                s = senders[j]
                slots.append(_settings(j, links[key], link_key(j, i), s.M(receiver), launch[key],
                                       up.get(key, every)))
            else:
                slots.append(_settings(None, None, 0, np.eye(w), np.zeros(w), every))
        lk = ("leader", i)
        leader = (_settings("leader", links[lk], link_key("leader", i), lead.M(receiver),
                            launch[lk], up.get(lk, every)) if lk in links and lead is not None
                  else _settings(None, None, 0, np.eye(leader_size), np.zeros(leader_size),
                                 every))
        out.append(dict(receiver=i, slots=len(row), fields=fields, leader_size=leader_size,
                        links=slots, leader=leader, **extra))
    return out


def network_connections(i: int, architecture: str, row: list[Any], fields: list[Any],
                        has_leader_link: bool, controller_inputs: Mapping[str, str],
                        modem_range: bool = False) -> list[Connection]:
    """Vehicle i's network wiring: senders -> ``network_i`` -> ``controller_i``.

    Parameters
    ----------
    i : int
        The receiving vehicle.
    architecture : str
        ``centralized`` or ``distributed``.
    row : list[Any]
        The sender of each slot (None: unused).
    fields : list[Any]
        [(field, size), ...] of a neighbour message.
    has_leader_link : bool
        Whether the leader's state reaches this vehicle.
    controller_inputs : Mapping[str, str]
        For the distributed controller, its input name of a slot's field: "nbr[{k}].{f}".
    modem_range : bool, optional
        Whether the FMU decides range from the vehicles' true states (inputs ``x`` and
        ``link[k].tx.x``).

    Returns
    -------
    list[Connection]
        Into the network FMU (every input) and out of it (the used links).
    """
    net, ctrl = f"network_{i}", f"controller_{i}"
    conns: list[Connection] = []
    names = [f for f, _ in fields]
    for k, j in enumerate(row, start=1):
        for f in names:
            src = _source(j if j is not None else i, f)
            conns.append(Connection(*src, net, f"link[{k}].tx.{f}"))
            if j is None or f == "u":
                continue
            dst = (f"vehicle[{j}].{f}" if architecture == "centralized"
                   else controller_inputs["slot"].format(k=k, f=f))
            conns.append(Connection(net, f"link[{k}].rx.{f}", ctrl, dst))
    if modem_range:
        conns.append(Connection(f"vehicle_{i}", "x", net, "x"))
        conns += [Connection(f"vehicle_{j if j is not None else i}", "x", net,
                             f"link[{k}].tx.x") for k, j in enumerate(row, start=1)]
    if has_leader_link:
        conns += [Connection("leader", "z", net, "leader.tx.z"),
                  Connection(net, "leader.rx.z", ctrl, "z")]
    else:
        conns.append(Connection(ctrl, "eta", net, "leader.tx.z"))
    return conns


def _source(j: int, field: str) -> tuple[str, str]:
    """Which component output sends a message field of vehicle j."""
    if field in ("xhat", "what"):
        return f"estimator_{j}", field
    return f"controller_{j}", field
