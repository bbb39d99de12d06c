"""Read the data of a .rrd file back without a viewer: scalar series (one entity or all of
them), 3D points and line strips, and the series names and colours.

Every reader returns the step index (int64) and ``sim_time`` (int64 nanoseconds; divide by
1e9 for seconds) of each recorded row, sorted by step, with the values of that row.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
from rerun.chunk import RrdReader

from .layout import _SCALARS_COLUMN, _SIM_TIME, _STEP

__all__ = [
    "read_rrd_line_strips",
    "read_rrd_points",
    "read_rrd_scalars",
    "read_rrd_series",
    "read_rrd_series_lines",
    "read_rrd_view_ranges",
]


def _int64_index(column: pa.Array | pa.ChunkedArray) -> np.ndarray:
    """An index column (int64 sequence or duration[ns]) as an int64 numpy array."""
    t = column.type
    if pa.types.is_duration(t):
        if t.unit != "ns":
            column = column.cast(pa.duration("ns"))
        column = column.cast(pa.int64())
    return np.asarray(column.to_numpy(zero_copy_only=False), dtype=np.int64)


def _scalar_rows(scal: pa.Array, what: str) -> np.ndarray:
    """A ``Scalars:scalars`` list column whose rows all hold k values, as (rows, k) float64."""
    k = _uniform(_lengths(scal), f"{what}: scalars per row")
    values = np.asarray(scal.flatten().to_numpy(zero_copy_only=False), dtype=np.float64)
    if values.size != len(scal) * k:  # null rows
        raise ValueError(f"{what}: has empty (null) rows")
    return values.reshape(len(scal), k)


def _merge_rows(pieces: list[tuple[np.ndarray, np.ndarray, np.ndarray]], what: str
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Concatenate (step, sim_time, values (rows, k)) pieces and sort them by step."""
    _uniform(np.asarray([p[2].shape[1] for p in pieces]), f"{what}: scalars per row")
    step = np.concatenate([p[0] for p in pieces])
    sim_time = np.concatenate([p[1] for p in pieces])
    values = np.concatenate([p[2] for p in pieces])
    order = np.argsort(step, kind="stable")
    return step[order], sim_time[order], values[order]


def read_rrd_scalars(path: str | Path) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Read every scalar series of the recording in a .rrd file, without a viewer.

    Static data (series styles, recording properties) is skipped.

    Parameters
    ----------
    path : str or Path
        The .rrd file.

    Returns
    -------
    dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]
        Entity path (no leading slash, e.g. ``error/1/kalman``) -> (step as int64,
        sim_time as int64 nanoseconds, values as float64), sorted by step.  Values are 1-D
        (rows,) for entities with one scalar per row (the paper layout) and (rows, k) for
        the multi-component entities of the fleet layout (e.g. ``vehicles/1/error/kalman``)
        with k > 1; :func:`read_rrd_series` always returns (rows, k).

    Raises
    ------
    ValueError
        If an entity's rows hold different numbers of scalars or a chunk lacks the
        step / sim_time timelines.
    """
    parts: dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {}
    for chunk in RrdReader(path).stream():
        if chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        names = batch.schema.names
        if _SCALARS_COLUMN not in names:
            continue
        entity = chunk.entity_path.lstrip("/")
        if _STEP not in names or _SIM_TIME not in names:
            raise ValueError(f"{path}: scalar chunk of {entity!r} lacks the step/sim_time "
                             "timelines")
        values = _scalar_rows(batch.column(_SCALARS_COLUMN), f"{path}: {entity!r}")
        parts.setdefault(entity, []).append(
            (_int64_index(batch.column(_STEP)), _int64_index(batch.column(_SIM_TIME)), values))

    out: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    for entity, pieces in parts.items():
        step, sim_time, values = _merge_rows(pieces, f"{path}: {entity!r}")
        out[entity] = (step, sim_time, values[:, 0] if values.shape[1] == 1 else values)
    return out


def read_rrd_series(path: str | Path, entity: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read the scalar series of one entity (e.g. ``vehicles/2/state/kalman/true``).

    Parameters
    ----------
    path : str or Path
        The .rrd file.
    entity : str
        Entity path (a leading slash is optional).

    Returns
    -------
    step : np.ndarray
        Step index of each row, int64, sorted.
    sim_time : np.ndarray
        Simulation time of each row, int64 nanoseconds.
    values : np.ndarray
        float64 of shape (rows, k); column c is component c (the c-th series line).

    Raises
    ------
    KeyError
        If the entity has no scalars.
    ValueError
        If rows hold different numbers of scalars.
    """
    step, sim_time, cols = _entity_rows(path, entity, _SCALARS_COLUMN)
    values = [_scalar_rows(col, f"{path}: {entity!r}") for col in cols]
    offsets = np.cumsum([0] + [len(v) for v in values])
    return _merge_rows([(step[a:b], sim_time[a:b], v)
                        for a, b, v in zip(offsets[:-1], offsets[1:], values)],
                       f"{path}: {entity!r}")


