"""A switching topology for the acoustic network: graphs with the times they take over (the
paper's eq. 1, N_i^t, as whom vehicle i hears at t).

A ``[network] schedule`` is a list of graphs, each with the time t (s) from which it holds:

- ``{t = 0.0, edges = [[j, i], ...]}``: only the listed links carry messages (j a vehicle
  number or "leader"; every other link of the architecture is down), or
- ``{t = 60.0, down = [[j, i], ...]}``: every link carries messages except the listed ones.

``schedule_period`` (s, optional) repeats the schedule; without it the last graph holds to
the end. A link that is down loses every message *sent* while it is down (as a modem out of
range does: the loss draw is made all the same, so a schedule never shifts another
message's draw); the receiver keeps what it has, held or propagated, a fixed-gain receiver
as everywhere else. The controllers' weights stay the scenario graph's: a schedule says
which links carry messages, not how a controller weighs them.

Switch times and the period are whole numbers of steps h. Joint connectivity (the union of
the graphs over a period lets the leader's information reach every vehicle) is necessary
for tracking, not sufficient: the verdict is the spectral radius of the error second
moment over one period (:mod:`orchestrator.analysis.acoustic.prediction`). Pure Python,
no FMI.
"""
from __future__ import annotations

import bisect
from collections.abc import Hashable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from ..linalg_checks import ModelError
from .base import _number, _vehicle, whole_steps

__all__ = ["LinkSchedule", "check_schedule", "connectivity", "resolve_schedule"]

Link = tuple[Any, int]


def check_schedule(entries: Any, N: int) -> list[tuple[float, str, list[Link]]]:
    """A switching topology validated on its own: times in order, vehicles that exist.

    Parameters
    ----------
    entries : Any
        ``[{t, edges = [[j, i], ...]} or {t, down = [[j, i], ...]}, ...]``, t in s strictly
        increasing from 0; j a vehicle number or "leader", i a vehicle number.
    N : int
        Number of vehicles.

    Returns
    -------
    list[tuple[float, str, list[tuple[Any, int]]]]
        (switch time, "edges" or "down", links) in order.

    Raises
    ------
    ModelError
        One line naming the entry: decreasing or repeated times, a first time other than 0,
        a vehicle that does not exist, a self-loop, both or neither of edges and down.
    """
    if not isinstance(entries, (list, tuple)) or not entries:
        raise ModelError("[network] schedule must be a non-empty list of {t, edges} or "
                         "{t, down}")
    out: list[tuple[float, str, list[Link]]] = []
    for n, entry in enumerate(entries, start=1):
        where = f"[network] schedule entry {n}"
        if not isinstance(entry, dict) or "t" not in entry:
            raise ModelError(f"{where}: needs a table with t and edges (or down)")
        kinds = [k for k in ("edges", "down") if k in entry]
        extra = sorted(set(entry) - {"t", "edges", "down"})
        if extra:
            raise ModelError(f"{where}: unknown key(s) {', '.join(extra)} (expected t and "
                             "edges or down)")
        if len(kinds) != 1:
            raise ModelError(f"{where}: give either edges (the links that carry messages) or "
                             "down (the links that do not), not "
                             f"{'both' if kinds else 'neither'}")
        t = _number(f"{where}: t", entry["t"])
        if n == 1 and t != 0.0:
            raise ModelError(f"{where}: the first graph must start at t = 0, not {t:g} s")
        if out and t <= out[-1][0]:
            raise ModelError(f"{where}: t = {t:g} s does not come after the previous "
                             f"switch at {out[-1][0]:g} s (switch times must increase)")
        links = entry[kinds[0]]
        if not isinstance(links, (list, tuple)):
            raise ModelError(f"{where}: {kinds[0]} must be a list of [j, i] pairs")
        pairs: list[Link] = []
        for e in links:
            if not isinstance(e, (list, tuple)) or len(e) != 2:
                raise ModelError(f"{where}: {e!r} is not a link [j, i] (j a vehicle or "
                                 "\"leader\"; the weights are the scenario graph's)")
            j = _vehicle(N, e[0], f"{where}, link {list(e)}")
            i = _vehicle(N, e[1], f"{where}, link {list(e)}")
            if i == "leader":
                raise ModelError(f"{where}, link {list(e)}: the leader receives nothing")
            if j == i:
                raise ModelError(f"{where}, link {list(e)}: a self-loop")
            pairs.append((j, int(i)))
        out.append((t, kinds[0], pairs))
    return out


