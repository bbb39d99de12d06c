"""The output folder of a campaign: its lock, the finished rows, the Parquet tables.

- the lock: held by the client while it runs (``.<name>.lock`` beside the folder,
  :func:`orchestrator.outputs.output_folder`, the lock of every command's output folder);
  a second campaign (or any command) into the same folder is refused. The kernel releases
  it when the process ends, however it ends. The client writes into a staging folder
  beside the destination (:func:`orchestrator.outputs.staged_output`), swapped in at the
  end;
- ``parts/*.json``: the rows of each finished task, written as they arrive, each file
  atomically (:mod:`orchestrator.atomic`). This is what survives a killed client (in its
  staging folder); a rerun gathers them and skips every run whose key is there (and
  removes the temporary files a killed client may have left).
- ``results.parquet``: one row per run (role ``run``), rewritten atomically after every
  finished task, sorted by point and seed; ``check.parquet``: the FMU re-runs of the numpy
  engine's sample.
"""
from __future__ import annotations

import json
import math
import uuid
from pathlib import Path
from typing import Any

from ..atomic import temporary_sibling, write_text_atomically

__all__ = ["ResultStore", "write_table", "PARAM_PREFIX", "unfinished_campaign"]

#: a fleet run's tracking figures in its row (orchestrator.analysis.tracking_segments, m and
#: the saturated share): the envelope's verdict is max_error against a tolerance
TRACKING_FIGURES = ("max_error", "max_error_straight", "max_error_turns", "rms_error_straight",
                    "rms_error_turns", "actuator_saturation_fraction")

#: swept parameters get one column each, named by their dotted key after this prefix
PARAM_PREFIX = "param:"


def _json_safe(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, list):
        return [_json_safe(v) for v in value]
    return value


def unfinished_campaign(folder: Path) -> bool:
    """Whether ``folder`` holds a campaign that did not finish (stopped, runs lost or
    missing, or killed before its ``campaign.json``): a rerun's result replaces it."""
    try:
        summary = json.loads((Path(folder) / "campaign.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return (Path(folder) / "parts").is_dir()
    return not isinstance(summary, dict) or bool(summary.get("interrupted_by")
                                                 or summary.get("lost")
                                                 or summary.get("missing"))


class ResultStore:
    """The rows of a campaign's output folder (module docstring).

    Parameters
    ----------
    out : Path
        The output folder (its ``parts/`` is read at once).
    """

    def __init__(self, out: Path):
        self.out = Path(out)
        self.parts = self.out / "parts"
        self.parts.mkdir(parents=True, exist_ok=True)
        self.rows: dict[str, dict[str, Any]] = {}
        # temporary siblings left by a killed client (the lock says no one else writes)
        for stale in [*self.out.glob(".*.part"), *self.parts.glob(".*.part")]:
            stale.unlink(missing_ok=True)
        for part in sorted(self.parts.glob("*.json")):
            try:
                rows = json.loads(part.read_text())
            except (OSError, ValueError):
                continue                  # never written whole (atomic): not a finished task
            for row in rows:
                self.rows[row["run_key"]] = row

    @property
    def done(self) -> set[str]:
        """Keys of the finished runs (an error row is finished: it fails the same way)."""
        return set(self.rows)

    def add(self, rows: list[dict[str, Any]]) -> None:
        """Keep ``rows`` (one task's): a new part file, written atomically.

        Parameters
        ----------
        rows : list[dict[str, Any]]
        """
        if not rows:
            return
        rows = [{k: _json_safe(v) for k, v in r.items()} for r in rows]
        name = f"{rows[0]['point']:06d}-{uuid.uuid4().hex[:12]}.json"
        write_text_atomically(self.parts / name, json.dumps(rows))
        for row in rows:
            self.rows[row["run_key"]] = row

    def table_rows(self, role: str = "run", keys: set[str] | None = None) -> list[dict]:
        """The rows of ``role`` (only ``keys`` if given), sorted by point and seed.

        Parameters
        ----------
        role : str, optional
        keys : set[str], optional

        Returns
        -------
        list[dict]
        """
        rows = [r for r in self.rows.values()
                if r["role"] == role and (keys is None or r["run_key"] in keys)]
        return sorted(rows, key=lambda r: (r["point"], r["seed"]))

    def write(self, keys: set[str] | None = None) -> Path:
        """Write ``results.parquet`` (and ``check.parquet`` if there are check rows).

        Parameters
        ----------
        keys : set[str], optional
            Only these runs (the current campaign's); default every row kept.

        Returns
        -------
        Path
            The results table.
        """
        path = self.out / "results.parquet"
        write_table(self.table_rows("run", keys), path)
        check = self.table_rows("check", keys)
        if check:
            write_table(check, self.out / "check.parquet")
        return path


def _param_columns(rows: list[dict[str, Any]]) -> dict[str, list[Any]]:
    """One column per swept key: its values when all are numbers (as floats), or all
    strings, or all booleans; else their JSON text."""
    params = [json.loads(r["params"]) for r in rows]
    keys: list[str] = []
    for p in params:
        keys += [k for k in p if k not in keys]
    cols = {}
    for k in keys:
        vals = [p.get(k) for p in params]
        present = [v for v in vals if v is not None]
        if present and all(isinstance(v, bool) for v in present):
            cols[k] = vals
        elif present and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                             for v in present):
            cols[k] = [None if v is None else float(v) for v in vals]
        elif all(isinstance(v, str) for v in present):
            cols[k] = vals
        else:
            cols[k] = [None if v is None else json.dumps(v) for v in vals]
    return cols


#: columns in this order first, then the rest as they come
_FIRST = ("point", "seed", "status", "error", "engine", "cost_rate", "predicted_cost_rate",
          "rms_e", "predicted_rms_e", "rms_u", "predicted_rms_u")


def write_table(rows: list[dict[str, Any]], path: Path,
                first: tuple[str, ...] = _FIRST) -> None:
    """Write rows as a Parquet table atomically: one column per swept key (named by the
    key after :data:`PARAM_PREFIX`), then the row's own columns.

    Parameters
    ----------
    rows : list[dict[str, Any]]
    path : Path
    first : tuple[str, ...], optional
        Columns to put first (those the rows have).
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    columns: dict[str, list[Any]] = {f"{PARAM_PREFIX}{k}": v
                                     for k, v in _param_columns(rows).items()}
    have = {k for r in rows for k in r} - {"params"}
    names = [c for c in first if c in have] + sorted(have - set(first))
    for name in names:
        columns[name] = [r.get(name) for r in rows]
    types = {"rms_e": pa.list_(pa.float64()), "rms_u": pa.list_(pa.float64()),
             "mean_e": pa.list_(pa.float64()), "predicted_rms_e": pa.list_(pa.float64()),
             "predicted_rms_u": pa.list_(pa.float64()), "rms_e_mean": pa.list_(pa.float64()),
             "rms_u_mean": pa.list_(pa.float64())}
    float_cols = ("cost_rate", "predicted_cost_rate", "wall_s", "loop_s", "design_s",
                  "build_s", "window_start_s", "T", "h", *TRACKING_FIGURES)
    arrays = {}
    for name, values in columns.items():
        typ = types.get(name) or (pa.float64() if name in float_cols else None)
        if typ is None and all(v is None for v in values):
            typ = pa.string()
        arrays[name] = pa.array(values, type=typ)
    table = pa.table(arrays)
    with temporary_sibling(path) as tmp:
        pq.write_table(table, tmp)