def _entity_rows(path: str | Path, entity: str,
                 column: str) -> tuple[np.ndarray, np.ndarray, list[pa.Array]]:
    """Temporal rows of one component column of one entity: (step, sim_time, pieces), unsorted."""
    want = "/" + entity.strip("/")
    steps: list[np.ndarray] = []
    times: list[np.ndarray] = []
    pieces: list[pa.Array] = []
    for chunk in RrdReader(path).stream():
        if chunk.is_static or "/" + chunk.entity_path.strip("/") != want:
            continue
        batch = chunk.to_record_batch()
        names = batch.schema.names
        if column not in names:
            continue
        if _STEP not in names or _SIM_TIME not in names:
            raise ValueError(f"{path}: {column} chunk of {entity!r} lacks the step/sim_time "
                             "timelines")
        steps.append(_int64_index(batch.column(_STEP)))
        times.append(_int64_index(batch.column(_SIM_TIME)))
        pieces.append(batch.column(column))
    if not pieces:
        raise KeyError(f"{path}: no temporal {column} data for entity {entity!r}")
    return np.concatenate(steps), np.concatenate(times), pieces


def _uniform(lengths: np.ndarray, what: str) -> int:
    if lengths.size == 0:
        return 0
    if not np.all(lengths == lengths[0]):
        raise ValueError(f"{what}: rows differ in length "
                         f"({int(lengths.min())}..{int(lengths.max())})")
    return int(lengths[0])


def _lengths(arr: pa.Array) -> np.ndarray:
    return np.asarray(arr.value_lengths().fill_null(0).to_numpy(zero_copy_only=False),
                      dtype=np.int64)


