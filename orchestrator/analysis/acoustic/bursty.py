"""Mean-square predictions of the loop over bursty links: a Markov jump linear system.

A Gilbert-Elliott link l (:class:`plant_model.acoustic.link_models.GilbertElliott`) has a
channel state s_l in {G, B} per message; message n of l gets through with probability
q_l(s) = 1 - loss_s, independently given s, and s steps per message with
P(G -> B) = p_gb, P(B -> G) = p_bg, started stationary (pi_B = p_gb / (p_gb + p_bg)). The
loop (:class:`~.loop.NetworkedLoop`) is Z+ = (A0 + sum_l delta_l D_l) [Z; zeta]: a Markov
jump linear system whose mode is the channel states of the links. Its exact second moment
needs one matrix per joint mode, 2^L; this module keeps L + 1 (docs/theory.md, "Bursty
links", derives them):

- X = E[Z Z'], the second moment;
- U_l = E[Z Z' (1{s_l = B} - pi_B,l)] per bursty link, s_l the state of the next message
  of l to arrive: how the second moment leans towards l's bad state (U_l = 0 at the known
  start).

The one approximation is the closure E[Z Z' | all s] = X + sum_l (E[Z Z' | s_l] - X)
(no interaction between two links' states in the second moment): exact with one bursty
link (and with independent links: U = 0), and the error is of fourth order in the links'
deviations from their means otherwise. With q = the mean delivery 1 - mean loss,
kappa = q_B - q_G, sigma2 = pi_B pi_G, lambda = 1 - p_gb - p_bg and Abar = A0 + sum q D,
a step with arrivals maps

    X+   = [the independent-loss step at the mean loss](X)
           + sum_(m bursty, arriving)
               kappa_m (D_m U_m Abar' + Abar U_m D_m' + (1 - 2 q_m) D_m U_m D_m')
    U_l+ = [the same step without noise](U_l)                                  (l not arriving)
    U_l+ = lambda_l ([the same step without noise](U_l)
           + sigma2 kappa (D Xe Abar' + Abar Xe D') + kappa (pi_G - pi_B)(D U Abar' + Abar U D')
           + (1 - 2q) sigma2 kappa D Xe D' + (1 - 2q)(pi_G - pi_B) kappa D U D'
           + sum_(m != l bursty, arriving) sigma2 kappa kappa_m (D U_m D_m' + D_m U_m D'))
                                                                               (l arriving)

(D = D_l, U = U_l, Xe = blockdiag(X, W) on [Z; zeta]); a step without arrivals maps
X -> G X G' + W and U_l -> G U_l G'. The cost over a window is sum tr(Qz X) as for
independent loss, and mean-square stability is the spectral radius of the noise-free
cycle map of (X, U_1, ..., U_L) on the error coordinates (:func:`bursty_radius`), exact
for one bursty link. :func:`critical_burst` finds the mean burst length at which it reaches
1, every bursty link keeping its stationary bad-state probability and state losses (so
its mean loss). A schedule with bursty links is refused (a down link's channel steps
without an arrival, which the patterns do not carry).
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.sparse.linalg import ArpackNoConvergence, LinearOperator, eigs

from plant_model.acoustic.link_models import GilbertElliott, min_burst
from plant_model.linalg_checks import ModelError

from .cache import cached
from .cycle import Event, Segment, _Compiler, _sandwich
from .loop import NetworkedLoop

__all__ = ["BurstyMoments", "bursty_radius", "bursty_window", "critical_burst"]

Log = Callable[[str], None]


@dataclass(frozen=True, eq=False)
class _Arrival:
    """A bursty link arriving at an event step: its D on Z and on zeta (restricted), its
    model's scalars."""

    key: Any
    DZ: Any             #: sparse (CSR): a link's few rows
    Dz: np.ndarray
    q: float            #: mean delivery 1 - mean loss
    kappa: float        #: q_B - q_G
    sigma2: float       #: pi_B pi_G
    tilt: float         #: pi_G - pi_B
    lam: float          #: 1 - p_gb - p_bg


