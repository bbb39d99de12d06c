"""The second moment of a networked loop with many links, kept in blocks.

:mod:`.prediction` propagates X2 = E[Z Z'] as one dense matrix, n^3 per product.
With many links (the centralized law over all-to-all links: formation-20 has 400 links of
12 values, 5271 states) most of Z is the receivers' held values R, and a step treats them
simply: between arrivals R <- M R, block-diagonal (one M per link), and nothing else
reaches R. Split Z = [c; R] (c: the loop and the messages in flight): a run of steps
without arrivals is then

    G = [[Gcc, GcR], [0, GRR]],  GRR block-diagonal,  noise only in c,

so G X2 G' costs nc nR^2 instead of n^3 (nc ~ 700 against n ~ 5300), and arrival steps
(R_l <- M (R_l + delta (F - R_l))) are applied block by block with sparse A. The results
are those of the dense propagation (a test compares them on formation-4).
"""
from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

from .cache import cached
from .cycle import _Compiler, doubled
from .loop import NetworkedLoop
from .prediction import NetworkPrediction, window_cost

__all__ = ["predict_window_blocks"]

Blocks = tuple[np.ndarray, np.ndarray, np.ndarray]      # (Xcc, XcR, XRR), X symmetric


@dataclass(frozen=True, eq=False)
class BlockSegment:
    """A run of steps without arrivals: X -> G X G' + W (W only in cc), cost tr(S X) + c."""

    Gcc: np.ndarray
    GcR: np.ndarray
    GRR: sp.csr_matrix
    Wcc: np.ndarray
    S: Blocks
    c: float
    length: int

    def then(self, b: BlockSegment) -> BlockSegment:
        """This run followed by ``b`` (module docstring; S = Sa + Ga' Sb Ga)."""
        Scc, ScR, SRR = b.S
        GRRt = self.GRR.T.tocsr()
        SG_c = Scc @ self.Gcc                               # Sb_cc Ga_cc
        SG_R = Scc @ self.GcR + np.asarray((GRRt @ ScR.T).T)  # Sb_cc GcR + Sb_cR GRR
        S = (self.S[0] + self.Gcc.T @ SG_c,
             self.S[1] + self.Gcc.T @ SG_R,
             self.S[2] + self.GcR.T @ SG_R
             + np.asarray(GRRt @ (ScR.T @ self.GcR + np.asarray((GRRt @ SRR.T).T))))
        return BlockSegment(
            Gcc=b.Gcc @ self.Gcc,
            GcR=b.Gcc @ self.GcR + np.asarray((self.GRR.T @ b.GcR.T).T),
            GRR=(b.GRR @ self.GRR).tocsr(),
            Wcc=b.Gcc @ self.Wcc @ b.Gcc.T + b.Wcc, S=S,
            c=self.c + b.c + float(np.sum(Scc * self.Wcc)), length=self.length + b.length)

    def power(self, m: int) -> BlockSegment:
        """m runs in a row, by doubling."""
        return doubled(self, m)


@dataclass(frozen=True, eq=False)
class BlockEvent:
    """A step with arrivals, as sparse blocks; per link (p(1 - p), the rows of D_l on the
    few columns they touch, those columns, the link's slice)."""

    A: sp.csr_matrix
    terms: tuple[tuple[float, np.ndarray, np.ndarray, slice], ...]
    noise: tuple[np.ndarray | None, ...]                  #: (cc, cR, RR), None: zero


def _dot(a: np.ndarray, b: np.ndarray) -> float:
    """sum(a * b) without a temporary (both C-contiguous)."""
    return float(np.vdot(np.ascontiguousarray(a), np.ascontiguousarray(b)))


def _sym_cost(S: Blocks, X: Blocks) -> float:
    """tr(S X) of two symmetric matrices in blocks."""
    return _dot(S[0], X[0]) + 2.0 * _dot(S[1], X[1]) + _dot(S[2], X[2])


def _right(A: sp.csr_matrix, Y: np.ndarray) -> np.ndarray:
    """Y A' for a sparse A, without scipy copying a transposed operand per call."""
    return np.ascontiguousarray((A @ np.ascontiguousarray(Y.T)).T)


class _Lookup:
    """Sub-matrices X[cols, cols] of a symmetric matrix kept in blocks."""

    def __init__(self, X: Blocks, nc: int):
        self.X, self.nc = X, nc

    def sub(self, cols: np.ndarray) -> np.ndarray:
        c, r = cols[cols < self.nc], cols[cols >= self.nc] - self.nc
        Xcc, XcR, XRR = self.X
        return np.block([[Xcc[np.ix_(c, c)], XcR[np.ix_(c, r)]],
                         [XcR[np.ix_(c, r)].T, XRR[np.ix_(r, r)]]])


