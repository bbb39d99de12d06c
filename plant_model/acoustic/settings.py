"""A fleet's acoustic network from its ``[network]`` table: the receivers, every link's timing.

:func:`resolve_links` gives every link of a fleet its timing (:class:`~.links.LinkTiming`)
from a ``[network]`` table (fleet-wide defaults, per-link overrides, TDMA);
:func:`check_network` validates the whole table (receiver, timing, modem range and the
switching schedule of :mod:`.schedule`) for a fleet of N vehicles and gives it as a
:class:`NetworkSettings`, the form a scenario carries it in. Pure Python, no FMI.
"""
from __future__ import annotations

import copy
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from ..linalg_checks import ModelError
from .base import MAX_MESSAGE_CYCLE_STEPS, _number, _vehicle
from .link_models import DEFAULT_MODEL, MODEL_KEY, link_model, model_parameter_keys
from .links import LinkTiming, check_link, tdma_offsets
from .schedule import LinkSchedule, resolve_schedule

__all__ = ["NOT_TIMING", "RECEIVERS", "NetworkSettings", "check_cycle", "check_network",
           "modem_range", "resolve_links", "timing_table"]

#: what a receiver does with the newest message between arrivals: hold it, or carry it
#: forward with the sender's model
RECEIVERS = ("hold", "propagate")


#: keys of a ``[network]`` table that are not the links' timing
NOT_TIMING = ("receiver", "schedule", "schedule_period")


def timing_table(table: Any) -> dict[str, Any]:
    """The keys of a ``[network]`` table that :func:`resolve_links` reads (not ``receiver``
    nor the switching schedule, :mod:`.schedule`)."""
    return {k: v for k, v in dict(table or {}).items() if k not in NOT_TIMING}


@dataclass(frozen=True)
class NetworkSettings:
    """A checked ``[network]`` table (:func:`check_network` makes one): the receiver, the
    links' timing table, the modem range and the switching schedule, read from one place.
    The table is kept as given (:meth:`to_mapping`) for what writes it whole (an FMU's
    configuration, a run's summary, a scenario's key)."""

    table: Mapping[str, Any]            #: the checked table, as given

    @property
    def receiver(self) -> str:
        """What a receiver does between arrivals, one of :data:`RECEIVERS`."""
        return str(self.table.get("receiver", "propagate"))

    @property
    def timing(self) -> dict[str, Any]:
        """The keys :func:`resolve_links` reads (:func:`timing_table`)."""
        return timing_table(self.table)

    @property
    def range(self) -> float | None:
        """The modem range (m; None: every link in range)."""
        return float(self.table["range"]) if "range" in self.table else None

    def fleet_figures(self, h: float) -> dict[str, Any]:
        """The fleet-wide latency, period (s; default h), loss, loss model and TDMA."""
        t = self.table
        return {"latency": float(t.get("latency", 0.0)), "period": float(t.get("period", h)),
                "loss": float(t.get("loss", 0.0)),
                "loss_model": t.get(MODEL_KEY, DEFAULT_MODEL), "tdma": bool(t.get("tdma", False))}

    def schedule(self, links: Iterable[tuple[Any, int]], h: float,
                 N: int) -> LinkSchedule | None:
        """The switching schedule over an architecture's links (None without;
        :func:`~.schedule.resolve_schedule`)."""
        return resolve_schedule(self.table, links, h, N)

    def to_mapping(self) -> dict[str, Any]:
        """The table as a new plain dict."""
        return copy.deepcopy(dict(self.table))

    def updated(self, overrides: Mapping[str, Any], N: int, h: float) -> NetworkSettings:
        """The table with ``overrides`` (latency, period, loss, receiver, ...) over it,
        checked anew (:func:`check_network`)."""
        return check_network({**self.to_mapping(), **overrides}, N, h)


def _link_name(j: int | str, i: int) -> str:
    return f"network link {j} -> {i}"


