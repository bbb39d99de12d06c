"""Test-only read-back of .rrd files: the embedded blueprint (views, layout tree, visible time
ranges) and the first series style of each entity.  The public readers of the data itself are in
:mod:`orchestrator.recording.reader`."""
from __future__ import annotations

import uuid
from pathlib import Path

import pyarrow as pa
from rerun.chunk import RrdReader

from orchestrator.recording import read_rrd_series_lines

__all__ = [
    "read_rrd_blueprint_tree",
    "read_rrd_blueprint_views",
    "read_rrd_series_styles",
    "read_rrd_visible_time_ranges",
    "rrd_has_blueprint",
]


def read_rrd_series_styles(path: str | Path) -> dict[str, tuple[str, tuple[int, int, int, int]]]:
    """Static series styles of a .rrd: entity path -> (series name, RGBA colour 0-255) of the
    first line of each entity (see :func:`read_rrd_series_lines` for every line)."""
    return {entity: (names[0], colors[0]) for entity, (names, colors) in read_rrd_series_lines(path).items()}


def read_rrd_blueprint_views(path: str | Path) -> dict[str, tuple[str, str]]:
    """Views of the blueprint(s) embedded in a .rrd: view name -> (view class, origin).

    The view class is Rerun's identifier, e.g. ``TimeSeries``; the origin is the entity
    path with its leading slash, e.g. ``/error/1``.  Empty if no blueprint is embedded.
    """
    reader = RrdReader(path)
    views: dict[str, tuple[str, str]] = {}
    for store in reader.blueprints():
        for chunk in reader.stream(store=store):
            batch = chunk.to_record_batch()
            cols = batch.schema.names
            if "ViewBlueprint:display_name" not in cols:
                continue
            names = batch.column("ViewBlueprint:display_name").to_pylist()
            classes = (batch.column("ViewBlueprint:class_identifier").to_pylist()
                       if "ViewBlueprint:class_identifier" in cols else [[""]] * len(names))
            origins = (batch.column("ViewBlueprint:space_origin").to_pylist()
                       if "ViewBlueprint:space_origin" in cols else [["/"]] * len(names))
            for n, c, o in zip(names, classes, origins):
                if n:
                    views[n[0]] = (c[0] if c else "", o[0] if o else "/")
    return views


_CONTAINER_KINDS = {1: "Tabs", 2: "Horizontal", 3: "Vertical", 4: "Grid"}


def _blueprint_rows(path: str | Path) -> dict[str, dict[str, object]]:
    """Blueprint store of a .rrd: entity path (leading slash) -> component -> last value."""
    reader = RrdReader(path)
    out: dict[str, dict[str, object]] = {}
    for store in reader.blueprints():
        for chunk in reader.stream(store=store):
            batch = chunk.to_record_batch()
            entity = "/" + chunk.entity_path.strip("/")
            for name in batch.schema.names:
                if ":" not in name or batch.num_rows == 0:
                    continue
                value = batch.column(name)[batch.num_rows - 1]
                if value.is_valid:
                    out.setdefault(entity, {})[name] = value
    return out


def read_rrd_blueprint_tree(path: str | Path) -> dict | None:
    """The layout of the blueprint embedded in a .rrd, as nested dicts (None if there is none).

    A container is ``{"kind": "Horizontal" | "Vertical" | "Grid" | "Tabs", "name": str | None,
    "contents": [...]}``; a view is ``{"kind": "view", "class": "3D" | "TimeSeries" | ...,
    "name": str, "origin": str}``.  The root is the viewport's root container.
    """
    rows = _blueprint_rows(path)
    viewport = rows.get("/viewport", {}).get("ViewportBlueprint:root_container")
    if viewport is None:
        return None

    def first(value: object) -> object:
        items = value.as_py() if hasattr(value, "as_py") else value
        return items[0] if isinstance(items, list) and items else None

    def node(entity: str) -> dict:
        comps = rows.get(entity, {})
        if "ViewBlueprint:class_identifier" in comps:
            return {"kind": "view", "class": first(comps["ViewBlueprint:class_identifier"]),
                    "name": first(comps["ViewBlueprint:display_name"]) if "ViewBlueprint:display_name" in comps
                    else None,
                    "origin": first(comps["ViewBlueprint:space_origin"]) if "ViewBlueprint:space_origin" in comps
                    else "/"}
        kind = first(comps.get("ContainerBlueprint:container_kind", pa.scalar([0])))
        name = comps.get("ContainerBlueprint:display_name")
        contents = comps.get("ContainerBlueprint:contents")
        return {"kind": _CONTAINER_KINDS.get(kind, str(kind)),
                "name": first(name) if name is not None else None,
                "contents": [node("/" + c.strip("/")) for c in (contents.as_py() if contents is not None else [])]}

    root = first(viewport)
    root_bytes = bytes(root) if isinstance(root, (bytes, list)) else None
    if root_bytes is None or len(root_bytes) != 16:
        return None
    return node(f"/container/{uuid.UUID(bytes=root_bytes)}")


