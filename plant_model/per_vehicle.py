"""The per-vehicle deployment's mathematics: each vehicle alone, the leader alone.

In the per-vehicle deployment every AUV is its own plant FMU holding only its own physics,
and the virtual leader is one more FMU. With the consensus protocol as a force
(``consensus = "protocol"``, :mod:`plant_model.fleet`) the stacked physics is block
diagonal, so this is the same sampled system, cut along the vehicles:

    vehicle i:  s_i = [x_i; w_i],  s_i[k+1] = Ad_i s_i[k] + Bd_i u_i[k] + v_i[k]
                y_i[k] = C_i x_i[k] + n_i[k]
                [[Ad_i, Bd_i]] from expm([[A_i, B2_i, B1_i], [0, K_i, 0], [0, 0, 0]] h)
    leader:     z[k+1] = Phi z[k] + v_z[k],  Phi = expm(F h)

Noise: vehicle i draws its row [v_i; n_i; nbar_i] (process noise on x_i and w_i, its
position sensor, and the reference sensor of the stacked model) from the generator seeded
[seed, i], coloured by the factor of blkdiag(Qd_i, V_y,i / h, V_ybar,i / h); the leader
draws from [seed, 0]. That is vehicle i's stream of the stacked protocol form
(:func:`plant_model.fleet.noise_blocks`), number for number: both build Qd_i by one Van Loan
exponential of the same block (:func:`plant_model.discretization.discretize` samples the
stacked noise block by block). A per-vehicle plant has no reference sensor: the nbar_i
columns are drawn and not used, so that the streams agree. The leader's stream agrees with
the stacked one when the stacked leader has no constant state c (no formation offsets) or
no process noise (a planned path, every built-in fleet).

Each vehicle's *view* of the mission (:func:`vehicle_view`) is a paper-style system: its
own physics, its own disturbance, and as reference z = [z_l; c] the leader with a constant
c = 1 carrying its formation offset d_i (H = [H_l, d_i]); the per-vehicle controllers and
estimators are designed on it. Units as the stacked fleet: SI, NED positions in m.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .discretization import DiscreteModel, check_step, van_loan, zoh
from .linalg_checks import ModelError, as_matrix, as_square, as_vector
from .system import LinearSystem

__all__ = ["vehicle_views", "vehicle_view", "vehicle_alone", "sample_vehicle",
           "sample_leader", "leader_system"]


def vehicle_view(A: Any, B1: Any, B2: Any, C: Any, K: Any, F: Any, H: Any,
                 offset: Any | None = None, **rest: Any) -> LinearSystem:
    """One vehicle's view of the mission: its physics, its disturbance, the leader as z.

    z = [z_l; c] with F = blkdiag(F_l, 0), H = [H_l, d_i] when the offset d_i is non-zero
    (c(0) = 1), else z = z_l; no coupling (Bz = 0), no other vehicle.

    Parameters
    ----------
    A, B1, B2, C, K : Any
        The vehicle's model (p x p in 1/s, p x q, p x r, s x p) and its disturbance
        exosystem (r x r, 1/s).
    F, H : Any
        The leader's exosystem (l x l, 1/s) and tracked output (s x l).
    offset : Any or None, optional
        Formation offset d_i (s,), m; default 0.
    **rest : Any
        Other :class:`LinearSystem` entries (x0, w0, z0 of the leader, Q, R, W_x, W_w,
        W_z of the leader, V_y, V_ybar, noise_convention).

    Returns
    -------
    LinearSystem
        The validated view.

    Raises
    ------
    ModelError
        Naming the entry that is invalid.
    """
    C = as_matrix("C", C)
    F = as_matrix("leader F", F)
    l0 = F.shape[0]
    H = as_matrix("leader H", H, (C.shape[0], l0))
    d = (np.zeros(C.shape[0]) if offset is None
         else as_vector("formation offset", offset, C.shape[0]))
    mapping = {"A": A, "B1": B1, "B2": B2, "C": C, "K": K, "F": F, "H": H, **rest}
    if np.any(d != 0.0):
        Fc = np.zeros((l0 + 1, l0 + 1))
        Fc[:l0, :l0] = F
        mapping["F"], mapping["H"] = Fc, np.hstack([H, d[:, None]])
        z0 = as_vector("leader z0", rest.get("z0", np.zeros(l0)), l0)
        mapping["z0"] = np.concatenate([z0, [1.0]])
        W_z = rest.get("W_z", 0.0)
        Wc = np.zeros((l0 + 1, l0 + 1))
        Wc[:l0, :l0] = W_z * np.eye(l0) if np.ndim(W_z) == 0 else as_matrix(
            "leader W_z", W_z, (l0, l0))
        mapping["W_z"] = Wc
    return LinearSystem.from_mapping(mapping)


def vehicle_views(spec: Mapping[str, Any], *,
                  models: Sequence[Any] | None = None) -> list[LinearSystem]:
    """Every vehicle's :func:`vehicle_view` of a fleet spec (:mod:`plant_model.fleet`).

    Parameters
    ----------
    spec : Mapping[str, Any]
        The fleet spec; vehicle entries as :func:`plant_model.fleet.fleet_system` reads them.
    models : sequence of VehicleModel, optional
        Its vehicle models when already parsed (:class:`plant_model.fleet_model.Fleet`).

    Returns
    -------
    list[LinearSystem]
        One view per vehicle, in vehicle order; x0 and w0 are the stacked system's.
    """
    from .fleet import disturbance_of, fleet_system, fleet_vehicles

    models = list(models) if models is not None else fleet_vehicles(spec)
    # a resolved spec (plant_model.fleet.resolve_fleet_spec) holds every x0; else the
    # stacked system derives them (leader state plus offset)
    stacked = None if all("x0" in v for v in spec["vehicles"]) else fleet_system(spec)
    leader = spec["leader"]
    F = as_matrix("leader F", leader["F"])
    l0 = F.shape[0]
    p = models[0].p
    views = []
    for i, (v, mdl) in enumerate(zip(spec["vehicles"], models)):
        K, W_w, w0 = disturbance_of(v, mdl.r, f"vehicle {i + 1}")
        views.append(vehicle_view(
            mdl.A, mdl.B1, mdl.B2, mdl.C, K, F, leader["H"], v.get("offset"),
            x0=v["x0"] if stacked is None else stacked.x0[i * p:(i + 1) * p], w0=w0,
            z0=leader.get("z0", np.zeros(l0)),
            Q=v.get("Q", 1.0), R=v.get("R", 1.0), W_x=v.get("W_x", 0.0), W_w=W_w,
            W_z=leader.get("W_z", 0.0), V_y=v.get("V_y", 0.0), V_ybar=v.get("V_ybar", 0.0),
            noise_convention=spec.get("noise_convention", "intensity")))
    return views


def vehicle_alone(mapping: dict[str, Any], l: int,  # noqa: E741 - the leader's size
                  noise_convention: str = "intensity") -> LinearSystem:
    """A vehicle's :func:`vehicle_view` from its own matrices only (an FMU's parameters):
    the leader part is zero, unread by :func:`sample_vehicle` and the vehicle's estimator.

    Parameters
    ----------
    mapping : dict[str, Any]
        A, B1, B2, C, K and any of x0, w0, W_x, W_w, V_y, V_ybar.
    l : int
        The leader's state size.
    noise_convention : str, optional
        ``intensity`` or ``per_sample``.

    Returns
    -------
    LinearSystem
        The validated view.
    """
    s = np.asarray(mapping["C"]).shape[0]
    return vehicle_view(**mapping, F=np.zeros((l, l)), H=np.zeros((s, l)),
                        noise_convention=noise_convention)


def _physics(system: LinearSystem) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Ac, Bc, Wc) of s = [x; w] alone: [[A, B2], [0, K]], [B1; 0], blkdiag(W_x, W_w)."""
    n, r = system.n, system.r
    Ac = np.zeros((n + r, n + r))
    Ac[:n, :n], Ac[:n, n:], Ac[n:, n:] = system.A, system.B2, system.K
    Bc = np.zeros((n + r, system.m))
    Bc[:n] = system.B1
    Wc = np.zeros((n + r, n + r))
    Wc[:n, :n], Wc[n:, n:] = system.W_x, system.W_w
    return Ac, Bc, Wc


