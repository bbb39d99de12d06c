"""The law one vehicle's controller runs, in each information architecture (per-vehicle).

``distributed`` (neighbour-only information; :mod:`controller_fmu.distributed` for the
observer and the regulator equations): vehicle i applies

    u_i = U eta_i + Uw what_i + uc - Kx eps_i + c Kx (sum_j a_ij eps_j - d_i eps_i),
    eps_i = xhat_i - X eta_i - Xw what_i - xc

with eta_i its distributed observer's estimate of the leader. ``tracking`` keeps its
stacked meaning, on the vehicle's own view of the mission
(:func:`plant_model.per_vehicle.vehicle_view`, z = [eta_i; c]):

- ``regulator``: Su and Huang's law, U, Uw, uc from the regulator equations
  (:func:`controller_fmu.distributed.design_vehicle_law`, continuous or sampled);
- ``lq``: the paper's law for the vehicle alone, u_i = -(Kx xhat + Kw what + Kz [eta; 1])
  (eq. 12-15 on the view), written in the same form with X, Xw, xc still the regulator
  solution: U = -Kz_l - Kx X, Uw = -Kw - Kx Xw, uc = -kz_c - Kx xc. The law is the paper's;
  eps_i stays the deviation from the vehicle's steady state (what the cohesion term couples).

``centralized`` (the paper's stacked law, every vehicle's estimate and the leader's state):
vehicle i applies its rows of the stacked gain, u_i = u0_i - K_i [xhat_1; what_1; ...; z_l]
(:func:`centralized_rows`); the stacked Riccati and Sylvester equations are solved once, by
whoever builds the system, not in each vehicle.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from plant_model.linalg_checks import ModelError
from plant_model.per_vehicle import vehicle_view

from .distributed import REGULATOR_FORMS, VehicleLaw, design_vehicle_law
from .regulator import TRACKING_MODES, tracking_law

__all__ = ["ARCHITECTURES", "DEPLOYMENTS", "DistributedSettings", "LEADER_INFORMATION",
           "centralized_rows", "observer_start", "vehicle_law"]

#: where each vehicle's law gets its information: the paper's stacked law cut by vehicle
#: (every vehicle's estimate and the leader), or neighbour-only
ARCHITECTURES = ("centralized", "distributed")
#: one set of FMUs for the stacked fleet, or one vehicle, estimator and controller per AUV
DEPLOYMENTS = ("stacked", "per-vehicle")


#: how the vehicles learn the leader's state: its messages reach the pinned vehicles and
#: spread through the observers, or the path is planned and known to every vehicle from
#: the start (no leader messages: every observer starts on it and stays there)
LEADER_INFORMATION = ("messages", "planned")


@dataclass(frozen=True)
class DistributedSettings:
    """The distributed law's gains: observer gain ``mu`` (1/s), ``cohesion`` gain c
    (dimensionless, 0: off), the ``regulator`` equations (continuous or sampled) and how the
    vehicles learn the leader's state (``leader``: one of :data:`LEADER_INFORMATION`)."""

    mu: float = 2.0
    cohesion: float = 0.0
    regulator: str = "continuous"
    leader: str = "messages"


def observer_start(z0: Any, settings: DistributedSettings) -> np.ndarray:
    """A vehicle's first estimate of the leader's state, eta(0): 0 when it learns the leader
    from messages, the leader's z0 for a planned path every vehicle knows.

    Parameters
    ----------
    z0 : Any
        The leader's initial state (l,).
    settings : DistributedSettings
        Its ``leader`` says which.

    Returns
    -------
    np.ndarray
        eta(0), shape (l,).
    """
    z0 = np.asarray(z0, dtype=float).reshape(-1)
    return z0.copy() if settings.leader == "planned" else np.zeros_like(z0)


