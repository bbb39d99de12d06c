"""Tracking errors on straight legs and in turns, and how often the actuators saturate.

A sample is *in a turn* when the leader's horizontal course turns faster than
``TURN_RATE`` (0.02 rad/s: a radius under 75 m at 1.5 m/s), from its planned state z:

    v = H_l F z,  a = H_l F^2 z,  chi' = (v_n a_e - v_e a_n) / (v_n^2 + v_e^2)   (rad/s)

Per sample and vehicle the tracking error is |e_i| = |H_l z + d_i - p_i| (m, the
NED position error from the formation slot). Over the statistics window [k0, K):

- ``max_error``: the largest |e_i| of any vehicle (m); ``max_error_straight``,
  ``max_error_turns`` the same on each kind of sample;
- ``rms_error_straight``, ``rms_error_turns``: sqrt(mean |e_i|^2) over vehicles and those
  samples (m);
- ``turn_fraction``: the share of the window's samples in a turn;
- ``actuator_saturation_fraction``: the share of (vehicle, sample) pairs in which some
  actuator command was at or beyond its limit (rpm, rudder, stern planes); None for the
  linear model, which has no actuators.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

__all__ = ["TURN_RATE", "SegmentSums", "leader_turn_rate", "run_segments", "segment_stats",
           "segment_summary"]

#: rad/s: a leader turning faster than this is in a turn
TURN_RATE = 0.02


def leader_turn_rate(z: np.ndarray, F: np.ndarray, H: np.ndarray) -> np.ndarray:
    """chi' (rad/s) per sample of the leader's state trace z (K x l; extra columns, such
    as a formation constant, are ignored), F (l x l, 1/s), H (3 x l, NED position)."""
    l0 = F.shape[0]
    zl = np.asarray(z)[:, :l0]
    v = zl @ (H @ F).T
    a = zl @ (H @ F @ F).T
    speed2 = v[:, 0] ** 2 + v[:, 1] ** 2
    rate = v[:, 0] * a[:, 1] - v[:, 1] * a[:, 0]
    return np.divide(rate, speed2, out=np.zeros_like(rate), where=speed2 > 1e-12)


class SegmentSums:
    """The window's figures (module docstring) accumulated chunk by chunk of window samples
    (:meth:`add`); :meth:`result` gives :func:`segment_stats`' dict. One chunk of the whole
    window gives exactly :func:`segment_stats`; more chunks the same maxima and fractions,
    and the RMS values to rounding."""

    def __init__(self) -> None:
        self.n = 0                                  #: window samples seen
        self.turns = 0                              #: of them in a turn
        self.max = -np.inf                          #: largest |e_i|, m
        #: (largest |e_i|, sum of |e_i|^2, count) on straight samples [0] and turns [1]
        self.parts = [[-np.inf, 0.0, 0], [-np.inf, 0.0, 0]]
        self.sat: np.ndarray | None = None          #: per vehicle, samples saturated
        self.size = 0                               #: |e_i| values seen

    def add(self, e: np.ndarray, turning: np.ndarray,
            saturated: np.ndarray | None = None) -> None:
        """Window samples: tracking errors e (rows x 3 N, m), whether the leader turns
        (rows booleans), saturation (rows x N, 1 at the limit; None: no actuators)."""
        e = np.asarray(e)
        norm = np.linalg.norm(e.reshape(e.shape[0], e.shape[1] // 3, 3), axis=2)  # (rows, N)
        rows = e.shape[0]
        turn = np.asarray(turning, bool)
        if norm.size:
            self.max = max(self.max, float(norm.max()))
        for part, mask in zip(self.parts, (~turn, turn)):
            if mask.any():
                sel = norm[mask]
                part[0] = max(part[0], float(sel.max()))
                part[1] += np.sum(sel ** 2)
                part[2] += sel.size
        self.turns += int(np.count_nonzero(turn))
        self.n += rows
        self.size += norm.size
        if saturated is not None:
            at = np.count_nonzero(np.asarray(saturated) > 0.5, axis=0)
            self.sat = at if self.sat is None else self.sat + at

    def result(self) -> dict[str, Any]:
        """The keys of the module docstring."""
        (max_s, sum_s, n_s), (max_t, sum_t, n_t) = self.parts
        out: dict[str, Any] = {
            "max_error": self.max if self.size else None,
            "max_error_straight": max_s if n_s else None,
            "max_error_turns": max_t if n_t else None,
            "rms_error_straight": float(np.sqrt(sum_s / n_s)) if n_s else None,
            "rms_error_turns": float(np.sqrt(sum_t / n_t)) if n_t else None,
            "turn_fraction": self.turns / self.n if self.n else None,
            "actuator_saturation_fraction": None,
        }
        if self.sat is not None:
            out["actuator_saturation_fraction"] = float(self.sat.sum() / (self.n * self.sat.size))
            out["actuator_saturation_fraction_per_vehicle"] = (self.sat / self.n).tolist()
        return out


def segment_stats(e: np.ndarray, turning: np.ndarray, k0: int,
                  saturated: np.ndarray | None = None) -> dict[str, Any]:
    """The window's figures (module docstring) of one run: :class:`SegmentSums` over the
    window at once.

    Parameters
    ----------
    e : np.ndarray
        Tracking errors, K x 3 N (NED per vehicle), m.
    turning : np.ndarray
        K booleans: the leader is in a turn.
    k0 : int
        First sample of the window.
    saturated : np.ndarray or None, optional
        K x N, 1 where a vehicle's actuator command was at its limit (None: no actuators).

    Returns
    -------
    dict[str, Any]
        The keys of the module docstring.
    """
    sums = SegmentSums()
    sums.add(np.asarray(e)[k0:], np.asarray(turning, bool)[k0:],
             None if saturated is None else np.asarray(saturated)[k0:])
    return sums.result()


def force_saturation(u: np.ndarray, u_max: Sequence[Sequence[float]],
                     prior: np.ndarray | None = None) -> np.ndarray:
    """(K, N) 1 where vehicle i's commanded force is at its limit on some axis,
    |u_a| >= u_max_a (1 - 1e-9) (the controllers clip at u_max), or-ed with ``prior`` (the
    vehicles' own actuator saturation, when they report it).

    Parameters
    ----------
    u : np.ndarray
        The stacked force, (K, sum of the vehicles' inputs), N.
    u_max : sequence of sequences
        Per vehicle its limit per axis, N.
    prior : np.ndarray or None
        (K, N) saturation already known, or None.
    """
    cols, start = [], 0
    for lim in u_max:
        m = len(lim)
        at = np.abs(u[:, start:start + m]) >= np.asarray(lim, float) * (1.0 - 1e-9)
        cols.append(at.any(axis=1))
        start += m
    sat = np.column_stack(cols).astype(float)
    return sat if prior is None else np.maximum(sat, np.asarray(prior) > 0.5)


def segment_summary(per_seed: list[dict[str, Any]]) -> dict[str, Any]:
    """Over seeds: the largest maximum, the RMS of the RMS values, the mean fractions."""
    out: dict[str, Any] = {}
    for key in per_seed[0]:
        vals = [s[key] for s in per_seed if s[key] is not None]
        if not vals:
            out[key] = None
        elif key.startswith("max_error"):
            out[key] = float(max(vals))
        elif key.startswith("rms_error"):
            out[key] = float(np.sqrt(np.mean(np.square(vals))))
        elif key.endswith("per_vehicle"):
            out[key] = np.mean(np.array(vals), axis=0).tolist()
        else:
            out[key] = float(np.mean(vals))
    return out


def run_segments(leader: Mapping[str, Any], traces: Mapping[str, np.ndarray], k0: int
                 ) -> dict[str, Any]:
    """:func:`segment_stats` of one fleet run: errors from the stacked ``e``, turns from
    the leader's ``z`` (``leader``: the fleet spec's F and H), saturation from the
    vehicles' ``saturated`` outputs when they have actuators."""
    turning = np.abs(leader_turn_rate(traces["z"], np.asarray(leader["F"], float),
                                      np.asarray(leader["H"], float))) > TURN_RATE
    return segment_stats(traces["e"], turning, k0, traces.get("saturated"))