class _BlockCompiler(_Compiler):
    """The compiler of :mod:`.prediction` with X2 kept in blocks."""

    def __init__(self, net: NetworkedLoop):
        super().__init__(net)
        self.nc = min(sl.start for sl in net.R.values())
        nc = self.nc
        Q = net.Qz
        self.Qb = (Q[:nc, :nc], Q[:nc, nc:], Q[nc:, nc:])

    def step(self, pattern: Any) -> BlockSegment | BlockEvent:
        if pattern in self._cache:
            return self._cache[pattern]
        A0, D = self.net.matrices(pattern)
        n, nc = self.net.n, self.nc
        if not D:
            A, Gam = A0[:, :n].tocsr(), A0[:, n:].toarray()
            assert A[nc:, :nc].nnz == 0 and not np.any(Gam[nc:]), "noise or F reaching R"
            Gc = Gam[:nc]
            out: Any = BlockSegment(
                Gcc=A[:nc, :nc].toarray(), GcR=A[:nc, nc:].toarray(), GRR=A[nc:, nc:].tocsr(),
                Wcc=Gc @ self.W @ Gc.T, S=tuple(q.copy() for q in self.Qb), c=self.c0,
                length=1)
        else:
            Abar, terms, noise = A0, [], None
            for key, Dl in D.items():
                p = self.net.loss[key]
                Abar = Abar + (1.0 - p) * Dl
                sl = self.net.R[key]
                V = Dl[sl.start:sl.stop, :n].tocsr()
                cols = np.unique(V.indices)              # F's slot and R_l: a few columns
                terms.append((p * (1.0 - p), V[:, cols].toarray(), cols, sl))
                G = Dl[:, n:].toarray()
                if np.any(G):
                    noise = (0 if noise is None else noise) + p * (1 - p) * (G @ self.W @ G.T)
            G = Abar[:, n:].toarray()
            noise = G @ self.W @ G.T + (0 if noise is None else noise)
            # kept as blocks, and only those that are not zero (noise reaches c alone)
            blocks = tuple(b if np.any(b) else None for b in
                           (noise[:nc, :nc], noise[:nc, nc:], noise[nc:, nc:]))
            out = BlockEvent(A=Abar[:, :n].tocsr(), terms=tuple(terms), noise=blocks)
        self._cache[pattern] = out
        return out

    def apply_blocks(self, plan: Sequence[Any], X: Blocks) -> tuple[Blocks, float]:
        """X2 (in blocks) after the plan, and the plan's expected cost."""
        cost = 0.0
        nc = self.nc
        for s in plan:
            Xcc, XcR, XRR = X
            if isinstance(s, BlockSegment):
                cost += _sym_cost(s.S, X) + s.c
                Tc = s.Gcc @ Xcc + s.GcR @ XcR.T
                TR = s.Gcc @ XcR + s.GcR @ XRR
                Ycc = Tc @ s.Gcc.T + TR @ s.GcR.T + s.Wcc
                YcR = _right(s.GRR, TR)
                YRR = _right(s.GRR, np.asarray(s.GRR @ XRR))
                X = (0.5 * (Ycc + Ycc.T), YcR, 0.5 * (YRR + YRR.T))
                continue
            cost += _sym_cost(self.Qb, X) + self.c0
            A = s.A
            Ac, AR = A[:nc].tocsr(), A[nc:].tocsr()
            Acc, AcR = Ac[:, :nc].toarray(), Ac[:, nc:].toarray()
            ARc, ARR = AR[:, :nc].tocsr(), AR[:, nc:].tocsr()
            XRc = np.ascontiguousarray(XcR.T)
            Pc = Acc @ Xcc + AcR @ XRc                       # rows c of A X
            PR = Acc @ XcR + AcR @ XRR
            Qc = np.asarray(ARc @ Xcc) + np.asarray(ARR @ XRc)   # rows R of A X
            QR = np.asarray(ARc @ XcR) + np.asarray(ARR @ XRR)
            Ycc = Pc @ Acc.T + PR @ AcR.T
            YcR = _right(ARc, Pc) + _right(ARR, PR)
            YRR = _right(ARc, Qc) + _right(ARR, QR)
            for Y, N in zip((Ycc, YcR, YRR), s.noise):
                if N is not None:
                    Y += N
            full = None
            for c, V, cols, sl in s.terms:                   # one small block per link
                if full is None:
                    full = _Lookup(X, nc)
                blk = V @ full.sub(cols) @ V.T
                r = slice(sl.start - nc, sl.stop - nc)
                YRR[r, r] += c * blk
            X = (0.5 * (Ycc + Ycc.T), YcR, 0.5 * (YRR + YRR.T))
        return X, cost


def predict_window_blocks(net: NetworkedLoop, Z0: np.ndarray, k0: int, K: int,
                          spectral_radius: float) -> NetworkPrediction:
    """:func:`.prediction.predict_window` with X2 in blocks (many links).

    Parameters
    ----------
    net : NetworkedLoop
        The loop.
    Z0 : np.ndarray
        Its initial state.
    k0, K : int
        The window.
    spectral_radius : float
        The verdict to report (computed elsewhere, or nan).

    Returns
    -------
    NetworkPrediction
        The expected cost rate over the window (kept in :mod:`.cache`).
    """
    cost = cached("window-blocks", net, (np.asarray(Z0, float), int(k0), int(K)),
                  lambda: _window_cost_blocks(net, Z0, k0, K))
    return NetworkPrediction(cost_rate=cost, spectral_radius=spectral_radius,
                             cycle_s=net.period * net.h)


def _window_cost_blocks(net: NetworkedLoop, Z0: np.ndarray, k0: int, K: int) -> float:
    """E[J] / (K - k0) with X2 in blocks."""
    comp = _BlockCompiler(net)
    nc = comp.nc
    X: Blocks = (np.outer(Z0[:nc], Z0[:nc]), np.outer(Z0[:nc], Z0[nc:]),
                 np.outer(Z0[nc:], Z0[nc:]))
    b, P = comp.first_cycle(), net.period
    cycle = functools.cache(lambda: comp.plan(b, b + P))     # compiled once, when first used
    return window_cost(X, k0, K, b, P, cycle, comp.plan, comp.apply_blocks)
