"""The networked loop's second moment compiled over its message cycle (the core that
:mod:`.prediction` and :mod:`.stability` share).

The second moment X2 = E[Z Z'] of :class:`~orchestrator.analysis.acoustic.loop.NetworkedLoop`
evolves exactly as X2+ = Abar X2 Abar' + sum_l p_l (1 - p_l) D_l X2 D_l' + noise, with one
loss term per link arriving at that step. A run of steps without arrivals is an affine map
of X2 with a cost functional, a :class:`Segment` (G, W, S, c)::

    X2 -> G X2 G' + W,   sum of the run's expected step costs = tr(S X2) + c

and two runs compose as G = Gb Ga, W = Gb Wa Gb' + Wb, S = Sa + Ga' Sb Ga,
c = ca + cb + tr(Sb Wa); a run of m equal steps by doubling. Steps with arrivals
(:class:`Event`) are applied as they are. Between arrivals each vehicle runs on its own, so
G is kept sparse when it is (:data:`SPARSE_DENSITY`), and a link's loss term D_l X2 D_l'
(:class:`LossTerm`) is applied on the rows of its receiver's held value and the few columns
D_l reads.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

from .loop import NetworkedLoop

__all__ = ["Event", "LossTerm", "SPARSE_DENSITY", "Segment", "doubled"]

#: a run's G (and an arrival step's A) is kept as a sparse matrix up to this fraction of
#: non-zero entries, dense above
SPARSE_DENSITY = 0.1

Matrix = np.ndarray | sp.csr_matrix


def _compact(G: Matrix) -> Matrix:
    """G sparse (CSR) when at most SPARSE_DENSITY of its entries are non-zero, else dense."""
    n = G.shape[0] * G.shape[1]
    if sp.issparse(G):
        return G.tocsr() if G.nnz <= SPARSE_DENSITY * n else G.toarray()
    nnz = np.count_nonzero(G)
    return sp.csr_matrix(G) if nnz <= SPARSE_DENSITY * n else G


def _product(A: Matrix, B: Matrix) -> Matrix:
    """A B for sparse or dense factors, compacted."""
    if sp.issparse(A) and sp.issparse(B):
        return _compact(A @ B)
    if sp.issparse(A) or sp.issparse(B):
        return _compact(np.asarray(A @ B))
    return _compact(A @ B)


@dataclass(frozen=True, eq=False)
class Segment:
    """X2 -> G X2 G' + W over a run of deterministic steps; its cost tr(S X2) + c."""

    G: np.ndarray
    W: np.ndarray
    S: np.ndarray
    c: float
    length: int

    def then(self, b: Segment) -> Segment:
        """This run followed by ``b`` (G sparse or dense, W and S dense)."""
        Gt = self.G.T.tocsr() if sp.issparse(self.G) else self.G.T
        return Segment(G=_product(b.G, self.G), W=_sandwich(b.G, self.W) + b.W,
                       S=self.S + _sandwich(Gt, b.S),
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
class LossTerm:
    """One link's p(1 - p) D_l X2 D_l' on the few rows and columns D_l has: D_l = V on
    (rows, cols), zero elsewhere."""

    c: float                   #: p (1 - p)
    D: sp.csr_matrix           #: D_l on the coordinates kept
    rows: np.ndarray
    cols: np.ndarray
    V: np.ndarray              #: D_l[rows][:, cols]

    def __post_init__(self) -> None:
        object.__setattr__(self, "_ix", (np.ix_(self.cols, self.cols),
                                         np.ix_(self.rows, self.rows)))

    @classmethod
    def of(cls, c: float, D: sp.csr_matrix) -> LossTerm:
        D = D.tocsr()
        D.eliminate_zeros()
        rows = np.unique(D.nonzero()[0])
        cols = np.unique(D.indices)
        return cls(c=c, D=D, rows=rows, cols=cols, V=D[rows][:, cols].toarray())

    def add_to(self, Y: np.ndarray, X: np.ndarray) -> None:
        """Y += p (1 - p) D_l X D_l' (in place)."""
        if self.rows.size:
            ixc, ixr = self._ix                    # type: ignore[attr-defined]
            Y[ixr] += self.c * (self.V @ X[ixc] @ self.V.T)


@dataclass(frozen=True, eq=False)
class Event:
    """A step with arrivals: X2 -> Abar X2 Abar' + sum_l p(1 - p) D_l X2 D_l' + noise."""

    A: Matrix
    terms: tuple[LossTerm, ...]
    noise: np.ndarray          #: Gbar W Gbar' + sum_l p(1 - p) D_zeta W D_zeta'


def _sandwich(A: Matrix, X: np.ndarray) -> np.ndarray:
    """A X A' (C-contiguous) for a sparse or dense A and a dense X."""
    if not sp.issparse(A):
        return A @ X @ A.T
    AX = np.asarray(A @ np.ascontiguousarray(X))
    return np.ascontiguousarray(np.asarray(A @ np.ascontiguousarray(AX.T)).T)


class _Compiler:
    """Segments and events of a networked loop, optionally with every link's loss set to p
    and restricted to the error coordinates."""

    def __init__(self, net: NetworkedLoop, loss: float | dict[Any, float] | None = None,
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

    def loss_of(self, key: Any) -> float:
        """The mean loss of link ``key`` this compiler uses: the loop's, the one given for
        every link, or the link's own from a mapping."""
        if self.loss is None:
            return self.net.loss[key]
        return float(self.loss[key]) if isinstance(self.loss, dict) else float(self.loss)

    def at_loss(self, loss: float) -> _Compiler:
        """The same loop with every link's loss set to ``loss``: the runs without arrivals
        (which do not depend on it) are taken from this compiler, not compiled again."""
        out = _Compiler.__new__(_Compiler)
        out.__dict__.update(self.__dict__)
        out.loss = loss
        out._cache = {k: v for k, v in self._cache.items() if isinstance(v, Segment)}
        return out

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
                G=_compact(A), W=Gd @ self.W @ Gd.T, S=self.Qz.copy(), c=self.c0, length=1)
        else:
            Abar, terms, noise_terms = A0, [], []
            for key, Dl in D.items():
                p = self.loss_of(key)
                Abar = Abar + (1.0 - p) * Dl
                DA, DG = self._restrict(Dl)
                terms.append(LossTerm.of(p * (1.0 - p), DA))
                if DG.nnz:
                    noise_terms.append((p * (1.0 - p), DG))
            A, Gam = self._restrict(Abar)
            Gd = Gam.toarray()
            noise = Gd @ self.W @ Gd.T
            for c, DG in noise_terms:
                Gl = DG.toarray()
                noise += c * (Gl @ self.W @ Gl.T)
            out = Event(A=_compact(A), terms=tuple(terms), noise=noise)
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

    def apply(self, plan: Sequence[Segment | Event], X: np.ndarray, noise: bool = True,
              cost: bool = True) -> tuple[np.ndarray, float]:
        """X2 after the plan, and the plan's expected cost summed over its steps (0 without
        ``cost``)."""
        total = 0.0
        for s in plan:
            if isinstance(s, Segment):
                if cost:
                    total += float(np.sum(s.S * X)) + (s.c if noise else 0.0)
                X = _sandwich(s.G, X) + (s.W if noise else 0.0)
            else:
                if cost:
                    total += float(np.sum(self.Qz * X)) + (self.c0 if noise else 0.0)
                Y = _sandwich(s.A, X) + (s.noise if noise else 0.0)
                for term in s.terms:
                    term.add_to(Y, X)
                X = Y
        return X, total

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
