"""Predictions of the loop over acoustic links: expected cost, mean-square stability, the
critical loss probability.

The second moment X2 = E[Z Z'] of :class:`~orchestrator.analysis.acoustic.loop.NetworkedLoop`
evolves exactly as X2+ = Abar X2 Abar' + sum_l p_l (1 - p_l) D_l X2 D_l' + noise, with one
loss term per link arriving at that step. A run of steps without arrivals is an affine map
of X2 with a cost functional, a :class:`Segment` (G, W, S, c)::

    X2 -> G X2 G' + W,   sum of the run's expected step costs = tr(S X2) + c

and two runs compose as G = Gb Ga, W = Gb Wa Gb' + Wb, S = Sa + Ga' Sb Ga,
c = ca + cb + tr(Sb Wa); a run of m equal steps by doubling. Steps with arrivals are
applied as they are. Over the message cycle (the hyperperiod of every link's period) the
sequence repeats, so it is compiled once and a long window costs a few dense products per
cycle.

- :func:`predict_window`: the expected cost rate over samples k0 <= k < K from the known
  start, the statistic a run computes (leader motion and transient included);
- :func:`ms_spectral_radius`: the spectral radius of the cycle map of X2 on the error
  coordinates (the loop without the leader's state, which need not be bounded); below 1 iff
  the loop is mean-square stable;
- :func:`critical_loss`: the loss probability, the same on every link, at which that radius
  reaches 1, or None when it stays below 1 up to loss -> 1.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import ArpackNoConvergence, LinearOperator, eigs

from .loop import NetworkedLoop

__all__ = ["NetworkPrediction", "Segment", "critical_loss", "frozen_radius", "ms_spectral_radius",
           "ms_stable", "predict_window", "prediction_work"]


@dataclass(frozen=True, eq=False)
class Segment:
    """X2 -> G X2 G' + W over a run of deterministic steps; its cost tr(S X2) + c."""

    G: np.ndarray
    W: np.ndarray
    S: np.ndarray
    c: float
    length: int

    def then(self, b: Segment) -> Segment:
        """This run followed by ``b``."""
        GW = b.G @ self.W
        return Segment(G=b.G @ self.G, W=GW @ b.G.T + b.W,
                       S=self.S + self.G.T @ b.S @ self.G,
                       c=self.c + b.c + float(np.sum(b.S * self.W)), length=self.length + b.length)

    def power(self, m: int) -> Segment:
        """m runs in a row, by doubling."""
        return doubled(self, m)


def doubled(seg: Any, m: int) -> Any:
    """m runs of a segment in a row (anything with ``then``), by doubling."""
    out, base = None, seg
    while m:
        if m & 1:
            out = base if out is None else out.then(base)
        m >>= 1
        if m:
            base = base.then(base)
    assert out is not None
    return out


@dataclass(frozen=True, eq=False)
class Event:
    """A step with arrivals: X2 -> Abar X2 Abar' + sum_l p(1 - p) D_l X2 D_l' + noise."""

    A: sp.csr_matrix
    terms: tuple[tuple[float, sp.csr_matrix], ...]
    noise: np.ndarray          #: Gbar W Gbar' + sum_l p(1 - p) D_zeta W D_zeta'


def _sandwich(A: Any, X: np.ndarray) -> np.ndarray:
    """A X A' for a sparse or dense A."""
    AX = A @ X
    return np.asarray((A @ AX.T).T if sp.issparse(A) else AX @ A.T)


