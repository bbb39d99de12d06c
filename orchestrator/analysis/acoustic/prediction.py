"""Predictions of the loop over acoustic links: the expected cost over a window.

The second moment X2 = E[Z Z'] of :class:`~orchestrator.analysis.acoustic.loop.NetworkedLoop`
is propagated through the message cycle compiled by :mod:`.cycle` (runs of steps without
arrivals as affine maps with their cost, :class:`~.cycle.Segment`; steps with arrivals as
they are), so a long window costs a few products per cycle.

- :func:`predict_window`: the expected cost rate over samples k0 <= k < K from the known
  start, the statistic a run computes (leader motion and transient included), with the
  second-moment radius of :mod:`.stability` beside it;
- :func:`prediction_work`: what the dense propagation would cost, to choose
  :mod:`.blocks` for many links.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .cache import cached
from .cycle import _Compiler
from .loop import NetworkedLoop
from .stability import ms_spectral_radius

__all__ = ["NetworkPrediction", "predict_window", "prediction_work", "window_cost"]

@dataclass(frozen=True)
class NetworkPrediction:
    """Expected cost rate over a window from the known start, and the stability verdict."""

    cost_rate: float
    spectral_radius: float          #: of the cycle map of X2 on the error coordinates
    cycle_s: float                  #: the message cycle (hyperperiod), s


def predict_window(net: NetworkedLoop, Z0: np.ndarray, k0: int, K: int,
                   spectral_radius: float | None = None) -> NetworkPrediction:
    """E[J] / (K - k0) over samples k0 <= k < K from Z(0) = Z0 (module docstring).

    Parameters
    ----------
    net : NetworkedLoop
        The loop.
    Z0 : np.ndarray
        Its initial state (:meth:`NetworkedLoop.initial_state`).
    k0, K : int
        The window.
    spectral_radius : float or None, optional
        The verdict if already computed (:func:`.stability.ms_spectral_radius`).

    Returns
    -------
    NetworkPrediction
        The expected cost rate and the verdict (the cost kept in :mod:`.cache`).
    """
    cost = cached("window", net, (np.asarray(Z0, float), int(k0), int(K)),
                  lambda: _window_cost(net, Z0, k0, K))
    if spectral_radius is None:
        spectral_radius = ms_spectral_radius(net)
    return NetworkPrediction(cost_rate=cost, spectral_radius=spectral_radius,
                             cycle_s=net.period * net.h)


def _window_cost(net: NetworkedLoop, Z0: np.ndarray, k0: int, K: int) -> float:
    """E[J] / (K - k0): X2 propagated from Z0 Z0' through the compiled plans."""
    comp = _Compiler(net)
    return window_cost(np.outer(Z0, Z0), k0, K, comp.first_cycle(), net.period,
                       comp.cycle, comp.plan, comp.apply)


def window_cost(M: Any, k0: int, K: int, b: int, P: int, cycle: Callable[[], Any],
                plan: Callable[[int, int], Any],
                apply: Callable[[Any, Any], tuple[Any, float]]) -> float:
    """E[J] / (K - k0) over samples k0 <= k < K: the moment ``M`` at k = 0 carried through
    [0, K) split at the cycle boundaries b + m P (:func:`_pieces`), each whole run of
    cycles as ``cycle()`` applied once per cycle, every other piece as ``plan(ka, kb)``;
    ``apply(plan, M)`` returns the next moment and the piece's expected cost, summed over
    the pieces inside the window. Every propagation (dense, in blocks, bursty) shares it.
    """
    cost = 0.0
    for ka, kb, counted in _pieces(0, k0, b, P, False) + _pieces(k0, K, b, P, True):
        if ka >= b and (ka - b) % P == 0 and (kb - ka) % P == 0:
            step, times = cycle(), (kb - ka) // P
        else:
            step, times = plan(ka, kb), 1
        for _ in range(times):
            M, c = apply(step, M)
            cost += c if counted else 0.0
    return cost / max(K - k0, 1)


def prediction_work(net: NetworkedLoop, K: int, blocks: bool = False) -> float:
    """Floating-point operations the window prediction takes, roughly: per message cycle
    four products per run and per arrival step (dense: n^3 each; in blocks: nc nR^2), and
    the cycles of K steps (a period of one step makes every step an arrival)."""
    steps = [net.pattern(k) for k in range(net.startup, net.startup + net.period)]
    events = sum(bool(p[1]) for p in steps)
    runs = sum(1 for a, b in zip(steps, steps[1:] + steps[:1]) if a != b) or 1
    nc = min((sl.start for sl in net.R.values()), default=net.n)
    size = nc * (net.n - nc) ** 2 + nc ** 3 if blocks else float(net.n) ** 3
    return 4.0 * size * (events + runs) * (K / net.period + 1)


def _pieces(ka: int, kb: int, b: int, P: int, counted: bool) -> list[tuple[int, int, bool]]:
    """[ka, kb) split at the cycle boundaries b + m P: a head, whole cycles, a tail."""
    if ka >= kb:
        return []
    first = b if ka <= b else b + -(-(ka - b) // P) * P
    if first >= kb:
        return [(ka, kb, counted)]
    whole = first + ((kb - first) // P) * P
    return [p for p in ((ka, first, counted), (first, whole, counted), (whole, kb, counted))
            if p[0] < p[1]]
