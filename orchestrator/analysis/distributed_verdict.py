"""Stability verdict and cost prediction of the distributed fleet's sampled closed loop
(:class:`~orchestrator.analysis.distributed.DistributedLoop`).

For identical vehicles (same model, gain and filter; offsets may differ) the error part of
the loop is I_N kron M0 + (L + G) kron M1 in per-vehicle order, so in the Schur basis of
L + G it is block triangular with blocks M0 + lambda M1, one per eigenvalue lambda of L + G:
:func:`stability_verdict` judges each block (exact) and names the failing lambda.

Cost rate (the project's, on the total force): J/T = tr(Q E[e e']) + tr(R E[u u']) with
Sigma = Phi_R Sigma Phi_R' + Gam_R W Gam_R' on the error part (:func:`predict_cost`); with a
window and an initial state the deterministic mean motion is added, as in
:func:`orchestrator.analysis.prediction.predict_stationary`.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from controller_fmu.distributed import consensus_eigenvalues, min_observer_gain
from plant_model.linalg_checks import ModelError, fmt_complex

from .block_stein import stein, triangular_order
from .distributed import DistributedLoop, _assemble, filtered
from .prediction import window_average_covariance, window_mean_sums

#: samples of the mean motion per block in :func:`predict_cost` (a block of a 3417-state
#: loop is 27 MB)
_MEAN_BLOCK = 1000

__all__ = ["DistributedPrediction", "StabilityVerdict", "predict_cost", "stability_verdict",
           "vehicle_blocks"]

def _identical(loop: DistributedLoop) -> bool:
    a0, l0 = loop.sampled[0], loop.laws[0]

    def same(x: np.ndarray | None, y: np.ndarray | None) -> bool:
        return (x is None and y is None) or (x is not None and y is not None
                                             and x.shape == y.shape and np.array_equal(x, y))
    return all(same(a.Ad, a0.Ad) and same(a.Bd, a0.Bd) and same(a.L, a0.L)
               and all(same(getattr(law, k), getattr(l0, k)) for k in ("Kx", "X", "U", "Xw", "Uw"))
               for a, law in zip(loop.sampled, loop.laws))


@dataclass(frozen=True)
class StabilityVerdict:
    """Spectral radius of the error part, per-eigenvalue blocks, continuous-time bounds."""

    spectral_radius: float          #: of the error part (the largest block's if identical)
    stacked_spectral_radius: float  #: from the eigenvalues of the stacked error part
    identical: bool                 #: the per-eigenvalue blocks are exact
    blocks: tuple[tuple[complex, float], ...]  #: (lambda of L + G, spectral radius of its block)
    observer_mu_min: float          #: continuous-time bound, mu > this (1/s)
    cohesion_bound: str             #: continuous-time statement on c
    stacked_eigenvalue: complex = 0j  #: the stacked error part's eigenvalue of largest |.|

    @property
    def stable(self) -> bool:
        """Spectral radius < 1."""
        return self.spectral_radius < 1.0


@lru_cache(maxsize=4)
def _verdict(loop: DistributedLoop) -> StabilityVerdict:
    """The verdict of :func:`stability_verdict`, computed once per loop (a loop is
    immutable): the stacked error part's eigenvalues are the costly part (a dense
    eigenproblem of a few thousand states for formation-100), and every prediction of a
    run asks for them."""
    R = ~loop.deterministic
    PhiR = loop.Phi[np.ix_(R, R)]
    blocks_R = vehicle_blocks(loop)
    if (sum(b.size for b in blocks_R) == PhiR.shape[0]
            and triangular_order(PhiR, blocks_R) is not None):
        # block triangular (an acyclic graph): the eigenvalues are the diagonal blocks'
        ev = np.concatenate([np.linalg.eigvals(PhiR[np.ix_(b, b)]) for b in blocks_R]
                            or [np.zeros(0, complex)])
    else:
        ev = np.linalg.eigvals(PhiR)
    k = int(np.argmax(np.abs(ev)))
    rho = float(np.abs(ev[k]))
    lams = consensus_eigenvalues(loop.LG)
    identical = _identical(loop)
    blocks: list[tuple[complex, float]] = []
    if identical:
        sa, law = loop.sampled[0], loop.laws[0]
        radius: dict[complex, float] = {}      # eigenvalues of L + G repeat (exactly, read
        for lam in lams:                       # off the diagonal of an acyclic graph's)
            if complex(lam) in radius:
                blocks.append((complex(lam), radius[complex(lam)]))
                continue
            part = _assemble([sa], [law], np.array([[lam]], dtype=complex), np.zeros(1),
                             loop.observer, np.zeros((sa.M.shape[0], loop.observer.Phi.shape[0])),
                             [np.zeros(sa.M.shape[0])], loop.cohesion, filtered(loop.estimator))
            Rb = ~part["deterministic"]
            radius[complex(lam)] = float(np.max(np.abs(
                np.linalg.eigvals(part["Phi"][np.ix_(Rb, Rb)]))))
            blocks.append((complex(lam), radius[complex(lam)]))
    if identical:       # exact: the stacked eigenvalues are ill-conditioned when L + G
        rho = max(b for _, b in blocks)     # is defective (a Jordan chain of length k)
    return StabilityVerdict(
        spectral_radius=rho, stacked_spectral_radius=float(np.abs(ev[k])),
        identical=identical, blocks=tuple(blocks),
        observer_mu_min=min_observer_gain(loop.observer.F, loop.LG),
        cohesion_bound=("continuous time: stable for every c >= 0 (blocks A - (1 + c lambda) "
                        "B Kx, Re(1 + c lambda) >= 1/2: LQ gain margin)"),
        stacked_eigenvalue=complex(ev[k]) if ev.size else 0j)


def stability_verdict(loop: DistributedLoop, *, check: bool = False) -> StabilityVerdict:
    """Stability of the sampled loop, per eigenvalue of L + G when the vehicles are identical.

    Parameters
    ----------
    loop : DistributedLoop
        The stacked loop.
    check : bool, optional
        Raise :class:`ModelError` when unstable.

    Returns
    -------
    StabilityVerdict
        The verdict.

    Raises
    ------
    ModelError
        With ``check``, naming the eigenvalue of L + G whose block fails (identical
        vehicles) or the unstable eigenvalue of the stacked loop, with mu, c and h.
    """
    verdict = _verdict(loop)
    rho = verdict.spectral_radius
    if check and rho >= 1.0:
        gains = (f"observer gain mu = {loop.observer.mu:g} 1/s, coupling gain c = "
                 f"{loop.cohesion:g}, h = {loop.h:g} s")
        if verdict.identical:
            lam, rb = max(verdict.blocks, key=lambda b: b[1])
            raise ModelError(
                f"the sampled distributed loop is unstable ({gains}): at eigenvalue "
                f"{fmt_complex(lam)} of L + G the vehicle block has spectral radius {rb:.6g} >= 1 "
                f"(continuous-time bound: mu > {verdict.observer_mu_min:.6g} 1/s, any c >= 0)")
        raise ModelError(
            f"the sampled distributed loop is unstable ({gains}): eigenvalue "
            f"{fmt_complex(verdict.stacked_eigenvalue)} "
            f"of the stacked loop (|.| = {rho:.6g} >= 1); the vehicles differ, so it is not "
            "attributed to one eigenvalue of L + G")
    return verdict


@dataclass(frozen=True)
class DistributedPrediction:
    """Predicted RMS of e and u per component and the cost rate J/T."""

    rms_e: list[float]
    rms_u: list[float]
    cost_rate: float
    spectral_radius: float
    settling_time: float      #: 5 time constants of the slowest error mode, s


def vehicle_blocks(loop: DistributedLoop) -> list[np.ndarray]:
    """Per vehicle the positions of its states (s_i, q_i, eta_i) in the error part of X.

    Parameters
    ----------
    loop : DistributedLoop
        The loop.

    Returns
    -------
    list[np.ndarray]
        One index array per vehicle, in the coordinates of X without [v; c].
    """
    R = np.flatnonzero(~loop.deterministic)
    where = {int(x): k for k, x in enumerate(R)}
    out = []
    for i in range(len(loop.index["s"])):
        idx = [x for key in ("s", "q", "eta") if loop.index[key]
               for x in range(*loop.index[key][i].indices(loop.Phi.shape[0]))]
        out.append(np.array([where[x] for x in idx], dtype=np.int64))
    return out


@lru_cache(maxsize=4)
def _stationary(loop: DistributedLoop) -> np.ndarray:
    """Sigma_R = Phi_R Sigma_R Phi_R' + Gam_R W Gam_R' on the error part, solved vehicle by
    vehicle when the graph has no cycle (:func:`orchestrator.analysis.block_stein.stein`);
    kept for the loop's other predictions (a loop is immutable)."""
    R = ~loop.deterministic
    GR = loop.Gam[R]
    S = stein(loop.Phi[np.ix_(R, R)], GR @ loop.W @ GR.T, vehicle_blocks(loop))
    S.setflags(write=False)
    return S


