"""Write simulation traces to a Rerun .rrd file (rerun-sdk 0.41) and read them back.

Two layouts: per component ("paper", the default) and, when a :class:`FleetLayout` is
given, a compact per-vehicle layout with a 3D scene written instead. Every entity path,
the timelines (``step``, ``sim_time``), decimation (``stride``), colours and the default
blueprints are documented in docs/recording.md. Modules: :mod:`.layout` (trace keys, entity
paths, colours), :mod:`.validation`, :mod:`.blueprint`, :mod:`.writer` (the series),
:mod:`.whole` (:func:`write_rrd`),
:mod:`.stream` (:class:`RrdStream`, the file written chunk by chunk), :mod:`.scene` (a
fleet's 3D scene), :mod:`.reader` (``read_rrd_*``).
"""
from __future__ import annotations

import importlib
from typing import Any

from .layout import TRACE_KEYS, VIEW_GROUPS, FleetLayout, method_color

#: names served by a submodule that imports Rerun: loaded on first use, so that importing
#: the layout (the workflow, before a run) does not pay Rerun's import (about 0.5 s)
_LAZY = {"write_rrd": ".whole", "RrdStream": ".stream", "read_rrd_line_strips": ".reader",
         "read_rrd_points": ".reader", "read_rrd_scalars": ".reader",
         "read_rrd_series": ".reader", "read_rrd_series_lines": ".reader",
         "read_rrd_view_ranges": ".reader"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["TRACE_KEYS", "VIEW_GROUPS", "FleetLayout", "method_color", *_LAZY]
