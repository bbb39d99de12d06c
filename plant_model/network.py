"""Acoustic links between vehicles: message schedule, latency, loss, and the receiver.

Underwater, vehicles talk through acoustic modems: a message every few seconds, a latency
of a second or more, losses of tens of percent. One directed link (sender -> receiver) at
the co-simulation's fixed step h, all times in seconds:

- the sender transmits at t = offset + m period (m = 0, 1, ...), i.e. at the steps
  k = round((offset + m period) / h); with a TDMA schedule the senders take turns, sender
  number s of S transmitting at offset = s period / S (:func:`tdma_offsets`);
- each message is lost independently with probability ``loss``, one uniform draw per
  message from the link's own generator, seeded [seed, 1_000_000 + key] (apart from every
  vehicle's noise stream, [seed, i]);
- a message that is not lost arrives ``latency`` later, at the first step at or after
  t_send + latency (ceil((t_send + latency) / h)); at most ceil(latency / period) + 1 are
  in flight at once;
- the receiver keeps the newest message that has arrived (its value and send time). It
  either holds that value, or propagates it to the current time with the sender's model,
  x(t) = Phi^(k - k_send) x(t_send) (:func:`propagate`). Both are fixed-gain receivers.

The age of information is t - t_send of the newest arrived message (infinite before the
first). :func:`resolve_links` gives every link of a fleet its timing from a ``[network]``
table (fleet-wide defaults, per-link overrides, TDMA), :func:`check_schedule` validates a
switching topology. This module is the mathematics only: the FMU and the predictions build
on it.
"""
from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .linalg_checks import ModelError

__all__ = ["LinkTiming", "LinkChannel", "check_link", "check_schedule", "propagate",
           "resolve_links", "tdma_offsets"]

#: added to the seed key of a link's generator (vehicles use 1..N, the leader 0)
LINK_KEY_BASE = 1_000_000


@dataclass(frozen=True)
class LinkTiming:
    """When a link transmits, how long a message travels, how often it is lost."""

    latency: float      #: s, >= 0
    period: float       #: s, > 0: one message per period
    loss: float         #: probability in [0, 1)
    offset: float = 0.0  #: s, in [0, period): the first transmission (TDMA slot)

    @property
    def max_in_flight(self) -> int:
        """ceil(latency / period) + 1: the most messages that can travel at once."""
        return math.ceil(self.latency / self.period) + 1