def _scalars(m: GilbertElliott) -> tuple[float, float, float, float, float]:
    pb = m.pi_bad
    return (1.0 - m.mean_loss, m.loss_good - m.loss_bad, pb * (1.0 - pb), 1.0 - 2.0 * pb,
            m.correlation)


class BurstyMoments:
    """(X, U_1..U_L) of a loop with bursty links through its compiled plans (module
    docstring).

    Parameters
    ----------
    net : NetworkedLoop
        The loop (no schedule).
    models : Mapping or None, optional
        Per bursty link its model (default the loop's own, ``net.bursty``).
    error_only : bool, optional
        Restrict to the error coordinates (the stability map).
    """

    def __init__(self, net: NetworkedLoop, models: Mapping[Any, GilbertElliott] | None = None,
                 error_only: bool = False):
        if net.schedule is not None:
            raise ModelError("bursty links (loss_model = \"gilbert-elliott\") with a switching "
                             "schedule are not predicted: a down link's channel steps without "
                             "an arrival")
        self.net = net
        self.models = dict(net.bursty if models is None else models)
        losses = {k: float(net.loss[k]) for k in net.form.links}
        losses.update({k: m.mean_loss for k, m in self.models.items()})
        self.comp = _Compiler(net, loss=losses, error_only=error_only)
        self.keys = list(self.models)
        self._arrivals: dict[int, tuple[np.ndarray, list[_Arrival]]] = {}

    # ---------------------------------------------------------------- plans
    def plan(self, ka: int, kb: int) -> list[Segment | Event]:
        """The maps of transitions ka..kb-1 (:meth:`_Compiler.plan`)."""
        return self.comp.plan(ka, kb)

    def cycle(self) -> list[Segment | Event]:
        """The compiled message cycle."""
        return self.comp.cycle()

    def _event(self, ev: Event) -> tuple[np.ndarray, list[_Arrival]]:
        """Abar's zeta part and the bursty links arriving at an event step."""
        if id(ev) not in self._arrivals:
            pattern = next(p for p, v in self.comp._cache.items() if v is ev)
            A0, D = self.net.matrices(pattern)
            Abar = A0
            for key, Dl in D.items():
                Abar = Abar + (1.0 - self.comp.loss_of(key)) * Dl
            _, Az = self.comp._restrict(Abar)
            arr = []
            for key in D:
                if key in self.models:
                    DZ, Dz = self.comp._restrict(D[key])
                    q, kappa, sigma2, tilt, lam = _scalars(self.models[key])
                    arr.append(_Arrival(key, DZ.tocsr(), Dz.toarray(), q, kappa, sigma2,
                                        tilt, lam))
            self._arrivals[id(ev)] = (Az.toarray(), arr)
        return self._arrivals[id(ev)]

    # ---------------------------------------------------------------- application
    def start(self, Z0: np.ndarray) -> list[np.ndarray]:
        """(X, U_1..U_L) at a known start: Z0 Z0' and zeros."""
        X = np.outer(Z0, Z0)
        return [X] + [np.zeros_like(X) for _ in self.keys]

    def apply(self, plan: list[Segment | Event], M: list[np.ndarray], noise: bool = True,
              cost: bool = True) -> tuple[list[np.ndarray], float]:
        """(X, U_1..U_L) after the plan, and its expected cost summed over its steps."""
        total = 0.0
        comp = self.comp
        W = comp.W
        for s in plan:
            X, U = M[0], M[1:]
            if isinstance(s, Segment):
                if cost:
                    total += float(np.sum(s.S * X)) + (s.c if noise else 0.0)
                M = [_sandwich(s.G, X) + (s.W if noise else 0.0)] + [_sandwich(s.G, u)
                                                                      for u in U]
                continue
            if cost:
                total += float(np.sum(comp.Qz * X)) + (comp.c0 if noise else 0.0)
            Az, arrivals = self._event(s)
            A = s.A

            def step(Y0: np.ndarray, with_noise: bool, s: Event = s, A: Any = A
                     ) -> np.ndarray:
                Y = _sandwich(A, Y0) + (s.noise if with_noise else 0.0)
                for term in s.terms:
                    term.add_to(Y, Y0)
                return Y

            def right(Dm: Any, Y: np.ndarray, A: Any = A) -> np.ndarray:
                """Dm Y A' (Dm sparse, A sparse or dense)."""
                return np.asarray(A @ np.asarray(Dm @ Y).T).T

            def both(Dm: Any, Y: np.ndarray, Dn: Any) -> np.ndarray:
                """Dm Y Dn' (sparse Dm, Dn)."""
                return np.asarray(Dn @ np.asarray(Dm @ Y).T).T

            idx = {k: n for n, k in enumerate(self.keys)}
            newX = step(X, noise)
            for a in arrivals:
                Um = U[idx[a.key]]
                P = right(a.DZ, Um)
                newX += a.kappa * (P + P.T + (1.0 - 2.0 * a.q) * both(a.DZ, Um, a.DZ))
            newU = []
            here = {a.key: a for a in arrivals}
            for n, key in enumerate(self.keys):
                V = step(U[n], False)
                a = here.get(key)
                if a is not None:
                    D, u = a.DZ, U[n]
                    P1 = right(D, X)
                    DXD = both(D, X, D)
                    if noise:
                        P1 = P1 + a.Dz @ W @ Az.T
                        DXD = DXD + a.Dz @ W @ a.Dz.T
                    P2 = right(D, u)
                    V += (a.sigma2 * a.kappa * (P1 + P1.T) + a.kappa * a.tilt * (P2 + P2.T)
                          + (1.0 - 2.0 * a.q) * a.sigma2 * a.kappa * DXD
                          + (1.0 - 2.0 * a.q) * a.tilt * a.kappa * both(D, u, D))
                    for b in arrivals:
                        if b.key != key:
                            C = both(D, U[idx[b.key]], b.DZ)
                            V += a.sigma2 * a.kappa * b.kappa * (C + C.T)
                    V = a.lam * V
                newU.append(V)
            M = [newX] + newU
        return M, total