def sample_vehicle(system: LinearSystem, h: float, vehicle: int) -> DiscreteModel:
    """Vehicle ``vehicle`` alone (s = [x; w], no reference: l = 0) sampled at h.

    Ad, Bd by zero-order hold, Qd by Van Loan (or W per step under ``per_sample``),
    Rd = blkdiag(V_y, V_ybar) / h; one noise stream keyed ``vehicle`` (module docstring).
    M = [[C, 0], [0, 0]] (the reference sensor rows carry only their noise), E = [-C, 0].

    Parameters
    ----------
    system : LinearSystem
        The vehicle's view (:func:`vehicle_view`); its reference part is not used.
    h : float
        Communication step, s.
    vehicle : int
        The vehicle's number, 1..N: its generator is seeded [seed, vehicle].

    Returns
    -------
    DiscreteModel
        The sampled vehicle.

    Raises
    ------
    ModelError
        If h is not positive, too small for the model, or the vehicle number is not >= 1.
    """
    h = float(h)
    if not np.isfinite(h) or h <= 0.0:
        raise ModelError(f"step h = {h} s must be a positive finite number")
    if int(vehicle) < 1:
        raise ModelError(f"vehicle number {vehicle} must be at least 1 (0 keys the leader)")
    Ac, Bc, Wc = _physics(system)
    check_step(Ac, h)
    Ad, Bd = zoh(Ac, Bc, h)
    s, ns = system.p, Ac.shape[0]
    V = np.zeros((2 * s, 2 * s))
    V[:s, :s], V[s:, s:] = system.V_y, system.V_ybar
    if system.noise_convention == "intensity":
        Qd, Rd = van_loan(Ac, Wc, h), V / h
    else:
        Qd, Rd = Wc.copy(), V
    M = np.zeros((2 * s, ns))
    M[:s, :system.n] = system.C
    E = np.zeros((s, ns))
    E[:, :system.n] = -system.C
    return DiscreteModel(h=h, Ad=Ad, Bd=Bd, Qd=Qd, Rd=Rd, M=M, E=E, n=system.n, r=system.r,
                         l=0, p=s, noise_blocks=(tuple(range(ns + 2 * s)),),
                         noise_keys=(int(vehicle),))