@dataclass(frozen=True)
class LinkSchedule:
    """Which links are up at a step: graph g holds from ``switch[g]`` (steps), repeating
    every ``period`` steps if set (0: the last graph holds to the end)."""

    switch: tuple[int, ...]
    period: int
    up: Mapping[Hashable, tuple[bool, ...]]     #: per link, per graph

    def graph(self, k: int) -> int:
        """The graph in force at step k (0-based)."""
        if self.period:
            k %= self.period
        return bisect.bisect_right(self.switch, k) - 1

    def is_up(self, link: Hashable, k: int) -> bool:
        """Does ``link`` carry the message it sends at step k?"""
        return self.up[link][self.graph(k)]

    @property
    def settled(self) -> int:
        """The step from which the graph is periodic (0 with a period, else the last
        switch)."""
        return 0 if self.period else self.switch[-1]


def resolve_schedule(table: Any, links: Iterable[Link], h: float, N: int
                     ) -> LinkSchedule | None:
    """The schedule of a ``[network]`` table over an architecture's links (None without).

    Parameters
    ----------
    table : Mapping or None
        The ``[network]`` table: ``schedule`` (:func:`check_schedule`) and
        ``schedule_period`` (s).
    links : Iterable[tuple[Any, int]]
        The architecture's links (sender, receiver).
    h : float
        Communication step, s.
    N : int
        Number of vehicles.

    Returns
    -------
    LinkSchedule or None
        Per link whether it is up in each graph.

    Raises
    ------
    ModelError
        One line: a link the architecture does not have (naming whom the receiver hears), a
        time or period that is not whole steps, a period not beyond the last switch.
    """
    net = dict(table or {})
    if "schedule" not in net:
        if "schedule_period" in net:
            raise ModelError("[network] schedule_period needs a schedule")
        return None
    keys = list(links)
    entries = check_schedule(net["schedule"], N)
    switch = tuple(whole_steps(f"[network] schedule entry {n}: t", t, h) if t else 0
                   for n, (t, _, _) in enumerate(entries, start=1))
    period = 0
    if "schedule_period" in net:
        T = _number("[network] schedule_period", net["schedule_period"])
        if T <= entries[-1][0]:
            raise ModelError(f"[network] schedule_period = {T:g} s must come after the last "
                             f"switch at {entries[-1][0]:g} s")
        period = whole_steps("[network] schedule_period", T, h)
    have = set(keys)
    up: dict[Hashable, list[bool]] = {k: [] for k in keys}
    for n, (_, kind, pairs) in enumerate(entries, start=1):
        for p in pairs:
            if p not in have:
                heard = sorted({str(a) for a, b in keys if b == p[1]}, key=str)
                raise ModelError(f"[network] schedule entry {n}: link {p[0]} -> {p[1]} is not "
                                 f"a link of this architecture (vehicle {p[1]} hears "
                                 f"{', '.join(heard) or 'nobody'})")
        listed = set(pairs)
        for k in keys:
            up[k].append((k in listed) if kind == "edges" else (k not in listed))
    return LinkSchedule(switch=switch, period=period, up={k: tuple(v) for k, v in up.items()})


def connectivity(schedule: LinkSchedule, links: Iterable[Link]) -> dict[str, Any]:
    """Whether the leader's information reaches every receiver, per graph and jointly.

    Parameters
    ----------
    schedule : LinkSchedule
        The schedule.
    links : Iterable[tuple[Any, int]]
        The architecture's links.

    Returns
    -------
    dict[str, Any]
        ``connected_graphs``: per graph whether the up links hold a spanning tree from the
        leader; ``jointly_connected``: whether their union over a period (or over the graphs
        from the last switch on, without a period) does.
    """
    keys = list(links)
    receivers = {i for _, i in keys}
    G = len(schedule.switch)

    def reaches(active: set[Link]) -> bool:
        seen, frontier = {"leader"}, ["leader"]
        while frontier:
            j = frontier.pop()
            for a, b in active:
                if a == j and b not in seen:
                    seen.add(b)
                    frontier.append(b)
        return receivers <= seen

    per = [reaches({k for k in keys if schedule.up[k][g]}) for g in range(G)]
    tail = range(G) if schedule.period else range(G - 1, G)
    union = {k for k in keys for g in tail if schedule.up[k][g]}
    return {"connected_graphs": per, "jointly_connected": reaches(union)}