def read_rrd_points(path: str | Path, entity: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read the temporal ``Points3D`` positions of one entity (e.g. ``world/kalman/vehicles``).

    Parameters and returns as :func:`read_rrd_series` (step, sim_time sorted by step), the
    third array the positions, float32 of shape (rows, n, 3), m (NED). KeyError if the
    entity has no positions, ValueError if rows hold different numbers of points.
    """
    step, sim_time, pieces = _entity_rows(path, entity, "Points3D:positions")
    rows = []
    for col in pieces:
        n = _uniform(_lengths(col), f"{path}: {entity!r} points")
        xyz = np.asarray(col.flatten().flatten().to_numpy(zero_copy_only=False), dtype=np.float32)
        rows.append(xyz.reshape(len(col), n, 3))
    _uniform(np.asarray([r.shape[1] for r in rows]), f"{path}: {entity!r} points")
    positions = np.concatenate(rows)
    order = np.argsort(step, kind="stable")
    return step[order], sim_time[order], positions[order]


def read_rrd_line_strips(path: str | Path,
                         entity: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read the temporal ``LineStrips3D`` strips of one entity (e.g. ``world/kalman/edges``).

    Parameters and returns as :func:`read_rrd_series` (step, sim_time sorted by step), the
    third array the strips, float32 of shape (rows, strips per row, points per strip, 3),
    m (NED). KeyError if the entity has no strips, ValueError if the rows are ragged.
    """
    step, sim_time, pieces = _entity_rows(path, entity, "LineStrips3D:strips")
    rows = []
    for col in pieces:
        n_strips = _uniform(_lengths(col), f"{path}: {entity!r} strips per row")
        inner = col.flatten()
        n_points = _uniform(_lengths(inner), f"{path}: {entity!r} points per strip")
        xyz = np.asarray(inner.flatten().flatten().to_numpy(zero_copy_only=False),
                         dtype=np.float32)
        rows.append(xyz.reshape(len(col), n_strips, n_points, 3))
    _uniform(np.asarray([r.shape[1] * 1000003 + r.shape[2] for r in rows]),
             f"{path}: {entity!r} strips")
    strips = np.concatenate(rows)
    order = np.argsort(step, kind="stable")
    return step[order], sim_time[order], strips[order]


def _unpack_rgba(packed: int) -> tuple[int, int, int, int]:
    packed = int(packed)  # 0xRRGGBBAA
    return ((packed >> 24) & 0xFF, (packed >> 16) & 0xFF, (packed >> 8) & 0xFF, packed & 0xFF)


def read_rrd_series_lines(
        path: str | Path,
) -> dict[str, tuple[tuple[str, ...], tuple[tuple[int, int, int, int], ...]]]:
    """Static series styles of the .rrd file ``path``, every line: names and RGBA colours
    per entity.

    Returns
    -------
    dict[str, tuple[tuple[str, ...], tuple[tuple[int, int, int, int], ...]]]
        Entity path -> (series names, RGBA colours 0-255), one name and colour per
        component (one of each in the paper layout).
    """
    out: dict[str, tuple[tuple[str, ...], tuple[tuple[int, int, int, int], ...]]] = {}
    for chunk in RrdReader(path).stream():
        if not chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        names = batch.schema.names
        if "SeriesLines:names" not in names or "SeriesLines:colors" not in names:
            continue
        entity = chunk.entity_path.lstrip("/")
        out[entity] = (tuple(batch.column("SeriesLines:names").to_pylist()[-1]),
                       tuple(_unpack_rgba(c)
                             for c in batch.column("SeriesLines:colors").to_pylist()[-1]))
    return out


def read_rrd_view_ranges(path: str | Path) -> dict[str, tuple[float, float] | None]:
    """The time-series views of the default blueprint embedded in the .rrd file ``path``:
    each view's name and the y range it opens with.

    Returns
    -------
    dict[str, tuple[float, float] or None]
        View name (e.g. ``vehicle 1 error (m)``) -> (low, high) of its y-axis, None for a
        view that fits its axis to the data. Views of other kinds (3D, text) are left out.

    Raises
    ------
    ValueError
        If the file holds no blueprint.
    """
    reader = RrdReader(path)
    stores = reader.blueprints()
    if not stores:
        raise ValueError(f"{path}: holds no blueprint")
    names: dict[str, str] = {}
    kinds: dict[str, str] = {}
    ranges: dict[str, tuple[float, float]] = {}
    for chunk in reader.stream(store=stores[0]):
        batch = chunk.to_record_batch()
        cols = batch.schema.names
        parts = chunk.entity_path.strip("/").split("/")
        if len(parts) < 2 or parts[0] != "view":
            continue
        view = parts[1]
        if len(parts) == 2:
            for col, into in (("ViewBlueprint:display_name", names),
                              ("ViewBlueprint:class_identifier", kinds)):
                if col in cols and (value := batch.column(col).to_pylist()[-1]):
                    into[view] = value[0] if isinstance(value, list) else value
        elif parts[2:] == ["ScalarAxis"] and "ScalarAxis:range" in cols:
            value = batch.column("ScalarAxis:range").to_pylist()[-1]
            if value:
                lo, hi = value[0] if isinstance(value[0], (list, tuple)) else value
                ranges[view] = (float(lo), float(hi))
    return {names.get(v, v): ranges.get(v) for v, kind in kinds.items()
            if kind == "TimeSeries"}