def leader_system(F: Any, z0: Any, W_z: Any = 0.0,
                  noise_convention: str = "intensity") -> tuple[np.ndarray, np.ndarray,
                                                                np.ndarray]:
    """The leader's (F, z0, W_z), checked: l x l (1/s), (l,), l x l (or a number times I).

    Parameters
    ----------
    F, z0, W_z : Any
        Exosystem, initial state, process noise intensity (per-step covariance under
        ``per_sample``).
    noise_convention : str, optional
        Only checked here.

    Returns
    -------
    tuple[np.ndarray, np.ndarray, np.ndarray]
        F, z0, W_z as float arrays.
    """
    F = as_square("leader F", F)
    l0 = F.shape[0]
    z0 = as_vector("leader z0", z0, l0)
    W = float(W_z) * np.eye(l0) if np.ndim(W_z) == 0 else as_matrix("leader W_z", W_z, (l0, l0))
    if noise_convention not in ("intensity", "per_sample"):
        raise ModelError(f"noise_convention {noise_convention!r} is not one of intensity, "
                         "per_sample")
    return F, z0, W


def sample_leader(F: Any, W_z: Any, h: float, noise_convention: str = "intensity"
                  ) -> DiscreteModel:
    """The leader alone (s = z, no input, no sensor) sampled at h; its stream keyed 0.

    Parameters
    ----------
    F : Any
        Exosystem, l x l, 1/s.
    W_z : Any
        Process noise intensity (l x l; 0 for a planned path).
    h : float
        Communication step, s.
    noise_convention : str, optional
        ``intensity`` or ``per_sample``.

    Returns
    -------
    DiscreteModel
        n = r = p = 0, l = l: Ad = expm(F h), Qd by Van Loan.
    """
    F, _, W = leader_system(F, np.zeros(np.asarray(F).shape[0]), W_z, noise_convention)
    h = float(h)
    if not np.isfinite(h) or h <= 0.0:
        raise ModelError(f"step h = {h} s must be a positive finite number")
    check_step(F, h)
    l0 = F.shape[0]
    Ad, Bd = zoh(F, np.zeros((l0, 0)), h)
    Qd = van_loan(F, W, h) if noise_convention == "intensity" else W.copy()
    return DiscreteModel(h=h, Ad=Ad, Bd=Bd, Qd=Qd, Rd=np.zeros((0, 0)),
                         M=np.zeros((0, l0)), E=np.zeros((0, l0)), n=0, r=0, l=l0, p=0,
                         noise_blocks=(tuple(range(l0)),), noise_keys=(0,))