def _union_value(arr: pa.UnionArray, i: int) -> tuple[str, int | None]:
    """Element i of a dense union as (variant name in snake_case, value or None)."""
    code = arr.type_codes[i].as_py()
    child = list(arr.type.type_codes).index(code)
    name = arr.type.field(child).name
    snake = "".join(("_" + ch.lower()) if ch.isupper() else ch for ch in name).lstrip("_")
    field = arr.field(child)
    value = None if pa.types.is_null(field.type) else field[arr.offsets[i].as_py()].as_py()
    return snake, value


def read_rrd_visible_time_ranges(
        path: str | Path) -> dict[tuple[str, str | None], dict[str, tuple[tuple[str, int | None], tuple[str, int | None]]]]:
    """Visible time ranges set in the embedded blueprint.

    Returns (view name, entity path with leading slash, or None for the view-wide setting)
    -> timeline -> ((start kind, start value), (end kind, end value)); kinds are
    ``cursor_relative``, ``absolute`` or ``infinite`` (value None); values are integer
    nanoseconds on duration timelines and sequence numbers on sequence timelines.
    """
    rows = _blueprint_rows(path)
    names = {e: comps["ViewBlueprint:display_name"].as_py()[0]
             for e, comps in rows.items() if "ViewBlueprint:display_name" in comps}
    out: dict[tuple[str, str | None], dict[str, tuple[tuple[str, int | None], tuple[str, int | None]]]] = {}
    for entity, comps in rows.items():
        value = comps.get("VisibleTimeRanges:ranges")
        if value is None or not entity.startswith("/view/"):
            continue
        parts = entity.split("/")  # ['', 'view', uuid, ...]
        view_entity = "/".join(parts[:3])
        rest = parts[3:]
        if rest[:2] == ["ViewContents", "overrides"] and rest[-1:] == ["visualizers"]:
            target: str | None = "/" + "/".join(rest[2:-1])
        elif rest == ["VisibleTimeRanges"]:
            target = None
        else:
            continue
        ranges = value.values  # StructArray of {timeline, range: {start, end}}
        timelines = ranges.field("timeline")
        starts = ranges.field("range").field("start")
        ends = ranges.field("range").field("end")
        per_timeline = {}
        for i in range(len(ranges)):
            per_timeline[timelines[i].as_py()] = (_union_value(starts, i), _union_value(ends, i))
        out[(names.get(view_entity, view_entity), target)] = per_timeline
    return out


def rrd_has_blueprint(path: str | Path) -> bool:
    """True if the .rrd embeds a blueprint store with at least one view."""
    return bool(read_rrd_blueprint_views(path))


def read_rrd_view_properties(path: str | Path) -> dict[str, dict[str, object]]:
    """View name -> the view's properties in the embedded blueprint, as Python values:
    ``"PlotLegend:visible"``, ``"ScalarAxis:range"``, ``"TimeAxis:view_range"``,
    ``"VisibleTimeRanges:ranges"``, ``"EyeControls3D:position"``, ... and the view's
    ``"ViewContents:query"`` (its entity filter lines)."""
    rows = _blueprint_rows(path)
    names = {e: comps["ViewBlueprint:display_name"].as_py()[0]
             for e, comps in rows.items() if "ViewBlueprint:display_name" in comps}
    out: dict[str, dict[str, object]] = {name: {} for name in names.values()}
    for entity, comps in rows.items():
        parts = entity.split("/")
        if len(parts) < 4 or parts[1] != "view":
            continue
        view = names.get("/".join(parts[:3]))
        if view is None or len(parts) != 4:
            continue
        for key, value in comps.items():
            out[view][key] = value.as_py() if hasattr(value, "as_py") else value
    return out
