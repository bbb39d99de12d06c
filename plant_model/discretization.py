"""Exact sampling of the continuous model at the communication step h.

Zero-order hold on u over [k h, (k+1) h):

    s[k+1] = Ad s[k] + Bd u[k] + v[k],   v[k] ~ N(0, Qd)
    Ad = expm(Ac h),  Bd = int_0^h expm(Ac t) dt Bc
    Qd = int_0^h expm(Ac t) Wc expm(Ac' t) dt          (Van Loan, 1978)

Sampled measurement noise: covariance V / h per sample ("intensity" convention: the
ideal anti-alias average of white noise of intensity V over one step), or V itself
under the "per_sample" convention, where the process noise covariance per step is W.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import block_diag, expm

from .linalg_checks import ModelError
from .memo import DesignCache
from .system import LinearSystem

__all__ = ["DiscreteModel", "zoh", "van_loan", "discretize"]


def zoh(Ac: np.ndarray, Bc: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """(Ad, Bd) of the zero-order-hold discretization, from one matrix exponential.

    expm([[Ac, Bc], [0, 0]] h) = [[Ad, Bd], [0, I]]: Ad = expm(Ac h),
    Bd = int_0^h expm(Ac t) dt Bc.

    Parameters
    ----------
    Ac : np.ndarray
        Continuous state matrix, ns x ns, 1/s.
    Bc : np.ndarray
        Continuous input matrix, ns x m.
    h : float
        Sampling period, s.

    Returns
    -------
    Ad : np.ndarray
        State transition over one step, ns x ns.
    Bd : np.ndarray
        Input matrix over one step, ns x m.
    """
    ns, m = Bc.shape
    M = np.zeros((ns + m, ns + m))
    M[:ns, :ns] = Ac
    M[:ns, ns:] = Bc
    E = expm(M * h)
    return E[:ns, :ns], E[:ns, ns:]


def van_loan(Ac: np.ndarray, Wc: np.ndarray, h: float) -> np.ndarray:
    """Qd = int_0^h expm(Ac t) Wc expm(Ac' t) dt by Van Loan's block exponential.

    Parameters
    ----------
    Ac : np.ndarray
        Continuous state matrix, ns x ns, 1/s.
    Wc : np.ndarray
        Intensity (power spectral density) of the process noise, ns x ns.
    h : float
        Sampling period, s.

    Returns
    -------
    np.ndarray
        Qd, the covariance of the noise added per step (symmetrized), ns x ns.
    """
    ns = Ac.shape[0]
    M = np.zeros((2 * ns, 2 * ns))
    M[:ns, :ns] = -Ac
    M[:ns, ns:] = Wc
    M[ns:, ns:] = Ac.T
    E = expm(M * h)
    Ad = E[ns:, ns:].T
    Qd = Ad @ E[:ns, ns:]
    return 0.5 * (Qd + Qd.T)


#: sampled models of this process, by their numbers (plant_model.memo)
_DISCRETE_CACHE = DesignCache("discretize")


@dataclass(frozen=True)
class DiscreteModel:
    """The sampled model at step h; s = [x; w; z] (sizes n, r, l)."""

    h: float
    Ad: np.ndarray      #: state transition over one step
    Bd: np.ndarray      #: input matrix over one step
    Qd: np.ndarray      #: covariance of the process noise added per step
    Rd: np.ndarray      #: covariance of [n; n_z] per sample (2p x 2p)
    M: np.ndarray       #: [y; ybar] = M s + [n; n_z]
    E: np.ndarray       #: e = E s
    n: int
    r: int
    l: int  # noqa: E741
    p: int
    #: independent noise streams: per stream the positions it fills in a noise row
    #: [v; n; n_z] (a fleet whose vehicles draw their own noise); None: one stream
    noise_blocks: tuple[tuple[int, ...], ...] | None = None
    #: the key of each stream's generator (seeded [seed, key]); None: 1..N for the blocks
    #: before the last, 0 for the last (the leader) (plant_model.plant.NoiseStream)
    noise_keys: tuple[int, ...] | None = None

    @property
    def ns(self) -> int:
        """Length of the sampled state s = [x; w; z], n + r + l."""
        return self.n + self.r + self.l

    @property
    def noise_dim(self) -> int:
        """Length of the standard normal vector drawn per step."""
        return self.ns + 2 * self.p


#: smallest h max|A| accepted: below it expm(A h) - I is at the level of rounding errors
MIN_STEP_RESOLUTION = 1e-8


def check_step(Ac: np.ndarray, h: float) -> None:
    """Refuse a step h too small to sample ``x' = Ac x``: h max|Ac| < ``MIN_STEP_RESOLUTION``
    makes expm(Ac h) the identity to within rounding.

    Parameters
    ----------
    Ac : np.ndarray
        The continuous-time (augmented) state matrix, 1/s.
    h : float
        Sampling period, s.

    Raises
    ------
    ModelError
        Naming h, h max|Ac| and the smallest step accepted.
    """
    scale = float(np.max(np.abs(Ac))) if Ac.size else 0.0
    if 0.0 < scale and h * scale < MIN_STEP_RESOLUTION:
        raise ModelError(
            f"step h = {h:g} s is too small for this model: h max|A| = {h * scale:.3g} is "
            f"below {MIN_STEP_RESOLUTION:g}, so the sampled model expm(A h) is the identity "
            "to within rounding and no estimator or controller can be designed from it; use "
            f"h >= {MIN_STEP_RESOLUTION / scale:.3g} s")


def discretize(system: LinearSystem, h: float) -> DiscreteModel:
    """Sample ``system`` at step ``h`` (seconds) as described in the module docstring.

    Solved once per process for identical numbers (:mod:`plant_model.memo`): the result's
    arrays are read-only.

    Parameters
    ----------
    system : LinearSystem
        The validated model.
    h : float
        Sampling period, s.

    Returns
    -------
    DiscreteModel
        Ad, Bd, Qd (Van Loan, or W_x, W_w, W_z per step under 'per_sample'),
        Rd = blkdiag(V_y, V_ybar) / h (or without / h under 'per_sample'), M and E.

    Raises
    ------
    ModelError
        If h is not a positive finite number, is too small for the model's fastest rate
        (h max|A| < ``MIN_STEP_RESOLUTION``) or the sampled model overflows.
    """
    h = float(h)
    if not np.isfinite(h) or h <= 0.0:
        raise ModelError(f"step h = {h} s must be a positive finite number")
    Ac, Bc, Wc = system.augmented()
    check_step(Ac, h)
    key = (h, Ac, Bc, Wc, system.V_y, system.V_ybar, system.noise_convention,
           system.measurement_matrix(), system.error_matrix(), system.n, system.r, system.l,
           system.p, repr(system.meta.get("noise_blocks")),
           repr(system.meta.get("noise_keys")))
    return _DISCRETE_CACHE.get(key, lambda: _discretize(system, h, Ac, Bc, Wc))


def _blockwise_van_loan(Ac: np.ndarray, Wc: np.ndarray, h: float,
                        blocks: tuple[tuple[int, ...], ...]) -> np.ndarray:
    """Qd of a system whose noise streams are independent blocks, one Van Loan per block.

    Each block's state positions (those below ns) must be closed under Ac (no coupling in
    the physics, the consensus protocol as a force); then Qd is block diagonal and block b
    is van_loan(Ac[b, b], Wc[b, b], h): the same numbers, bit for bit, as sampling that
    vehicle alone (:func:`plant_model.per_vehicle.sample_vehicle`), so a per-vehicle plant
    draws exactly the stacked plant's noise.
    """
    ns = Ac.shape[0]
    Qd = np.zeros((ns, ns))
    for block in blocks:
        st = np.array([i for i in block if i < ns], dtype=np.int64)
        if not st.size:
            continue
        rest = np.setdiff1d(np.arange(ns), st)
        if rest.size and (np.any(Ac[np.ix_(st, rest)]) or np.any(Ac[np.ix_(rest, st)])):
            raise ModelError("a noise stream's states are coupled to other states in the "
                             "physics: the noise cannot be drawn per vehicle")
        Qd[np.ix_(st, st)] = van_loan(Ac[np.ix_(st, st)], Wc[np.ix_(st, st)], h)
    return Qd


def _discretize(system: LinearSystem, h: float, Ac: np.ndarray, Bc: np.ndarray,
                Wc: np.ndarray) -> DiscreteModel:
    Ad, Bd = zoh(Ac, Bc, h)
    V = block_diag(system.V_y, system.V_ybar)
    blocks = system.meta.get("noise_blocks")
    if system.noise_convention == "intensity" and blocks:
        Qd = _blockwise_van_loan(Ac, Wc, h, blocks)
        Rd = V / h
    elif system.noise_convention == "intensity":
        Qd = van_loan(Ac, Wc, h)
        Rd = V / h
    else:
        Qd = Wc.copy()
        Rd = V.copy()
    if not (np.all(np.isfinite(Ad)) and np.all(np.isfinite(Qd))):
        raise ModelError(
            f"the sampled model at h = {h} s overflows; the continuous model is too fast "
            "or unstable for this step"
        )
    return DiscreteModel(h=h, Ad=Ad, Bd=Bd, Qd=Qd, Rd=Rd, M=system.measurement_matrix(),
                         E=system.error_matrix(), n=system.n, r=system.r, l=system.l,
                         p=system.p, noise_blocks=system.meta.get("noise_blocks"),
                         noise_keys=system.meta.get("noise_keys"))
