"""Mean-square stability of the loop over acoustic links: the second-moment radius, its
certificates and the critical loss probability.

Over one message cycle the noise-free second moment of the error coordinates (the loop
without the leader's state, which need not be bounded) evolves by a linear map

    L(X) = G_b (Abar G_a X G_a' Abar' + sum_l p (1 - p) D_l G_a X G_a' D_l') G_b' (...)

the compiled cycle of :mod:`.prediction` (runs G without arrivals, steps with arrivals),
applied to X without ever forming L (n^2 x n^2, 118 000^2 for the centralized formation-4).
L is positive (it keeps X positive semidefinite), so its spectral radius, *the second-moment
radius* rho (per cycle, dimensionless), is an eigenvalue, real, with the largest real part:
the loop is mean-square stable iff rho < 1, and E|e|^2 decays as rho^(t / cycle). Every
radius this module reports is that one; for a deterministic cycle (every message lost)
L(X) = G X G' and rho = rho(G)^2, the square of the state transition's radius.

- :func:`ms_spectral_radius`: rho by Arnoldi iteration on L (scipy's ``eigs`` on a
  LinearOperator, relative tolerance :data:`ARPACK_TOL`);
- :func:`ms_stable`: a verdict by certificate, not by an estimate;
- :func:`frozen_radius`: rho with every message lost;
- :func:`critical_loss`: the loss probability, the same on every link, where rho reaches 1.

Results are kept in the process and on disk (:mod:`.cache`).
"""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import ArpackNoConvergence, LinearOperator, eigs

from .cache import cached
from .cycle import Segment, _Compiler, _product
from .loop import NetworkedLoop

__all__ = ["ARPACK_NCV", "ARPACK_TOL", "SEARCH_MAXITER", "SEARCH_TOL", "VERDICT_MARGIN", "CycleMap",
           "critical_loss", "frozen_radius", "ms_spectral_radius", "ms_stable"]

#: relative tolerance of the Arnoldi estimate of rho (scipy eigs ``tol``: the Ritz residual
#: |L v - rho v| <= tol |rho| |v|)
ARPACK_TOL = 1e-12
#: the same in the critical-loss search, where only rho < 1 or not matters (on formation-4
#: its estimates differ from those to ARPACK_TOL by at most 6e-11)
SEARCH_TOL = 1e-9
#: Arnoldi restarts the search allows at one loss before the certificate decides there
#: (a cluster of eigenvalues near the top converges slowly: formation-4 distributed at 0.9)
SEARCH_MAXITER = 40
#: Krylov vectors per restart (more cost ARPACK more than the matrix-vector products save)
ARPACK_NCV = 20
#: the critical-loss search takes the verdict of the estimate when |rho - 1| exceeds this,
#: 1000 times its tolerance (room for an eigenvalue condition number up to 1000); closer to
#: 1 the certificate (:func:`ms_stable`) decides
VERDICT_MARGIN = 1e-6

Log = Callable[[str], None]


class CycleMap:
    """L: X -> X after one message cycle, noise-free, on the error coordinates (module
    docstring), applied from the compiled cycle of a compiler."""

    def __init__(self, comp: _Compiler):
        self.comp = comp
        self.plan = comp.cycle()
        self.n = comp.keep.size

    def __call__(self, X: np.ndarray) -> np.ndarray:
        """L(X) for a symmetric n x n X."""
        return self.comp.apply(self.plan, X, noise=False, cost=False)[0]

    def radius(self, v0: np.ndarray | None = None, tol: float = ARPACK_TOL,
               maxiter: int = 500, fallback: bool = True) -> tuple[float, np.ndarray | None]:
        """(rho, its eigenvector) by Arnoldi iteration on L over the symmetric matrices,
        n (n + 1) / 2 coordinates (the upper triangle; L keeps X symmetric and its Perron
        eigenvector is symmetric), "largest real part" (which converges where "largest
        magnitude" stalls on the many eigenvalues of nearly equal modulus), from ``v0``
        (default I); without convergence, the growth rate of tr(L^t(I)) over the last 50
        of 400 cycles and no vector.

        Parameters
        ----------
        v0 : np.ndarray or None, optional
            Starting vector, the upper triangle (a nearby loss's eigenvector: a warm start).
        tol : float, optional
            Relative tolerance (scipy eigs ``tol``).
        maxiter : int, optional
            Arnoldi restarts allowed.
        fallback : bool, optional
            Without convergence, the trace's growth rate (else nan).

        Returns
        -------
        tuple[float, np.ndarray | None]
            rho per cycle and the eigenvector's upper triangle (None from the fallback).
        """
        n = self.n
        iu = np.triu_indices(n)

        def full(v: np.ndarray) -> np.ndarray:
            X = np.zeros((n, n))
            X[iu] = v
            return X + np.triu(X, 1).T

        N = iu[0].size
        if N <= 4 * ARPACK_NCV:             # a tiny loop: the operator itself
            Lm = np.column_stack([self(full(e))[iu] for e in np.eye(N)])
            vals, vecs = np.linalg.eig(Lm)
            i = int(np.argmax(vals.real))
            return float(vals[i].real), np.real(vecs[:, i]).copy()
        op = LinearOperator((N, N), matvec=lambda v: self(full(v))[iu], dtype=float)
        start = np.eye(n)[iu] if v0 is None else v0
        try:
            vals, vecs = eigs(op, k=1, which="LR", v0=start, tol=tol, ncv=ARPACK_NCV,
                              maxiter=maxiter)
            return float(vals[0].real), np.real(vecs[:, 0]).copy()
        except ArpackNoConvergence:
            if not fallback:
                return math.nan, None
            X, rates = np.eye(n), []
            for _ in range(400):
                X = self(X)
                t = float(np.trace(X))
                rates.append(t)
                X /= t
            return float(np.exp(np.mean(np.log(rates[-50:])))), None

    def certify(self, max_cycles: int = 4000) -> bool | None:
        """:func:`ms_stable` on this map."""
        Y, log_scale = np.eye(self.n), 0.0        # L^t(I) = exp(log_scale) Y
        for c in range(max_cycles):
            nxt = self(Y)
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