def predict_cost(loop: DistributedLoop, window: tuple[int, int] | None = None,
                 X0: np.ndarray | None = None, *, transient: bool = False
                 ) -> DistributedPrediction:
    """J/T = tr(Qc E[e e']) + tr(Rc E[u u']) from the discrete Lyapunov equation.

    Kept on disk by content (:mod:`orchestrator.analysis.distributed_cache`): a second run
    of the same fleet (another seed, folder or command) reads it back bit for bit.

    Sigma = Phi_R Sigma Phi_R' + Gam_R W Gam_R' on the error part; E[e e'] = Ce Sigma Ce',
    E[u u'] = Gx Sigma Gx' + Geta W Geta'. With ``window`` = (k0, K) and ``X0`` the mean
    motion X_mean[k] = Phi^k X0 is averaged over the window and added; with ``transient`` the
    covariance is the window average from Sigma_0 = 0
    (:func:`orchestrator.analysis.prediction.window_average_covariance`).

    Parameters
    ----------
    loop : DistributedLoop
        The stacked loop.
    window : tuple[int, int] or None, optional
        Samples k0 <= k < K.
    X0 : np.ndarray or None, optional
        Initial state for the mean motion (:meth:`DistributedLoop.initial_state`).
    transient : bool, optional
        Average the covariance over the window from a known initial state.

    Returns
    -------
    DistributedPrediction
        The prediction.

    Raises
    ------
    ModelError
        If the error part is not stable.
    """
    from .distributed_cache import cached_prediction
    return cached_prediction(loop, window, X0, transient,
                             lambda: _predict_cost(loop, window, X0, transient),
                             DistributedPrediction)