def vehicle_law(A: Any, B1: Any, B2: Any, C: Any, K: Any, Q: Any, R: Any, F: Any, H: Any,
                offset: Any, *, tracking: str = "regulator", regulator: str = "continuous",
                h: float | None = None, where: str = "") -> VehicleLaw:
    """One vehicle's distributed law for ``tracking`` (module docstring).

    Parameters
    ----------
    A, B1, B2, C, K : Any
        The vehicle (p x p in 1/s, p x q, p x r, s x p) and its disturbance (r x r, 1/s).
    Q, R : Any
        Cost weights, s x s (1/m^2) and q x q (1/N^2).
    F, H : Any
        The leader's exosystem (l x l, 1/s) and tracked output (s x l).
    offset : Any
        Formation offset d_i (s,), m.
    tracking : str, optional
        ``lq`` or ``regulator`` (:data:`controller_fmu.regulator.TRACKING_MODES`).
    regulator : str, optional
        ``continuous`` or ``sampled`` regulator equations (``regulator`` tracking only).
    h : float or None, optional
        Communication step, s (for the sampled form).
    where : str, optional
        Prefix of the error messages ("vehicle 3: ").

    Returns
    -------
    VehicleLaw
        u = U eta + Uw what + uc - Kx (xhat - X eta - Xw what - xc).

    Raises
    ------
    ModelError
        An unknown mode, or the design fails (named by
        :func:`~controller_fmu.distributed.design_vehicle_law`).
    """
    if tracking not in TRACKING_MODES:
        raise ModelError(f"{where}unknown tracking mode {tracking!r}; expected one of "
                         f"{', '.join(TRACKING_MODES)}")
    if regulator not in REGULATOR_FORMS:
        raise ModelError(f"{where}unknown regulator form {regulator!r}; expected one of "
                         f"{', '.join(REGULATOR_FORMS)}")
    form = regulator if tracking == "regulator" else "continuous"
    reg = design_vehicle_law(A, B1, C, Q, R, F, H, offset, B2, K, regulator=form, h=h,
                             where=where)
    if tracking == "regulator":
        return reg
    view = vehicle_view(A, B1, B2, C, K, F, H, offset, Q=Q, R=R)
    try:
        law = tracking_law(view, "lq")
    except ModelError as exc:
        raise ModelError(f"{where}{exc}") from None
    p, r, l0 = reg.X.shape[0], reg.Xw.shape[1], reg.X.shape[1]
    Ks = np.asarray(law.Ks)
    Kx, Kw, Kz = Ks[:, :p], Ks[:, p:p + r], Ks[:, p + r:p + r + l0]
    kc = Ks[:, p + r + l0] if Ks.shape[1] > p + r + l0 else np.zeros(Ks.shape[0])
    return VehicleLaw(Kx=Kx.copy(), P=law.design.P,
                      poles=law.design.closed_loop_poles, X=reg.X, U=-Kz - Kx @ reg.X,
                      Xw=reg.Xw, Uw=-Kw - Kx @ reg.Xw, xc=reg.xc, uc=-kc - Kx @ reg.xc,
                      regulator="continuous", h=None)


def centralized_rows(Ks: Any, N: int, p: int, r: int, q: int, l0: int
                     ) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each vehicle's rows of the stacked law u = -Ks [x_1..N; w_1..N; z_l; c].

    Parameters
    ----------
    Ks : Any
        The stacked gain, N q x (N p + N r + l), l = l0 or l0 + 1 (with the constant c of
        the formation offsets), including the consensus force of the protocol form.
    N, p, r, q, l0 : int
        Vehicles, states, disturbance states and inputs per vehicle, leader states.

    Returns
    -------
    list[tuple[np.ndarray, np.ndarray]]
        Per vehicle (K_i, u0_i): u_i = u0_i - K_i [xhat_1; what_1; ...; xhat_N; what_N; z_l]
        (each vehicle's estimates together, as its estimator sends them), K_i of shape
        q x (N p + N r + l0), u0_i = -Ks[rows, c] (zeros without c).

    Raises
    ------
    ModelError
        If Ks does not have the stacked shape.
    """
    Ks = np.asarray(Ks, dtype=float)
    cols = N * (p + r) + l0
    if Ks.shape[0] != N * q or Ks.shape[1] not in (cols, cols + 1):
        raise ModelError(f"the stacked gain has shape {Ks.shape}; expected ({N * q}, {cols}) "
                         f"or ({N * q}, {cols + 1}) for {N} vehicles")
    order = np.concatenate([np.r_[j * p:(j + 1) * p, N * p + j * r:N * p + (j + 1) * r]
                            for j in range(N)] + [N * (p + r) + np.arange(l0)])
    out = []
    for i in range(N):
        rows = Ks[i * q:(i + 1) * q]
        u0 = -rows[:, cols] if Ks.shape[1] > cols else np.zeros(q)
        out.append((np.ascontiguousarray(rows[:, order]), u0.copy()))
    return out