def ms_spectral_radius(net: NetworkedLoop, loss: float | None = None) -> float:
    """The second-moment radius rho per message cycle (module docstring).

    Parameters
    ----------
    net : NetworkedLoop
        The loop.
    loss : float or None, optional
        The same loss probability on every link instead of the links' own.

    Returns
    -------
    float
        rho (below 1: mean-square stable), dimensionless, per cycle.
    """
    memo = net.__dict__.setdefault("_ms_radius", {})    # the summary asks again
    if loss not in memo:
        memo[loss] = cached(
            "ms-radius", net, (loss, ARPACK_TOL),
            lambda: CycleMap(_Compiler(net, loss=loss, error_only=True)).radius()[0])
    return memo[loss]


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
    return CycleMap(_Compiler(net, loss=loss, error_only=True)).certify(max_cycles)


def frozen_radius(net: NetworkedLoop) -> float:
    """The second-moment radius per cycle of the loop with every message lost
    (deterministic: each vehicle on frozen, held or propagated, neighbour data): rho(G)^2,
    G the cycle's state transition on the error coordinates."""
    comp = _Compiler(net, loss=1.0, error_only=True)
    G: np.ndarray | sp.csr_matrix = sp.identity(comp.keep.size, format="csr")
    for s in comp.cycle():
        G = _product(s.G if isinstance(s, Segment) else s.A, G)
    G = G.toarray() if sp.issparse(G) else G
    return float(np.max(np.abs(np.linalg.eigvals(G)))) ** 2


class _Search:
    """Verdicts at losses p for the critical-loss search: the Arnoldi estimate of rho,
    warm-started from the last eigenvector plus I, and the certificate where rho is within
    VERDICT_MARGIN of 1 or the estimate did not converge in SEARCH_MAXITER restarts."""

    def __init__(self, net: NetworkedLoop, max_cycles: int):
        self.base = _Compiler(net, loss=0.0, error_only=True)
        self.base.cycle()                   # its runs without arrivals serve every loss
        self.v0: np.ndarray | None = None
        self.max_cycles = max_cycles
        self.radius: dict[float, float] = {}
        self.certified: set[float] = set()

    def __call__(self, p: float) -> bool | None:
        cmap = CycleMap(self.base.at_loss(p))
        rho, v = cmap.radius(None if self.v0 is None else self._start(cmap.n), SEARCH_TOL,
                             maxiter=SEARCH_MAXITER, fallback=False)
        self.radius[p] = rho
        if v is not None:
            self.v0 = v
            if abs(rho - 1.0) > VERDICT_MARGIN:
                return rho < 1.0
        self.certified.add(p)
        return cmap.certify(self.max_cycles)

    def _start(self, n: int) -> np.ndarray:
        """The last eigenvector plus I, scaled to equal norms. The eigenvector alone spans
        an (almost) invariant subspace: Arnoldi would return its eigenvalue and miss a mode
        that grows with the loss. I has a component along the dominant mode of every
        positive map (<W, I> = tr W > 0 for its positive semidefinite left eigenvector W)."""
        assert self.v0 is not None
        eye = np.eye(n)[np.triu_indices(n)]
        v = self.v0 * (1.0 if np.dot(self.v0, eye) >= 0.0 else -1.0)
        return v / np.linalg.norm(v) + eye / np.linalg.norm(eye)

    def at(self, p: float) -> str:
        """'0.998 at 0.7' (and 'certified' where the certificate decided; 'not estimated'
        where Arnoldi did not converge)."""
        r = self.radius[p]
        return ((f"{r:.6g} at {p:.4g}" if math.isfinite(r) else f"not estimated at {p:.4g}")
                + (" (certified)" if p in self.certified else ""))