def bursty_window(net: NetworkedLoop, Z0: np.ndarray, k0: int, K: int) -> float:
    """E[J] / (K - k0) over samples k0 <= k < K from Z(0) = Z0, with the loop's bursty
    links (module docstring); kept in the prediction cache."""
    def compute() -> float:
        from .prediction import window_cost
        bm = BurstyMoments(net)
        return window_cost(bm.start(np.asarray(Z0, float)), k0, K, bm.comp.first_cycle(),
                           net.period, bm.cycle, bm.plan, bm.apply)
    return cached("bursty-window", net, (_models_key(net.bursty), np.asarray(Z0, float),
                                         int(k0), int(K)), compute)


def _models_key(models: Mapping[Any, GilbertElliott]) -> list[Any]:
    return [[str(k), list(m.parameters().values())] for k, m in sorted(models.items(), key=str)]


def _radius(bm: BurstyMoments, tol: float = 1e-10) -> float:
    """The largest modulus of an eigenvalue of the noise-free cycle map of (X, U_1..U_L)
    on the error coordinates: by Arnoldi over the stacked upper triangles."""
    n = bm.comp.keep.size
    L = len(bm.keys)
    iu = np.triu_indices(n)
    N = iu[0].size
    plan = bm.cycle()

    def full(v: np.ndarray) -> np.ndarray:
        Y = np.zeros((n, n))
        Y[iu] = v
        return Y + np.triu(Y, 1).T

    def matvec(v: np.ndarray) -> np.ndarray:
        parts = [full(v[j * N:(j + 1) * N]) for j in range(L + 1)]
        out, _ = bm.apply(plan, parts, noise=False, cost=False)
        return np.concatenate([o[iu] for o in out])

    size = (L + 1) * N
    if size <= 400:
        Lm = np.column_stack([matvec(e) for e in np.eye(size)])
        return float(np.max(np.abs(np.linalg.eigvals(Lm))))
    op = LinearOperator((size, size), matvec=matvec, dtype=float)
    v0 = np.concatenate([np.eye(n)[iu]] + [np.full(N, 1e-3)] * L)
    try:
        vals = eigs(op, k=1, which="LM", v0=v0, tol=tol, ncv=20, maxiter=500,
                    return_eigenvectors=False)
        return float(np.abs(vals[0]))
    except ArpackNoConvergence:
        X = [np.eye(n)] + [np.zeros((n, n))] * L
        rates = []
        for _ in range(400):
            X, _ = bm.apply(plan, X, noise=False, cost=False)
            t = float(np.trace(X[0]))
            rates.append(t)
            X = [x / t for x in X]
        return float(np.exp(np.mean(np.log(rates[-50:]))))


