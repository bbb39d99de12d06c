"""Formation figures of a fleet run: how well each communication edge keeps its offset, and
how close two vehicles came.

With p_i[k] the NED position of vehicle i (m) and delta_i its formation offset from the
leader (m):

- formation error of the edge j -> i: ||(p_i - p_j) - (delta_i - delta_j)||, its RMS over
  the statistics window k0 <= k < K (m);
- separation: min over k and over pairs i < j of ||p_i - p_j|| over the whole run (m), with
  the pair and the time: a safety figure, so the start-up transient counts.
"""
from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["formation_stats", "formation_summary"]

_CHUNK = 256          # time steps per block of the all-pairs distance computation


def formation_stats(x: np.ndarray, position_index: np.ndarray, offsets: np.ndarray,
                    edges: Any, k0: int, h: float) -> dict[str, Any]:
    """Formation figures of one run (module docstring).

    Parameters
    ----------
    x : np.ndarray
        Stacked vehicle states, shape (steps, n).
    position_index : np.ndarray
        (N, 3) int: the columns of x holding vehicle i's north, east, down position.
    offsets : np.ndarray
        (N, 3): formation offsets delta_i, m.
    edges : Any
        Communication edges (j, i), 1-based: vehicle i hears vehicle j.
    k0 : int
        First sample of the statistics window.
    h : float
        Sampling period, s (for the time of the closest approach).

    Returns
    -------
    dict[str, Any]
        ``formation_error_rms`` (edge "j->i" -> RMS, m), ``formation_error_rms_max`` (m),
        ``min_separation`` (m), ``min_separation_vehicles`` ([i, j], 1-based) and
        ``min_separation_time_s``.
    """
    idx = np.asarray(position_index, dtype=np.int64)
    off = np.asarray(offsets, dtype=float)
    pos = x[:, idx]                                           # (steps, N, 3)
    window = pos[k0:]
    rms = {}
    for j, i in edges:
        rel = window[:, i - 1] - window[:, j - 1] - (off[i - 1] - off[j - 1])
        rms[f"{j}->{i}"] = float(np.sqrt(np.mean(np.sum(rel * rel, axis=1))))
    N = idx.shape[0]
    best, where = np.inf, (0, 1, 0)
    if N >= 2:
        # per block the squared distances of every ordered pair, one coordinate at a time
        # (contiguous (b, N, N) arrays; summed in the order north, east, down as before),
        # i >= j masked, and the square root of the minimum alone (it is increasing: the
        # same pair, time and value, first in (k, i, j) order)
        not_pair = np.tril(np.ones((N, N), dtype=bool))
        coords = np.ascontiguousarray(np.moveaxis(pos, 2, 0))     # (3, steps, N)
        for a in range(0, pos.shape[0], _CHUNK):
            d2 = np.zeros((min(_CHUNK, pos.shape[0] - a), N, N))
            for c in range(3):
                blk = coords[c, a:a + _CHUNK]
                d = blk[:, :, None] - blk[:, None, :]
                d *= d
                d2 += d
            d2[:, not_pair] = np.inf
            k, i, j = np.unravel_index(np.argmin(d2), d2.shape)
            if np.sqrt(d2[k, i, j]) < best:
                best, where = float(np.sqrt(d2[k, i, j])), (int(i), int(j), a + int(k))
    return {
        "formation_error_rms": rms,
        "formation_error_rms_max": max(rms.values()) if rms else None,
        "min_separation": None if N < 2 else best,
        "min_separation_vehicles": None if N < 2 else [where[0] + 1, where[1] + 1],
        "min_separation_time_s": None if N < 2 else where[2] * h,
    }


def formation_summary(per_seed: list[dict[str, Any]], seeds: list[int]) -> dict[str, Any]:
    """The formation figures over seeds: the mean RMS per edge, the closest approach of all.

    Parameters
    ----------
    per_seed : list[dict[str, Any]]
        :func:`formation_stats` of each seed.
    seeds : list[int]
        The seeds, in the same order.

    Returns
    -------
    dict[str, Any]
        ``formation_error_rms`` (edge -> mean over seeds, m), ``formation_error_rms_max``,
        and ``min_separation``: {``m``, ``vehicles``, ``time_s``, ``seed``}.
    """
    edges = list(per_seed[0]["formation_error_rms"])
    rms = {e: float(np.mean([s["formation_error_rms"][e] for s in per_seed])) for e in edges}
    out: dict[str, Any] = {"formation_error_rms": rms,
                           "formation_error_rms_max": max(rms.values()) if rms else None}
    closest = [(s["min_separation"], k) for k, s in enumerate(per_seed)
               if s["min_separation"] is not None]
    if closest:
        d, k = min(closest)
        s = per_seed[k]
        out["min_separation"] = {"m": d, "vehicles": s["min_separation_vehicles"],
                                 "time_s": s["min_separation_time_s"], "seed": int(seeds[k])}
    else:
        out["min_separation"] = None
    return out