def critical_loss(net: NetworkedLoop, tol: float = 0.01,
                  grid: tuple[float, ...] = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9),
                  log: Log | None = None, max_cycles: int = 4000
                  ) -> tuple[float | None, str]:
    """The smallest loss probability p, the same on every link, at which the loop stops
    being mean-square stable (rho(p) = 1): the verdict at 0 and on a grid of p, then a
    bisection between the last stable and the first unstable grid point down to a bracket
    of width ``tol``.

    Each verdict is rho(p) < 1 from the Arnoldi estimate (:class:`CycleMap`, started from
    the previous point's eigenvector plus I) where |rho - 1| > VERDICT_MARGIN, so that the
    estimate's error cannot change it; closer to 1, or without convergence, the
    certificate of :func:`ms_stable` (undecided within ``max_cycles``: the search stops
    there, as it says). Mean-square
    stability need not be monotone in p (with propagating receivers errors can circulate
    at intermediate losses while the loop with every message lost is only marginal), so no
    shortcut through the frozen loop is taken; its second-moment radius is reported.

    Parameters
    ----------
    net : NetworkedLoop
        The loop.
    tol : float, optional
        Width of the final bracket.
    grid : tuple[float, ...], optional
        The losses decided before bisecting.
    log : callable or None, optional
        Told in one line what is computed before it starts (not on a cache hit).
    max_cycles : int, optional
        The certificate's cycles.

    Returns
    -------
    tuple[float | None, str]
        (p, how it was decided); p None when the loop is stable on the whole grid, or not
        stable even without loss, or a point stays undecided (the note says which).
    """
    def compute() -> tuple[float | None, str]:
        if log is not None:
            log(f"searching the critical loss: the second-moment radius over the "
                f"{net.period}-step message cycle ({net.period * net.h:g} s) at losses 0, "
                f"{grid[0]:g}, ..., {grid[-1]:g} and by bisection to {tol:g} (--predict "
                "full) ...")
        return _critical_loss(net, tol, grid, max_cycles)

    out = cached("critical-loss", net, (tol, tuple(grid), max_cycles, SEARCH_TOL, SEARCH_MAXITER,
                                        VERDICT_MARGIN), compute, encode=list,
                 decode=lambda v: (v[0], v[1]))
    return out


def _critical_loss(net: NetworkedLoop, tol: float, grid: tuple[float, ...],
                   max_cycles: int) -> tuple[float | None, str]:
    frozen = (f"with every message lost the second-moment radius is {frozen_radius(net):.6g} "
              "per cycle")
    how = (f"second-moment radius per cycle by Arnoldi iteration (relative tolerance "
           f"{SEARCH_TOL:g}; the certificate where within {VERDICT_MARGIN:g} of 1 or not "
           "converged)")
    verdict = _Search(net, max_cycles)
    at0 = verdict(0.0)
    if at0 is not True:
        return None, ("not mean-square stable without loss" if at0 is False else
                      "undecided without loss (radius close to 1)") + \
            f" (radius {verdict.at(0.0)}); {frozen}"
    lo = 0.0
    for p in grid:
        v = verdict(p)
        if v is None:
            return None, (f"stable up to {lo:g}, undecided at {p:g} (second-moment radius "
                          f"{verdict.at(p)}: close to 1); {how}; {frozen}")
        if not v:
            hi = p
            break
        lo = p
    else:
        est = [r for p, r in verdict.radius.items() if p not in verdict.certified]
        cert = sorted(verdict.certified)
        return None, (f"none up to {grid[-1]:g}: mean-square stable at 0 and at every loss "
                      f"{grid[0]:g}, {grid[1]:g}, ..., {grid[-1]:g} ("
                      + (f"second-moment radius at most {max(est):.6g} per cycle" if est else "")
                      + ("; " if est and cert else "")
                      + ("certified at " + ", ".join(f"{p:g}" for p in cert) if cert else "")
                      + f"); {how}; {frozen}")
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        v = verdict(mid)
        if v is None:
            return mid, (f"radius 1 within the certificates' reach near {mid:.4g} (stable "
                         f"at {lo:.4g}, not at {hi:.4g}; second-moment radius "
                         f"{verdict.at(mid)}); {how}; {frozen}")
        lo, hi = (mid, hi) if v else (lo, mid)
    return 0.5 * (lo + hi), (f"bisection: stable at {lo:.4g}, not at {hi:.4g} (second-moment "
                             f"radius {verdict.at(lo)}, {verdict.at(hi)}); {how}; {frozen}")
