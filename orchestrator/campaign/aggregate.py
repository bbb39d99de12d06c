"""The aggregate of a campaign: per design point, the mean over seeds with its confidence
interval, against the prediction.

For the n finished runs of a point with cost rates J_1..J_n (per second):

    mean = sum J_i / n,   s = sqrt(sum (J_i - mean)^2 / (n - 1)),
    CI = mean -/+ t_{0.975, n-1} s / sqrt(n)          (95 %, Student's t)

``predicted_in_ci`` says whether the Lyapunov prediction lies in that interval, and
``rel_error`` = (mean - predicted) / predicted; the RMS of each error and control component
is averaged the same way. ``engines`` names the engine(s) that ran the point.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from .results import PARAM_PREFIX, write_table

__all__ = ["aggregate_rows", "confidence_interval", "write_aggregate"]


def confidence_interval(values: list[float], level: float = 0.95) -> tuple[float, float, float]:
    """Mean and the two-sided Student-t confidence interval of the mean.

    Parameters
    ----------
    values : list[float]
        Samples (at least one).
    level : float, optional
        Confidence level.

    Returns
    -------
    mean, low, high : float
        The interval is (mean, mean) for one sample (nothing to estimate the spread from).
    """
    from scipy.stats import t

    a = np.asarray(values, dtype=float)
    mean = float(a.mean())
    if a.size < 2:
        return mean, mean, mean
    half = float(t.ppf(0.5 + level / 2, a.size - 1) * a.std(ddof=1) / math.sqrt(a.size))
    return mean, mean - half, mean + half


def _mean_list(rows: list[dict[str, Any]], key: str) -> list[float] | None:
    vals = [r[key] for r in rows if r.get(key) is not None]
    if not vals or len({len(v) for v in vals}) != 1:
        return None
    return np.mean(np.asarray(vals, dtype=float), axis=0).tolist()


def aggregate_rows(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per design point (module docstring).

    Parameters
    ----------
    rows : list[dict[str, Any]]
        The runs (results.parquet's rows).

    Returns
    -------
    list[dict[str, Any]]
        ``point``, ``params`` (JSON), ``runs``, ``ok``, ``failed``, ``error`` (the first
        message), ``engines``, ``cost_rate_mean``, ``cost_rate_std``, ``cost_rate_ci_low``,
        ``cost_rate_ci_high``, ``predicted_cost_rate``, ``predicted_in_ci``,
        ``rel_error``, ``rms_e_mean``, ``predicted_rms_e``, ``rms_u_mean``,
        ``predicted_rms_u``, ``wall_s_mean``.
    """
    by_point: dict[int, list[dict[str, Any]]] = {}
    for r in rows:
        by_point.setdefault(r["point"], []).append(r)
    out = []
    for point in sorted(by_point):
        group = by_point[point]
        ok = [r for r in group if r["status"] == "ok"]
        failed = [r for r in group if r["status"] != "ok"]
        agg: dict[str, Any] = {
            "point": point, "params": group[0]["params"], "runs": len(group), "ok": len(ok),
            "failed": len(failed), "error": failed[0]["error"] if failed else None,
            "engines": ",".join(sorted({r["engine"] for r in group})),
            "engine_note": next((r.get("engine_note") for r in group
                                 if r.get("engine_note")), None),
        }
        costs = [r["cost_rate"] for r in ok if r.get("cost_rate") is not None]
        pred = next((r.get("predicted_cost_rate") for r in ok), None)
        if costs:
            mean, lo, hi = confidence_interval(costs)
            std = float(np.std(costs, ddof=1)) if len(costs) > 1 else 0.0
            agg.update(cost_rate_mean=mean, cost_rate_std=std, cost_rate_ci_low=lo,
                       cost_rate_ci_high=hi)
            if pred is not None:
                agg.update(predicted_in_ci=bool(lo <= pred <= hi),
                           rel_error=(mean - pred) / pred if pred else None)
        agg.update(predicted_cost_rate=pred,
                   rms_e_mean=_mean_list(ok, "rms_e"),
                   predicted_rms_e=next((r.get("predicted_rms_e") for r in ok), None),
                   rms_u_mean=_mean_list(ok, "rms_u"),
                   predicted_rms_u=next((r.get("predicted_rms_u") for r in ok), None),
                   wall_s_mean=float(np.mean([r["wall_s"] for r in ok])) if ok else None)
        out.append(agg)
    return out


def write_aggregate(rows: list[dict[str, Any]], out: Path) -> list[dict[str, Any]]:
    """Write ``aggregate.parquet`` (and a readable ``aggregate.csv``) of ``rows``.

    Parameters
    ----------
    rows : list[dict[str, Any]]
        The runs.
    out : Path
        The output folder.

    Returns
    -------
    list[dict[str, Any]]
        The aggregate rows (:func:`aggregate_rows`).
    """
    from ..atomic import write_text_atomically

    agg = aggregate_rows(rows)
    if not agg:
        return agg
    write_table(agg, out / "aggregate.parquet", first=("point", "ok", "failed", "engines"))
    params = [json.loads(a["params"]) for a in agg]
    keys = list(dict.fromkeys(k for p in params for k in p))
    cols = ["point"] + [f"{PARAM_PREFIX}{k}" for k in keys] + [
        "ok", "failed", "engines", "cost_rate_mean", "cost_rate_ci_low", "cost_rate_ci_high",
        "predicted_cost_rate", "predicted_in_ci", "rel_error", "error"]
    lines = [",".join(cols)]
    for a, p in zip(agg, params):
        vals = [a["point"]] + [p.get(k) for k in keys] + [a.get(c) for c in cols[1 + len(keys):]]
        lines.append(",".join("" if v is None else json.dumps(v) if not isinstance(v, float)
                              else repr(v) for v in vals))
    write_text_atomically(out / "aggregate.csv", "\n".join(lines) + "\n")
    return agg