def resolve_links(N: int, edges: Sequence[tuple[int, int, float]],
                  pinning: Sequence[tuple[int, float]], network: Any,
                  h: float) -> dict[tuple[int | str, int], LinkTiming]:
    """The timing of every link that carries a message, from a ``[network]`` table.

    Links are the graph's edges j -> i and leader -> i for the pinned vehicles. The
    table's ``latency``, ``period`` and loss model (``loss_model``, default "independent",
    with its parameters: ``loss``, or ``p_gb``, ``p_bg``, ``loss_good``, ``loss_bad`` for
    "gilbert-elliott", :mod:`.link_models`) are the fleet-wide defaults (without them: no
    latency, a message every step h, no loss); ``links = [{from, to, latency, period,
    loss_model, <its parameters>}, ...]`` overrides single links (``from`` a vehicle number
    or "leader"; an entry naming another model gives all of its parameters, one naming
    none changes single parameters of the fleet's); with
    ``tdma = true`` the senders take turns within the period, the leader first, then
    vehicles 1..N (:func:`tdma_offsets`, rounded to whole steps), which needs one period
    for every link. Every period must be a whole number of steps h.

    Parameters
    ----------
    N : int
        Number of vehicles.
    edges : Sequence[tuple[int, int, float]]
        (j, i, a_ij): vehicle i hears vehicle j.
    pinning : Sequence[tuple[int, float]]
        (i, a_i0): vehicle i hears the leader.
    network : Mapping or None
        The table (None: perfect links).
    h : float
        Communication step, s.

    Returns
    -------
    dict[tuple[int | str, int], LinkTiming]
        (sender, receiver) -> timing.

    Raises
    ------
    ModelError
        One line naming the link or the entry: an unknown key, a bad value, a link that is
        not a communication edge, a vehicle that does not exist, periods that differ under
        TDMA.
    """
    net = dict(network or {})
    loss_keys = (MODEL_KEY, *model_parameter_keys())
    unknown = sorted(set(net) - {"latency", "period", "tdma", "links", "range", *loss_keys})
    if unknown:
        raise ModelError(f"[network]: unknown key(s) {', '.join(unknown)} (expected latency, "
                         f"period, {', '.join(loss_keys)}, tdma, links, range, receiver, "
                         "schedule, schedule_period)")
    if "range" in net:
        modem_range(net["range"])
    fleet_loss = {k: net[k] for k in loss_keys if k in net}
    base = check_link("[network]", net.get("latency", 0.0), net.get("period", h),
                      link_model("[network]", fleet_loss), h=h)
    keys = [(int(j), int(i)) for j, i, _ in edges] + [("leader", int(i)) for i, _ in pinning]
    settings = {k: {"latency": base.latency, "period": base.period, **fleet_loss}
                for k in keys}
    entries = net.get("links", [])
    if not isinstance(entries, (list, tuple)):
        raise ModelError("[network] links must be a list of tables {from, to, ...}")
    for n, entry in enumerate(entries, start=1):
        where = f"[network] links entry {n}"
        if not isinstance(entry, dict) or "from" not in entry or "to" not in entry:
            raise ModelError(f"{where}: needs a table with from and to")
        extra = sorted(set(entry) - {"from", "to", "latency", "period", *loss_keys})
        if extra:
            raise ModelError(f"{where}: unknown key(s) {', '.join(extra)}")
        link_model(where, {k: entry[k] for k in loss_keys if k in entry}
                   if MODEL_KEY in entry else {})       # its own values: named in errors
        j = _vehicle(N, entry["from"], where)
        i = _vehicle(N, entry["to"], where)
        if (j, i) not in settings:
            heard = sorted({str(a) for a, b in keys if b == i}, key=str)
            raise ModelError(f"{_link_name(j, i)}: no such communication edge (vehicle {i} "
                             f"hears {', '.join(heard) or 'nobody'})")
        own = settings[(j, i)]
        if entry.get(MODEL_KEY, own.get(MODEL_KEY, DEFAULT_MODEL)) != own.get(
                MODEL_KEY, DEFAULT_MODEL):               # another model: its own parameters
            for k in loss_keys:
                own.pop(k, None)
        own.update({k: entry[k] for k in ("latency", "period", *loss_keys) if k in entry})
    tdma = net.get("tdma", False)
    if not isinstance(tdma, bool):
        raise ModelError(f"[network] tdma = {tdma!r} must be true or false")
    offsets: dict[Any, float] = {}
    if tdma:
        periods = {float(s["period"]) for s in settings.values()}
        if len(periods) > 1:
            raise ModelError("[network] tdma = true needs one period for every link; the "
                             f"links use {', '.join(f'{p:g}' for p in sorted(periods))} s")
        period = base.period if not periods else periods.pop()
        senders = sorted({k[0] for k in keys}, key=lambda v: -1 if v == "leader" else v)
        if period < len(senders) * h * (1 - 1e-9):
            raise ModelError(f"[network] tdma = true: {len(senders)} senders need a period of "
                             f"at least {len(senders)} steps ({len(senders) * h:g} s), not "
                             f"{period:g} s")
        # each slot starts on a step of the co-simulation
        offsets = {v: round(o / h) * h for v, o in tdma_offsets(senders, period).items()}
    return {k: check_link(_link_name(*k), s["latency"], s["period"],
                          link_model(_link_name(*k), {x: s[x] for x in loss_keys if x in s}),
                          offsets.get(k[0], 0.0), h=h) for k, s in settings.items()}