def bursty_radius(net: NetworkedLoop, models: Mapping[Any, GilbertElliott] | None = None
                  ) -> float:
    """The second-moment radius per message cycle of the loop with bursty links (module
    docstring): below 1, mean-square stable. Kept in the prediction cache."""
    models = dict(net.bursty if models is None else models)
    return cached("bursty-radius", net, (_models_key(models),),
                  lambda: _radius(BurstyMoments(net, models, error_only=True)))


def critical_burst(net: NetworkedLoop, grid: tuple[float, ...] = (1, 2, 4, 8, 16, 32, 64, 128),
                   rel_tol: float = 0.02, log: Log | None = None) -> tuple[float | None, str]:
    """The mean burst length (messages, 1 / p_bg) at which the loop stops being
    mean-square stable, every bursty link keeping its stationary bad-state probability and
    its state losses (so its mean loss): the radius at grid multiples of the shortest
    reachable burst, then bisection (in log) to ``rel_tol``.

    Returns
    -------
    tuple[float | None, str]
        (burst length, how it was decided); None when stable on the whole grid or unstable
        already at the shortest burst.
    """
    models = dict(net.bursty)
    if not models:
        return None, "no bursty links"
    b0 = max(min_burst(m.pi_bad) for m in models.values())

    def rho(b: float) -> float:
        return bursty_radius(net, {k: m.with_mean_burst(b) for k, m in models.items()})

    def compute() -> tuple[float | None, str]:
        if log is not None:
            log(f"searching the critical mean burst length: the second-moment radius at "
                f"bursts {b0 * grid[0]:g} .. {b0 * grid[-1]:g} messages and by bisection ...")
        r = {}
        lo = None
        for g in grid:
            b = b0 * g
            r[b] = rho(b)
            if r[b] >= 1.0:
                if lo is None:
                    return None, (f"not mean-square stable at the shortest burst {b:g} "
                                  f"(radius {r[b]:.6g})")
                hi = b
                break
            lo = b
        else:
            return None, (f"none up to {b0 * grid[-1]:g} messages: second-moment radius at "
                          f"most {max(r.values()):.6g} per cycle")
        while hi / lo - 1.0 > rel_tol:
            mid = math.sqrt(lo * hi)
            r[mid] = rho(mid)
            lo, hi = (mid, hi) if r[mid] < 1.0 else (lo, mid)
        return math.sqrt(lo * hi), (f"bisection: stable at a mean burst of {lo:.4g} messages "
                                    f"(radius {r[lo]:.6g}), not at {hi:.4g} ({r[hi]:.6g}); "
                                    "the same stationary bad-state probability and state "
                                    "losses on every bursty link")
    out = cached("critical-burst", net, (_models_key(models), tuple(grid), rel_tol), compute,
                 encode=list, decode=lambda v: (v[0], v[1]))
    return out