class _Compiler:
    """Segments and events of a networked loop, optionally with every link's loss set to p
    and restricted to the error coordinates."""

    def __init__(self, net: NetworkedLoop, loss: float | None = None,
                 error_only: bool = False):
        self.net = net
        self.loss = loss
        keep = ~net.deterministic if error_only else np.ones(net.n, dtype=bool)
        self.keep = np.flatnonzero(keep)
        self.error_only = error_only
        self._cache: dict[Any, Any] = {}
        W = net.form.W
        self.W = W
        k = self.keep
        self.Qz = net.Qz[np.ix_(k, k)]
        self.c0 = 0.0 if error_only else net.c0

    def _restrict(self, M: sp.csr_matrix) -> tuple[sp.csr_matrix, sp.csr_matrix]:
        n = self.net.n
        MZ, Mz = M[:, :n], M[:, n:]
        return MZ[self.keep][:, self.keep].tocsr(), Mz[self.keep].tocsr()

    def step(self, pattern: Any) -> Segment | Event:
        """The map of one transition of the given pattern."""
        if pattern in self._cache:
            return self._cache[pattern]
        A0, D = self.net.matrices(pattern)
        if not D:
            A, Gam = self._restrict(A0)
            Gd = Gam.toarray()
            out: Segment | Event = Segment(
                G=A.toarray(), W=Gd @ self.W @ Gd.T, S=self.Qz.copy(), c=self.c0, length=1)
        else:
            Abar, terms, noise_terms = A0, [], []
            for key, Dl in D.items():
                p = self.net.loss[key] if self.loss is None else self.loss
                Abar = Abar + (1.0 - p) * Dl
                DA, DG = self._restrict(Dl)
                terms.append((p * (1.0 - p), DA))
                if DG.nnz:
                    noise_terms.append((p * (1.0 - p), DG))
            A, Gam = self._restrict(Abar)
            Gd = Gam.toarray()
            noise = Gd @ self.W @ Gd.T
            for c, DG in noise_terms:
                Gl = DG.toarray()
                noise += c * (Gl @ self.W @ Gl.T)
            out = Event(A=A, terms=tuple(terms), noise=noise)
        self._cache[pattern] = out
        return out

    def plan(self, ka: int, kb: int) -> list[Segment | Event]:
        """The maps of transitions ka..kb-1: runs of equal deterministic steps doubled."""
        out: list[Segment | Event] = []
        k = ka
        while k < kb:
            pat = self.net.pattern(k)
            m = 1
            while k + m < kb and self.net.pattern(k + m) == pat:
                m += 1
            s = self.step(pat)
            if not hasattr(s, "then"):                  # a step with arrivals
                out += [s] * m
            else:
                key = (pat, m)
                if key not in self._cache:
                    self._cache[key] = doubled(s, m)
                seg = self._cache[key]
                if out and hasattr(out[-1], "then"):
                    out[-1] = out[-1].then(seg)
                else:
                    out.append(seg)
            k += m
        return out

    def apply(self, plan: Sequence[Segment | Event], X: np.ndarray, noise: bool = True
              ) -> tuple[np.ndarray, float]:
        """X2 after the plan, and the plan's expected cost summed over its steps."""
        cost = 0.0
        for s in plan:
            if isinstance(s, Segment):
                cost += float(np.sum(s.S * X)) + (s.c if noise else 0.0)
                X = s.G @ X @ s.G.T + (s.W if noise else 0.0)
            else:
                cost += float(np.sum(self.Qz * X)) + (self.c0 if noise else 0.0)
                Y = _sandwich(s.A, X) + (s.noise if noise else 0.0)
                for c, DA in s.terms:
                    Y = Y + c * _sandwich(DA, X)
                X = Y
        return X, cost

    def cycle(self) -> list[Segment | Event]:
        """The compiled message cycle after start-up (transitions b..b + period - 1, b the
        first multiple of the period at or after every link's first arrival)."""
        if "cycle" not in self._cache:
            b = self.first_cycle()
            self._cache["cycle"] = self.plan(b, b + self.net.period)
        return self._cache["cycle"]

    def first_cycle(self) -> int:
        P = self.net.period
        return -(-self.net.startup // P) * P


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
        The verdict if already computed (:func:`ms_spectral_radius`).

    Returns
    -------
    NetworkPrediction
        The expected cost rate and the verdict.
    """
    comp = _Compiler(net)
    X = np.outer(Z0, Z0)
    b, P = comp.first_cycle(), net.period
    cost = 0.0
    for ka, kb, counted in _pieces(0, k0, b, P, False) + _pieces(k0, K, b, P, True):
        if ka >= b and (ka - b) % P == 0 and (kb - ka) % P == 0:
            plan, times = comp.cycle(), (kb - ka) // P
        else:
            plan, times = comp.plan(ka, kb), 1
        for _ in range(times):
            X, c = comp.apply(plan, X)
            cost += c if counted else 0.0
    return NetworkPrediction(cost_rate=cost / max(K - k0, 1),
                             spectral_radius=(ms_spectral_radius(net) if spectral_radius
                                              is None else spectral_radius),
                             cycle_s=P * net.h)


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


def ms_spectral_radius(net: NetworkedLoop, loss: float | None = None) -> float:
    """Spectral radius of the cycle map of X2 on the error coordinates (no noise).

    The map is positive (it keeps X2 positive semidefinite), so its dominant eigenvalue is
    real and has the largest real part: Arnoldi iteration (scipy's eigs, "largest real
    part", which converges where "largest magnitude" stalls on the many eigenvalues of
    nearly equal modulus) on vec(X2); if it does not converge, the growth rate of
    tr(L^t(I)) over the last of 400 cycles.

    Parameters
    ----------
    net : NetworkedLoop
        The loop.
    loss : float or None, optional
        The same loss probability on every link instead of the links' own.

    Returns
    -------
    float
        The radius per message cycle (below 1: mean-square stable).
    """
    cache = net.__dict__.setdefault("_ms_radius", {})    # the summary asks again
    if loss not in cache:
        cache[loss] = _ms_radius(net, loss)
    return cache[loss]


def _ms_radius(net: NetworkedLoop, loss: float | None) -> float:
    comp = _Compiler(net, loss=loss, error_only=True)
    cyc = comp.cycle()
    n = comp.keep.size

    def apply(X: np.ndarray) -> np.ndarray:
        return comp.apply(cyc, 0.5 * (X + X.T), noise=False)[0]

    op = LinearOperator((n * n, n * n), matvec=lambda v: apply(v.reshape(n, n)).reshape(-1),
                        dtype=float)
    try:
        vals = eigs(op, k=1, which="LR", v0=np.eye(n).reshape(-1), tol=1e-8,
                    ncv=min(60, n * n - 2), maxiter=100, return_eigenvectors=False)
        return float(np.max(vals.real))
    except ArpackNoConvergence:
        X, rates = np.eye(n), []
        for _ in range(400):
            X = apply(X)
            t = float(np.trace(X))
            rates.append(t)
            X /= t
        return float(np.exp(np.mean(np.log(rates[-50:]))))


def ms_stable(net: NetworkedLoop, loss: float | None = None, max_cycles: int = 4000
              ) -> bool | None:
    """Mean-square stability decided by a certificate, not an eigenvalue estimate.

    Y_t = L^t(I) (L the cycle map on the error coordinates): if lambda_max(Y_T) < 1, then
    X = sum_(t<T) L^t(I) > 0 has L(X) - X = Y_T - I < 0, a Lyapunov certificate (stable);
    if L(Y_T) >= Y_T, then L^k(Y_T) >= Y_T for every k by positivity: the second moment
    never decays (not stable).

    Parameters
    ----------
    net : NetworkedLoop
        The loop.
    loss : float or None, optional
        The same loss probability on every link.
    max_cycles : int, optional
        How many message cycles to try.

    Returns
    -------
    bool or None
        True (stable), False (not), None (undecided within ``max_cycles``: radius close to 1).
    """
    comp = _Compiler(net, loss=loss, error_only=True)
    cyc = comp.cycle()
    Y, log_scale = np.eye(comp.keep.size), 0.0        # L^t(I) = exp(log_scale) Y
    for c in range(max_cycles):
        nxt = comp.apply(cyc, Y, noise=False)[0]
        nxt = 0.5 * (nxt + nxt.T)
        # L(Y) >= Y: the sequence never decays (a certificate of instability); checked
        # only while the trace grows, which it must then
        if np.trace(nxt) >= np.trace(Y) and (
                np.linalg.eigvalsh(nxt - Y)[0] >= -1e-12 * np.trace(Y)):
            return False
        t = float(np.trace(nxt))
        Y, log_scale = nxt / t, log_scale + math.log(t)
        # lambda_max <= trace: the trace decides at once; the eigenvalues every 5 cycles
        scale = math.exp(min(log_scale, 700.0))
        if scale < 1.0 or (c % 5 == 4 and np.linalg.eigvalsh(Y)[-1] * scale < 1.0):
            return True
    return None


def frozen_radius(net: NetworkedLoop) -> float:
    """Spectral radius per cycle of the loop with every message lost (deterministic): each
    vehicle on frozen (held or propagated) neighbour data, on the error coordinates."""
    comp = _Compiler(net, loss=1.0, error_only=True)
    G = np.eye(comp.keep.size)
    for s in comp.cycle():
        G = (s.G if isinstance(s, Segment) else s.A) @ G
    return float(np.max(np.abs(np.linalg.eigvals(G))))


def critical_loss(net: NetworkedLoop, tol: float = 0.01,
                  grid: tuple[float, ...] = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9)
                  ) -> tuple[float | None, str]:
    """The smallest loss probability p, the same on every link, at which the loop stops
    being mean-square stable: certified (:func:`ms_stable`) at 0 and on a grid of p, then
    bisected between the last stable and the first unstable grid point.

    Mean-square stability need not be monotone in p (with propagating receivers errors can
    circulate at intermediate losses while the loop with every message lost is only
    marginal), so no shortcut through the frozen loop is taken; its radius is reported.

    Parameters
    ----------
    net : NetworkedLoop
        The loop.
    tol : float, optional
        Width of the final bracket.
    grid : tuple[float, ...], optional
        The losses certified before bisecting.

    Returns
    -------
    tuple[float | None, str]
        (p, how it was decided); p None when the loop is stable on the whole grid, or not
        stable even without loss, or a point stays undecided (the note says which).
    """
    rf = frozen_radius(net)
    frozen = f"with every message lost the radius is {rf:.6g} per cycle"
    at0 = ms_stable(net, 0.0)
    if at0 is not True:
        return None, ("not mean-square stable without loss" if at0 is False else
                      "undecided without loss (radius close to 1)") + f"; {frozen}"
    lo = 0.0
    for p in grid:
        verdict = ms_stable(net, p)
        if verdict is None:
            return None, (f"certified stable up to {lo:g}, undecided at {p:g} (radius close "
                          f"to 1); {frozen}")
        if not verdict:
            hi = p
            break
        lo = p
    else:
        return None, (f"none up to {grid[-1]:g}: certified mean-square stable at 0 and at "
                      f"every loss {grid[0]:g}, {grid[1]:g}, ..., {grid[-1]:g}; {frozen}")
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        verdict = ms_stable(net, mid)
        if verdict is None:
            return mid, (f"radius 1 within the certificates' reach near {mid:.4g} "
                         f"(stable at {lo:.4g}, not at {hi:.4g}, certified); {frozen}")
        lo, hi = (mid, hi) if verdict else (lo, mid)
    return 0.5 * (lo + hi), (f"bisection: stable at {lo:.4g}, not at {hi:.4g} (both "
                             f"certified); {frozen}")