def _number(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ModelError(f"{name} = {value!r} is not a number")
    v = float(value)
    if not math.isfinite(v):
        raise ModelError(f"{name} = {v} is not finite")
    return v


def check_link(name: str, latency: Any, period: Any, loss: Any,
               offset: Any = 0.0) -> LinkTiming:
    """A validated :class:`LinkTiming`; every error is one line naming the link.

    Parameters
    ----------
    name : str
        The link, e.g. "link 2 -> 4" or "leader -> 1".
    latency, period, loss, offset : Any
        Seconds (>= 0), seconds (> 0), a probability in [0, 1), seconds in [0, period).

    Returns
    -------
    LinkTiming
        The timing.

    Raises
    ------
    ModelError
        Naming the link and the value.
    """
    lat = _number(f"{name}: latency", latency)
    per = _number(f"{name}: period", period)
    p = _number(f"{name}: loss", loss)
    off = _number(f"{name}: offset", offset)
    if lat < 0.0:
        raise ModelError(f"{name}: latency = {lat:g} s is negative")
    if per <= 0.0:
        raise ModelError(f"{name}: period = {per:g} s must be positive")
    if not 0.0 <= p < 1.0:
        raise ModelError(f"{name}: loss = {p:g} is not a probability in [0, 1) (a link "
                         "that loses every message carries nothing)")
    if not 0.0 <= off < per:
        raise ModelError(f"{name}: offset = {off:g} s is not within [0, period = {per:g} s)")
    return LinkTiming(latency=lat, period=per, loss=p, offset=off)


def tdma_offsets(senders: Sequence[int], period: float) -> dict[int, float]:
    """TDMA: S senders take turns in each period, sender number s at s period / S.

    Parameters
    ----------
    senders : Sequence[int]
        The senders in slot order (vehicle numbers).
    period : float
        The cycle, s.

    Returns
    -------
    dict[int, float]
        Sender -> its transmission offset, s.
    """
    S = len(senders)
    return {int(v): s * float(period) / S for s, v in enumerate(senders)}


def propagate(value: np.ndarray, steps: int, Phi: np.ndarray) -> np.ndarray:
    """Phi^steps value: a received state carried forward with the sender's model.

    Parameters
    ----------
    value : np.ndarray
        The state at its send time.
    steps : int
        Steps since then (>= 0).
    Phi : np.ndarray
        The sender's one-step map.

    Returns
    -------
    np.ndarray
        The state now.
    """
    return np.linalg.matrix_power(np.asarray(Phi, dtype=float), int(steps)) @ value


class LinkChannel:
    """One directed link, stepped with the co-simulation (module docstring)."""

    def __init__(self, timing: LinkTiming, h: float, seed: int, key: int, size: int):
        self.timing, self.h, self.size = timing, float(h), int(size)
        self.rng = np.random.default_rng([int(seed), LINK_KEY_BASE + int(key)])
        self._first = round(timing.offset / self.h)
        self._every = timing.period / self.h
        self._m = 0                                  # next message number
        self.in_flight: deque[tuple[int, int, np.ndarray]] = deque()
        self.held: np.ndarray | None = None
        self.held_sent: int | None = None
        self.sent = self.lost = self.delivered = 0

    def _next_send(self) -> int:
        return self._first + round(self._m * self._every)

    def step(self, k: int, value: np.ndarray) -> None:
        """At step k: transmit ``value`` if k is a send step (unless lost), then deliver
        every message due by k.

        Parameters
        ----------
        k : int
            The step (t = k h), visited in increasing order.
        value : np.ndarray
            What the sender would send now, shape (size,).
        """
        while self._next_send() < k:                 # steps skipped: their messages never left
            self._m += 1
        if self._next_send() == k:
            self._m += 1
            self.sent += 1
            if self.rng.random() < self.timing.loss:
                self.lost += 1
            else:
                t_send = k * self.h
                arrive = math.ceil((t_send + self.timing.latency) / self.h - 1e-9)
                self.in_flight.append((arrive, k, np.array(value, dtype=float)))
        while self.in_flight and self.in_flight[0][0] <= k:
            _, k_sent, v = self.in_flight.popleft()
            self.held, self.held_sent = v, k_sent
            self.delivered += 1

    def age(self, k: int) -> float:
        """t - t_send of the newest message arrived by step k, s (inf before the first)."""
        return math.inf if self.held_sent is None else (k - self.held_sent) * self.h

    def received(self, k: int, Phi: np.ndarray | None = None) -> np.ndarray | None:
        """What the receiver uses at step k: the held value, or with ``Phi`` the held value
        propagated to k (None before the first message).

        Parameters
        ----------
        k : int
            The step.
        Phi : np.ndarray or None, optional
            The sender's one-step map (propagating receiver).

        Returns
        -------
        np.ndarray or None
            The value.
        """
        if self.held is None:
            return None
        if Phi is None:
            return self.held
        return propagate(self.held, k - self.held_sent, Phi)


# ------------------------------------------------------------------------------------
# a fleet's links from its graph and a [network] table
def _vehicle(N: int, value: Any, where: str) -> int | str:
    if value == "leader":
        return "leader"
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ModelError(f"{where}: {value!r} is not a vehicle number or \"leader\"")
    if not 1 <= int(value) <= N:
        raise ModelError(f"{where}: vehicle {value} does not exist (vehicles are 1..{N})")
    return int(value)


def _link_name(j: int | str, i: int) -> str:
    return f"network link {j} -> {i}"


def resolve_links(N: int, edges: Sequence[tuple[int, int, float]],
                  pinning: Sequence[tuple[int, float]], network: Any,
                  h: float) -> dict[tuple[int | str, int], LinkTiming]:
    """The timing of every link that carries a message, from a ``[network]`` table.

    Links are the graph's edges j -> i and leader -> i for the pinned vehicles. The
    table's ``latency``, ``period`` and ``loss`` are the fleet-wide defaults (without them:
    no latency, a message every step h, no loss); ``links = [{from, to, latency, period,
    loss}, ...]`` overrides single links (``from`` a vehicle number or "leader"); with
    ``tdma = true`` the senders take turns within the period, the leader first, then
    vehicles 1..N (:func:`tdma_offsets`), which needs one period for every link.

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
    unknown = sorted(set(net) - {"latency", "period", "loss", "tdma", "links"})
    if unknown:
        raise ModelError(f"[network]: unknown key(s) {', '.join(unknown)} (expected latency, "
                         "period, loss, tdma, links)")
    base = check_link("[network]", net.get("latency", 0.0), net.get("period", h),
                      net.get("loss", 0.0))
    keys = [(int(j), int(i)) for j, i, _ in edges] + [("leader", int(i)) for i, _ in pinning]
    settings = {k: {"latency": base.latency, "period": base.period, "loss": base.loss}
                for k in keys}
    entries = net.get("links", [])
    if not isinstance(entries, (list, tuple)):
        raise ModelError("[network] links must be a list of tables {from, to, ...}")
    for n, entry in enumerate(entries, start=1):
        where = f"[network] links entry {n}"
        if not isinstance(entry, dict) or "from" not in entry or "to" not in entry:
            raise ModelError(f"{where}: needs a table with from and to")
        extra = sorted(set(entry) - {"from", "to", "latency", "period", "loss"})
        if extra:
            raise ModelError(f"{where}: unknown key(s) {', '.join(extra)}")
        j = _vehicle(N, entry["from"], where)
        i = _vehicle(N, entry["to"], where)
        if (j, i) not in settings:
            heard = sorted({str(a) for a, b in keys if b == i}, key=str)
            raise ModelError(f"{_link_name(j, i)}: no such communication edge (vehicle {i} "
                             f"hears {', '.join(heard) or 'nobody'})")
        settings[(j, i)].update({k: entry[k] for k in ("latency", "period", "loss")
                                 if k in entry})
    tdma = net.get("tdma", False)
    if not isinstance(tdma, bool):
        raise ModelError(f"[network] tdma = {tdma!r} must be true or false")
    offsets: dict[Any, float] = {}
    if tdma:
        periods = {float(s["period"]) for s in settings.values()}
        if len(periods) > 1:
            raise ModelError("[network] tdma = true needs one period for every link; the "
                             f"links use {', '.join(f'{p:g}' for p in sorted(periods))} s")
        offsets = tdma_offsets(range(N + 1), base.period if not periods else periods.pop())
        offsets = {("leader" if s == 0 else s): o for s, o in offsets.items()}
    return {k: check_link(_link_name(*k), s["latency"], s["period"], s["loss"],
                          offsets.get(k[0], 0.0)) for k, s in settings.items()}


def check_schedule(entries: Any, N: int) -> list[tuple[float, list[tuple[int, int, float]]]]:
    """A switching topology: graphs with the times they take over (eq. 1's N_i^t).

    Parameters
    ----------
    entries : Any
        ``[{t, edges = [[j, i, a_ij], ...]}, ...]``, t in s strictly increasing from 0.
    N : int
        Number of vehicles.

    Returns
    -------
    list[tuple[float, list[tuple[int, int, float]]]]
        (switch time, edges) in order.

    Raises
    ------
    ModelError
        One line naming the entry: decreasing or repeated times, a first time other than 0,
        a vehicle that does not exist, a self-loop or a negative weight.
    """
    if not isinstance(entries, (list, tuple)) or not entries:
        raise ModelError("[network] schedule must be a non-empty list of {t, edges}")
    out: list[tuple[float, list[tuple[int, int, float]]]] = []
    for n, entry in enumerate(entries, start=1):
        where = f"[network] schedule entry {n}"
        if not isinstance(entry, dict) or "t" not in entry or "edges" not in entry:
            raise ModelError(f"{where}: needs a table with t and edges")
        t = _number(f"{where}: t", entry["t"])
        if n == 1 and t != 0.0:
            raise ModelError(f"{where}: the first graph must start at t = 0, not {t:g} s")
        if out and t <= out[-1][0]:
            raise ModelError(f"{where}: t = {t:g} s does not come after the previous "
                             f"switch at {out[-1][0]:g} s (switch times must increase)")
        edges = []
        for e in entry["edges"]:
            if not isinstance(e, (list, tuple)) or len(e) != 3:
                raise ModelError(f"{where}: edge {e!r} is not [j, i, a_ij]")
            j = _vehicle(N, e[0], f"{where}, edge {list(e)}")
            i = _vehicle(N, e[1], f"{where}, edge {list(e)}")
            if j == "leader" or i == "leader":
                raise ModelError(f"{where}, edge {list(e)}: edges join vehicles; the leader's "
                                 "links are the pinning")
            if j == i:
                raise ModelError(f"{where}, edge {list(e)}: a self-loop")
            a = _number(f"{where}, edge {list(e)}: weight", e[2])
            if a < 0.0:
                raise ModelError(f"{where}, edge {list(e)}: negative weight {a:g}")
            edges.append((int(j), int(i), a))
        out.append((t, edges))
    return out
