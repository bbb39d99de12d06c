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

__all__ = ["FormationSums", "formation_stats", "formation_summary"]

_CHUNK = 256          # time steps per block of the all-pairs distance computation


class FormationSums:
    """The formation figures of a run (module docstring) accumulated chunk by chunk of
    samples (:meth:`add`); :meth:`result` gives :func:`formation_stats`' dict. One chunk
    of the whole run gives exactly :func:`formation_stats`; more chunks the same maxima
    and closest approach, and the RMS values to rounding.

    Parameters
    ----------
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
    """

    def __init__(self, position_index: np.ndarray, offsets: np.ndarray, edges: Any, k0: int,
                 h: float):
        self.idx = np.asarray(position_index, dtype=np.int64)
        self.off = np.asarray(offsets, dtype=float)
        self.edges = [(int(j), int(i)) for j, i in edges]
        self.k0, self.h = int(k0), float(h)
        self.sums = np.zeros(len(self.edges))      #: sum over the window of |rel|^2, m^2
        self.n = 0                                 #: window samples seen
        self.best, self.where = np.inf, (0, 1, 0)  #: closest approach so far (m; i, j, k)

    def add(self, start: int, x: np.ndarray) -> None:
        """Samples start .. start + len(x) - 1 of the stacked vehicle states x."""
        pos = x[:, self.idx]                                      # (rows, N, 3)
        window = pos[max(0, self.k0 - start):]
        if window.shape[0]:
            for c, (j, i) in enumerate(self.edges):
                rel = window[:, i - 1] - window[:, j - 1] - (self.off[i - 1] - self.off[j - 1])
                self.sums[c] += np.sum(np.sum(rel * rel, axis=1))
            self.n += window.shape[0]
        if self.idx.shape[0] >= 2 and pos.shape[0]:
            self.best, self.where = _closest_approach(np.ascontiguousarray(pos), start,
                                                      self.best, self.where)

    def result(self) -> dict[str, Any]:
        """The figures (:func:`formation_stats`)."""
        rms = {f"{j}->{i}": float(np.sqrt(s / self.n))
               for (j, i), s in zip(self.edges, self.sums)}
        two = self.idx.shape[0] >= 2
        return {
            "formation_error_rms": rms,
            "formation_error_rms_max": max(rms.values()) if rms else None,
            "min_separation": self.best if two else None,
            "min_separation_vehicles": [self.where[0] + 1, self.where[1] + 1] if two else None,
            "min_separation_time_s": self.where[2] * self.h if two else None,
        }


def formation_stats(x: np.ndarray, position_index: np.ndarray, offsets: np.ndarray,
                    edges: Any, k0: int, h: float) -> dict[str, Any]:
    """Formation figures of one run (module docstring): :class:`FormationSums` (its
    parameters) over the whole run at once, ``x`` the stacked vehicle states, shape
    (steps, n).

    Returns
    -------
    dict[str, Any]
        ``formation_error_rms`` (edge "j->i" -> RMS, m), ``formation_error_rms_max`` (m),
        ``min_separation`` (m), ``min_separation_vehicles`` ([i, j], 1-based) and
        ``min_separation_time_s``.
    """
    sums = FormationSums(position_index, offsets, edges, k0, h)
    sums.add(0, x)
    return sums.result()


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


def _closest_approach(pos: np.ndarray, start: int = 0, best: float = np.inf,
                      where: tuple[int, int, int] = (0, 1, 0)
                      ) -> tuple[float, tuple[int, int, int]]:
    """The smallest distance between two vehicles over the run, its pair (i < j, 0-based)
    and sample: the first in (k, i, j) order. ``pos`` may be a chunk of the run, from
    sample ``start``, after chunks whose closest approach was ``best`` at ``where``: the
    result is then the run's so far (a tie keeps the earlier sample).

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
            best, where = (float(np.sqrt(d2[k, q])),
                           (int(pi[q]), int(pj[q]), start + a + int(k)))
    return best, where