def _predict_cost(loop: DistributedLoop, window: tuple[int, int] | None,
                  X0: np.ndarray | None, transient: bool) -> DistributedPrediction:
    """:func:`predict_cost`, computed."""
    verdict = stability_verdict(loop, check=True)
    R = ~loop.deterministic
    PhiR = loop.Phi[np.ix_(R, R)]
    Sigma = np.zeros_like(loop.Phi)
    SR = _stationary(loop)
    if transient and window is not None:
        SR = window_average_covariance(PhiR, SR, *window)
    Sigma[np.ix_(R, R)] = SR
    See = loop.Ce @ Sigma @ loop.Ce.T
    Suu = loop.Gx @ Sigma @ loop.Gx.T + loop.Geta @ loop.W @ loop.Geta.T
    if window is not None and X0 is not None:
        from scipy.sparse import csr_matrix
        k0, K = window
        Phi = csr_matrix(loop.Phi)             # each vehicle hears a few others: sparse
        X = np.asarray(X0, dtype=float)
        ee, uu = window_mean_sums(Phi, X, k0, K, loop.Ce, loop.Gx, _MEAN_BLOCK,
                                  np.asarray(loop.deterministic))
        See, Suu = See + ee / max(K - k0, 1), Suu + uu / max(K - k0, 1)
    rho = verdict.stacked_spectral_radius if PhiR.size else 0.0
    tau = -loop.h / np.log(rho) if rho > 0 else loop.h
    cost = float(np.trace(loop.Qc @ See) + np.trace(loop.Rc @ Suu))
    return DistributedPrediction(rms_e=np.sqrt(np.clip(np.diag(See), 0, None)).tolist(),
                                 rms_u=np.sqrt(np.clip(np.diag(Suu), 0, None)).tolist(),
                                 cost_rate=cost, spectral_radius=rho, settling_time=5 * tau)