def modem_range(value: Any) -> float:
    """The ``[network] range``: the distance (m, > 0) beyond which a message is not heard
    (sender and receiver positions at its send time; simulation only: the predictions
    assume every link in range)."""
    r = _number("[network] range", value)
    if r <= 0.0:
        raise ModelError(f"[network] range = {r:g} m must be positive")
    return r


def check_network(table: Any, N: int, h: float) -> NetworkSettings:
    """A ``[network]`` table checked for a fleet of N vehicles: its ``receiver`` (one of
    :data:`RECEIVERS`) and its timing; an override must name a link of at least one
    architecture (every ordered pair of vehicles, the leader to any vehicle).

    Parameters
    ----------
    table : Any
        The table.
    N : int
        Number of vehicles.
    h : float
        Communication step, s.

    Returns
    -------
    NetworkSettings
        The checked table.

    Raises
    ------
    ModelError
        One line naming the key, link or entry.
    """
    if isinstance(table, NetworkSettings):
        table = table.to_mapping()
    if not isinstance(table, dict):
        raise ModelError(f"[network] must be a table, not {table!r}")
    receiver = table.get("receiver", "propagate")
    if receiver not in RECEIVERS:
        raise ModelError(f"[network] receiver = {receiver!r} is not one of "
                         f"{', '.join(RECEIVERS)}")
    timing = timing_table(table)
    every = [(j, i, 1.0) for i in range(1, N + 1) for j in range(1, N + 1) if j != i]
    pins = [(i, 1.0) for i in range(1, N + 1)]
    links = resolve_links(N, every, pins, timing, h)
    schedule = resolve_schedule(table, [(j, i) for j, i, _ in every] +
                                [("leader", i) for i, _ in pins], h, N)
    check_cycle(links, schedule.period if schedule is not None else 0, h)
    if schedule is not None and any(t.bursts is not None for t in links.values()):
        raise ModelError("[network] loss_model = \"gilbert-elliott\" with a schedule is not "
                         "supported (a down link's channel would step without an arrival, "
                         "which the predictions do not carry)")
    return NetworkSettings(dict(table))


def check_cycle(links: dict[tuple[Any, int], LinkTiming], schedule_period: int,
                h: float) -> int:
    """The message cycle (steps): the lcm of the links' periods and the schedule's period
    (steps, 0: none), at most :data:`~.base.MAX_MESSAGE_CYCLE_STEPS`.

    Raises
    ------
    ModelError
        Naming the periods (s) and the cycle they make, and the bound.
    """
    periods = sorted({round(t.period / h) for t in links.values()})
    cycle = math.lcm(*periods, *([schedule_period] if schedule_period else []))
    if cycle > MAX_MESSAGE_CYCLE_STEPS:
        text = ", ".join(f"{p * h:g} s" for p in periods)
        if schedule_period:
            text += f" and schedule_period {schedule_period * h:g} s"
        raise ModelError(f"[network]: the periods {text} repeat together every {cycle} steps "
                         f"of h = {h:g} s ({cycle * h:g} s), more than the "
                         f"{MAX_MESSAGE_CYCLE_STEPS} steps one message cycle may take; choose "
                         "periods with a shorter common multiple")
    return cycle
