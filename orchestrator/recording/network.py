"""The acoustic links in the recording: each link's counts and each vehicle's age of
information (per-vehicle fleets over a ``[network]``).

Entities, per method m::

    network/links/{j}-{i}/{m}     delivered, lost, in flight (messages, one line each)
    vehicles/{i}/network/{m}/age  age of the newest information vehicle i holds about each
                                  sender (s, one line per sender: "from j", "from leader")

The traces are the network FMUs' outputs in the stacked layout of a run (``link_age``,
``link_delivered``, ``link_lost``, ``link_in_flight``: one column per link, in the order of
the run's link names "j -> i").
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from .layout import axis_colors

__all__ = ["LINK_KEYS", "network_view", "send_links"]

#: the traces of the links (one column per link)
LINK_KEYS = ("link_age", "link_delivered", "link_lost", "link_in_flight")


def _parse(name: str) -> tuple[str, str]:
    j, i = (s.strip() for s in name.split("->"))
    return j, i


def send_links(rec: rr.RecordingStream, method: str, traces: Mapping[str, np.ndarray],
               links: Sequence[str], stride: int, indexes: list[Any], method_index: int
               ) -> int:
    """Log one run's links; returns the number of scalar lines written.

    Parameters
    ----------
    rec : rr.RecordingStream
        The open recording.
    method : str
        The run's method name.
    traces : Mapping[str, np.ndarray]
        The run's traces with :data:`LINK_KEYS`.
    links : Sequence[str]
        The link of each column, "j -> i".
    stride : int
        Record every stride-th step.
    indexes : list
        The time columns of the recorded steps.
    method_index : int
        The method's place (shade).

    Returns
    -------
    int
        Lines written.
    """
    lines = 0
    counts = np.stack([np.asarray(traces[k], float)[::stride] for k in LINK_KEYS[1:]], axis=2)
    colors = axis_colors(3, method_index)
    for c, name in enumerate(links):
        j, i = _parse(name)
        entity = f"network/links/{j}-{i}/{method}"
        rec.log(entity, rr.SeriesLines(colors=colors, names=[
            f"{method} {j}->{i} delivered", f"{method} {j}->{i} lost",
            f"{method} {j}->{i} in flight"]), static=True)
        rec.send_columns(entity, indexes=indexes, columns=rr.Scalars.columns(
            scalars=np.ascontiguousarray(counts[:, c, :])))
        lines += 3
    age = np.asarray(traces["link_age"], float)[::stride]
    by_receiver: dict[str, list[tuple[int, str]]] = {}
    for c, name in enumerate(links):
        j, i = _parse(name)
        by_receiver.setdefault(i, []).append((c, j))
    for i, cols in by_receiver.items():
        entity = f"vehicles/{i}/network/{method}/age"
        rec.log(entity, rr.SeriesLines(colors=axis_colors(len(cols), method_index),
                                       names=[f"{method} from {j}" for _, j in cols]),
                static=True)
        rec.send_columns(entity, indexes=indexes, columns=rr.Scalars.columns(
            scalars=np.ascontiguousarray(age[:, [c for c, _ in cols]])))
        lines += len(cols)
    return lines


def network_view(n: int, series_view: Any) -> rrb.Container:
    """The blueprint tab of the links: every vehicle's age of information, and the links'
    counts."""
    ages = [series_view(f"vehicle {i} age of information (s)", f"/vehicles/{i}/network")
            for i in range(1, n + 1)]
    counts = series_view("links: delivered, lost, in flight", "/network/links")
    return rrb.Grid(contents=[counts, *ages], grid_columns=2, name="network")
