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

from .layout import _shade, _vehicle_colors
from .ranges import data_range
from .selection import LINK_KEYS

__all__ = ["LINK_COLORS", "LINK_KEYS", "LINKS_LEGEND_ENTITY", "links_legend", "network_view",
           "send_links"]

#: the traces of the links (one column per link)
#: delivered, lost, in flight: grey, orange, purple (apart from the components' red, green,
#: blue)
LINK_COLORS: tuple[tuple[int, int, int], ...] = ((150, 150, 150), (255, 140, 0),
                                                 (170, 90, 230))
_LINK_COLOR_NAMES = ("grey", "orange", "purple")
_LEADER_COLOR = (255, 215, 0)
#: entity of the links' one-line legend (markdown), shown above the links view
LINKS_LEGEND_ENTITY = "legend_links"


def links_legend(methods: list[str]) -> str:
    """The one-line legend of the links and age-of-information views (markdown).

    Parameters
    ----------
    methods : list[str]
        The recorded methods with links (shaded as the main legend says).

    Returns
    -------
    str
        Markdown.
    """
    counts = " · ".join(f"{what} {c}" for what, c in zip(
        ("delivered", "lost", "in flight"), _LINK_COLOR_NAMES))
    return (f"**links** (messages): {counts} · **age** (s): the sender's 3D colour, "
            f"leader gold" + (" · methods shaded as above" if len(methods) > 1 else ""))


def _parse(name: str) -> tuple[str, str]:
    j, i = (s.strip() for s in name.split("->"))
    return j, i


def send_links(rec: rr.RecordingStream, method: str, traces: Mapping[str, np.ndarray],
               links: Sequence[str], stride: int, indexes: list[Any], method_index: int,
               n: int | None = None) -> int:
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
    n : int or None, optional
        Vehicles of the fleet (the 3D colours the age lines take); None: the highest vehicle
        number in ``links``.

    Returns
    -------
    int
        Lines written.
    """
    lines = 0
    counts = np.stack([np.asarray(traces[k], float)[::stride] for k in LINK_KEYS[1:]], axis=2)
    colors = [_shade(c, method_index) for c in LINK_COLORS]
    for c, name in enumerate(links):
        j, i = _parse(name)
        entity = f"network/links/{j}-{i}/{method}"
        rec.log(entity, rr.SeriesLines(colors=colors, names=[
            f"{method} {j}->{i} delivered", f"{method} {j}->{i} lost",
            f"{method} {j}->{i} in flight"], aggregation_policy="MinMax"), static=True)
        rec.send_columns(entity, indexes=indexes, columns=rr.Scalars.columns(
            scalars=np.ascontiguousarray(counts[:, c, :])))
        lines += 3
    age = np.asarray(traces["link_age"], float)[::stride]
    by_receiver: dict[str, list[tuple[int, str]]] = {}
    for c, name in enumerate(links):
        j, i = _parse(name)
        by_receiver.setdefault(i, []).append((c, j))
    if n is None:
        n = max(int(v) for name in links for v in _parse(name) if v.isdigit())
    vehicle = _vehicle_colors(n)

    def sender_color(j: str) -> tuple[int, int, int]:
        base = (_LEADER_COLOR if not j.isdigit()
                else tuple(int(c) for c in vehicle[int(j) - 1]))
        return _shade(base, method_index)  # type: ignore[arg-type]

    for i, cols in by_receiver.items():
        entity = f"vehicles/{i}/network/{method}/age"
        rec.log(entity, rr.SeriesLines(colors=[sender_color(j) for _, j in cols],
                                       names=[f"{method} from {j}" for _, j in cols],
                                       aggregation_policy="MinMax"),
                static=True)
        rec.send_columns(entity, indexes=indexes, columns=rr.Scalars.columns(
            scalars=np.ascontiguousarray(age[:, [c for c, _ in cols]])))
        lines += len(cols)
    return lines


def _link_columns(links: Sequence[str], receiver: str) -> list[int]:
    return [c for c, name in enumerate(links) if _parse(name)[1] == receiver]


def network_view(runs: Mapping[str, Mapping[str, np.ndarray]],
                 links: Mapping[str, Sequence[str]], series_view: Any
                 ) -> tuple[rrb.Container, dict[str, rrb.TimeSeriesView]]:
    """The links' views: (legend line over the links' counts, one age-of-information view per
    vehicle), every y-axis covering the data of every method.

    Parameters
    ----------
    runs : Mapping[str, Mapping[str, np.ndarray]]
        Method -> traces with :data:`LINK_KEYS` (methods without links are skipped).
    links : Mapping[str, Sequence[str]]
        Method -> the link of each column, "j -> i".
    series_view : Callable
        ``series_view(name, origin, contents, y_range)`` of the blueprint.

    Returns
    -------
    tuple[rrb.Container, dict[str, rrb.TimeSeriesView]]
        A Vertical (legend, counts view) named "links", and receiving vehicle -> its age
        view (named ``vehicle i age of information (s)``).
    """
    with_links = [m for m in runs if m in links]
    counts = [np.asarray(runs[m][k]) for m in with_links for k in LINK_KEYS[1:]]
    count_view = series_view("links: delivered, lost, in flight (messages)", "/network/links",
                             None, data_range(counts))
    receivers = {_parse(name)[1] for m in with_links for name in links[m]}
    ages = {}
    for i in receivers:
        data = [np.asarray(runs[m]["link_age"])[:, _link_columns(links[m], i)]
                for m in with_links]
        ages[i] = series_view(f"vehicle {i} age of information (s)",
                              f"/vehicles/{i}/network", None, data_range(data))
    legend = rrb.TextDocumentView(origin=f"/{LINKS_LEGEND_ENTITY}", name="links legend")
    return rrb.Vertical(legend, count_view, row_shares=[1.6, 5.0], name="links"), ages
