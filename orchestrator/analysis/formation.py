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
        best, where = _closest_approach(np.ascontiguousarray(pos))
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


def _closest_approach(pos: np.ndarray) -> tuple[float, tuple[int, int, int]]:
    """The smallest distance between two vehicles over the run, its pair (i < j, 0-based)
    and sample: the first in (k, i, j) order.

    Block by block of :data:`_CHUNK` samples. A pair (i, j) cannot come closer within a
    block than its distance at the block's first sample less how far each vehicle moves
    from there in the block, d_ij(a) - r_i - r_j; only the pairs whose bound is not above
    the closest approach so far are measured sample by sample (the first block: every
    pair). Squared distances summed north, east, down, the square root of the minimum
    alone: the same value, pair and sample as measuring every pair at every sample.

    Parameters
    ----------
    pos : np.ndarray
        (steps, N, 3) positions, m.

    Returns
    -------
    tuple[float, tuple[int, int, int]]
        The distance (m) and (i, j, k).
    """
    steps, N, _ = pos.shape
    iu, ju = np.triu_indices(N, k=1)                 # the pairs i < j in (i, j) order
    best, where = np.inf, (0, 1, 0)
    for a in range(0, steps, _CHUNK):
        blk = pos[a:a + _CHUNK]
        moved = np.sqrt(np.max(np.sum((blk - blk[0]) ** 2, axis=2), axis=0))     # (N,)
        d0 = np.sqrt(np.sum((blk[0, iu] - blk[0, ju]) ** 2, axis=1))
        bound = d0 - moved[iu] - moved[ju]
        # a margin of rounding: a pair is dropped only when clearly farther than the best
        near = np.flatnonzero(bound <= best + 1e-9 * (1.0 + best))
        if near.size == 0:
            continue
        pi, pj = iu[near], ju[near]
        d2 = np.zeros((blk.shape[0], near.size))
        for c in range(3):
            d = blk[:, pi, c] - blk[:, pj, c]
            d *= d
            d2 += d
        k, q = np.unravel_index(np.argmin(d2), d2.shape)
        if np.sqrt(d2[k, q]) < best:
            best, where = float(np.sqrt(d2[k, q])), (int(pi[q]), int(pj[q]), a + int(k))
    return best, where
