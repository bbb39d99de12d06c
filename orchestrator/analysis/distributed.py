"""The sampled closed loop of N vehicles under the distributed law: stability and cost.

The per-vehicle pieces are in :mod:`controller_fmu.distributed` (what one controller FMU
runs); this module stacks them into one linear map to judge the whole fleet. It lives here,
not in ``controller_fmu``, because it needs the per-vehicle Kalman filter
(:mod:`estimator_fmu.estimators`) and the window average of
:mod:`orchestrator.analysis.prediction`, which the controller FMU does not ship; and
because :func:`orchestrator.analysis.prediction.closed_loop` does not fit: it assumes one
estimator on one stacked plant and u = -Ks est, while the distributed controller has its own
dynamic state (the observers) and neighbour terms. The Lyapunov step and the cost formula
are the same (docs/theory.md section 6).

Per vehicle i, sampled exactly at the communication step h (zero-order hold on u_i)::

    s_i[k+1] = Ad_i s_i[k] + Bd_i u_i[k] + nu_i[k],   s_i = [x_i; w_i],   nu_i ~ N(0, Qd_i)
    y_i[k]   = C_i x_i[k] + n_i[k],                                       n_i ~ N(0, Rd_i)
    estimate: ideal   est_i = s_i
              kalman  est_i = q_i + L_i (y_i - M_i q_i),  q_i[k+1] = Ad_i est_i + Bd_i u_i
                      (the vehicle's own steady Kalman filter on its own y_i, M_i = [C_i, 0])
    observer: eta_i[k+1] = Phi eta_i + mu Gam_F (-(sum_j (L+G)_ij eta_j) + a_i0 v)
    law:      eps_i = [I, -Xw_i] est_i - X_i eta_i - xc_i c
              u_i   = U_i eta_i + [0, Uw_i] est_i + uc_i c - Kx_i eps_i
                      - c_coh Kx_i sum_j (L+G)_ij eps_j
    leader:   v[k+1] = Phi v[k]  (a planned path, noise-free),  c = 1 carries the offsets
    error:    e_i = H v + d_i c - C_i x_i          (scored, as everywhere, on the truth)

Stacked, X = [v; c; s_1..s_N; q_1..q_N (kalman); eta_1..eta_N] and the noise of one step
zeta = [nu_1..nu_N; n_1..n_N] with covariance W = blkdiag(Qd_i, Rd_i)::

    X[k+1] = Phi_cl X[k] + Gam zeta[k],  u[k] = Gx X[k] + Geta zeta[k],  e[k] = Ce X[k]

[v; c] is autonomous (and never settles); the rest (the *error part*) is what must be
stable. For identical vehicles (same model, gain and filter; offsets may differ) the error
part is I_N kron M0 + (L + G) kron M1 in per-vehicle order, so in the Schur basis of L + G it
is block triangular with blocks M0 + lambda M1, one per eigenvalue lambda of L + G:
:func:`stability_verdict` judges each block (exact) and names the failing lambda.
Continuous-time sufficient bounds reported beside it: observer mu > max Re f / min Re lambda
(any mu > 0 for a marginally stable F); cohesion: any c >= 0 (the blocks
A - (1 + c lambda) B Kx are Hurwitz since Re(1 + c lambda) >= 1/2, the LQ gain margin).

The stability verdict and the cost prediction of such a loop are in
:mod:`orchestrator.analysis.distributed_verdict`.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.linalg import block_diag

from controller_fmu.distributed import (
    SampledObserver,
    VehicleLaw,
    design_vehicle_law,
)
from estimator_fmu.estimators import steady_kalman
from estimator_fmu.registry import ESTIMATORS as _ROWS
from estimator_fmu.registry import TRUTH, estimator_kind
from plant_model.discretization import van_loan, zoh
from plant_model.fleet import disturbance_of, fleet_graph, fleet_vehicles
from plant_model.fleet_model import Fleet
from plant_model.graph import CommunicationGraph
from plant_model.linalg_checks import ModelError, as_matrix, as_vector

__all__ = ["Agent", "DistributedLoop", "SampledAgent", "agents_from_fleet_spec",
           "fleet_agents",
           "design_laws", "distributed_closed_loop", "filtered", "sample_agent"]

#: the estimators the distributed law accepts (their registry rows' ``distributed``)
ESTIMATORS = tuple(k.name for k in _ROWS.values() if k.distributed is not None)


def filtered(estimator: str) -> bool:
    """Whether each vehicle runs its own steady Kalman filter (q in the loop) under the
    distributed law, rather than the truth."""
    return estimator_kind(estimator).distributed == "steady"


@dataclass(frozen=True, eq=False)
class Agent:
    """One vehicle as plain arrays: model, own disturbance, noise intensities, cost, offset."""

    A: np.ndarray        #: p x p, 1/s
    B: np.ndarray        #: p x m
    C: np.ndarray        #: s x p
    E: np.ndarray        #: p x r (disturbance input)
    Kw: np.ndarray       #: r x r, the disturbance's exosystem, 1/s
    Q: np.ndarray        #: s x s, output error weight
    R: np.ndarray        #: m x m, input weight
    W_x: np.ndarray      #: p x p, process noise intensity on x
    W_w: np.ndarray      #: r x r, process noise intensity on w
    V_y: np.ndarray      #: s x s, measurement noise intensity
    offset: np.ndarray   #: (s,), formation offset d_i
    x0: np.ndarray       #: (p,)
    w0: np.ndarray       #: (r,)

    @property
    def ns(self) -> int:
        """Length of the sampled state s_i = [x_i; w_i]."""
        return self.A.shape[0] + self.E.shape[1]


def _square(name: str, value: Any, size: int) -> np.ndarray:
    if np.ndim(value) == 0:
        return float(value) * np.eye(size)
    return as_matrix(name, value, (size, size))


def fleet_agents(fleet: Fleet) -> tuple[list[Agent], CommunicationGraph,
                                         dict[str, np.ndarray]]:
    """:func:`agents_from_fleet_spec` of a parsed fleet, made once and kept with it (the
    agents are not changed by their users: they are frozen dataclasses)."""
    if "agents" not in fleet.memo:
        fleet.memo["agents"] = _agents(fleet.spec, list(fleet.models), fleet.graph)
    agents, graph, leader = fleet.memo["agents"]
    return list(agents), graph, dict(leader)


def agents_from_fleet_spec(spec: Mapping[str, Any]) -> tuple[list[Agent], CommunicationGraph,
                                                            dict[str, np.ndarray]]:
    """The vehicles, graph and leader of a fleet spec (:mod:`plant_model.fleet`).

    Parameters
    ----------
    spec : Mapping[str, Any]
        The fleet spec.

    Returns
    -------
    agents : list[Agent]
        Per vehicle; x0 defaults to the leader's state plus the offset, as in the fleet.
    graph : CommunicationGraph
        The validated graph.
    leader : dict[str, np.ndarray]
        ``F``, ``H``, ``z0``.
    """
    return _agents(spec, fleet_vehicles(spec), fleet_graph(spec))


def _agents(spec: Mapping[str, Any], models: list[Any], graph: CommunicationGraph
            ) -> tuple[list[Agent], CommunicationGraph, dict[str, np.ndarray]]:
    ld = spec["leader"]
    F = as_matrix("leader F", ld["F"])
    H = as_matrix("leader H", ld["H"], (models[0].s, F.shape[0]))
    z0 = as_vector("leader z0", ld.get("z0", np.zeros(F.shape[0])), F.shape[0])
    agents = []
    for i, (v, mdl) in enumerate(zip(spec["vehicles"], models), start=1):
        where = f"vehicle {i}"
        Kw, Ww, w0 = disturbance_of(v, mdl.r, where)
        d = as_vector(f"{where} offset", v.get("offset", np.zeros(mdl.s)), mdl.s)
        x0 = v.get("x0")
        agents.append(Agent(
            A=mdl.A, B=mdl.B1, C=mdl.C, E=mdl.B2, Kw=Kw,
            Q=_square(f"{where} Q", v.get("Q", 1.0), mdl.s),
            R=_square(f"{where} R", v.get("R", 1.0), mdl.q),
            W_x=_square(f"{where} W_x", v.get("W_x", 0.0), mdl.p), W_w=Ww,
            V_y=_square(f"{where} V_y", v.get("V_y", 0.0), mdl.s), offset=d,
            x0=(np.linalg.pinv(mdl.C) @ (H @ z0 + d) if x0 is None
                else as_vector(f"{where} x0", x0, mdl.p)),
            w0=w0))
    return agents, graph, {"F": F, "H": H, "z0": z0}


def design_laws(agents: Sequence[Agent], F: Any, H: Any, *, regulator: str = "continuous",
                h: float | None = None) -> list[VehicleLaw]:
    """:func:`controller_fmu.distributed.design_vehicle_law` for every vehicle.

    Parameters
    ----------
    agents : Sequence[Agent]
        The vehicles.
    F, H : Any
        Leader exosystem (1/s) and its tracked output.
    regulator : str, optional
        ``continuous`` or ``sampled`` (:data:`controller_fmu.distributed.REGULATOR_FORMS`).
    h : float or None, optional
        Communication step, s (for the sampled form).

    Returns
    -------
    list[VehicleLaw]
        One law per vehicle.
    """
    return [design_vehicle_law(a.A, a.B, a.C, a.Q, a.R, F, H, a.offset, a.E, a.Kw,
                               regulator=regulator, h=h, where=f"vehicle {i}: ")
            for i, a in enumerate(agents, start=1)]


@dataclass(frozen=True, eq=False)
class SampledAgent:
    """One vehicle sampled at h: s+ = Ad s + Bd u + nu, y = M s + n; its Kalman gain."""

    Ad: np.ndarray
    Bd: np.ndarray
    Qd: np.ndarray
    Rd: np.ndarray
    M: np.ndarray
    L: np.ndarray | None    #: current-estimator gain (kalman), ns x s


def sample_agent(agent: Agent, h: float, *, convention: str = "intensity",
                 estimator: str = TRUTH, where: str = "vehicle") -> SampledAgent:
    """Exact ZOH of [x; w] (zoh), Van Loan's Qd, Rd = V_y / h; the vehicle's own Kalman gain.

    Parameters
    ----------
    agent : Agent
        The vehicle.
    h : float
        Communication step, s.
    convention : str, optional
        ``intensity`` (W, V are intensities) or ``per_sample`` (covariances per step).
    estimator : str, optional
        ``ideal`` or ``kalman``.
    where : str, optional
        Names the vehicle in error messages.

    Returns
    -------
    SampledAgent
        The sampled matrices.
    """
    p, r = agent.A.shape[0], agent.E.shape[1]
    Ac = np.zeros((p + r, p + r))
    Ac[:p, :p], Ac[:p, p:], Ac[p:, p:] = agent.A, agent.E, agent.Kw
    Bc = np.vstack([agent.B, np.zeros((r, agent.B.shape[1]))])
    Ad, Bd = zoh(Ac, Bc, h)
    Wc = block_diag(agent.W_x, agent.W_w)
    if convention == "intensity":
        Qd, Rd = van_loan(Ac, Wc, h), agent.V_y / h
    elif convention == "per_sample":
        Qd, Rd = Wc.copy(), agent.V_y.copy()
    else:
        raise ModelError(f"unknown noise convention {convention!r}")
    M = np.hstack([agent.C, np.zeros((agent.C.shape[0], r))])
    if estimator_kind(estimator).distributed is None:
        raise ModelError(f"estimator {estimator!r} is not accepted by the distributed loop; "
                         f"expected one of {', '.join(ESTIMATORS)}")
    L = steady_kalman(f"{where} [x; w]", Ad, M, Qd, Rd).L if filtered(estimator) else None
    return SampledAgent(Ad=Ad, Bd=Bd, Qd=Qd, Rd=Rd, M=M, L=L)


@dataclass(frozen=True, eq=False)
class DistributedLoop:
    """X[k+1] = Phi X + Gam zeta, u = Gx X + Geta zeta, e = Ce X (module docstring)."""

    Phi: np.ndarray
    Gam: np.ndarray
    W: np.ndarray            #: covariance of zeta
    Gx: np.ndarray
    Geta: np.ndarray
    Ce: np.ndarray
    Qc: np.ndarray           #: blkdiag(Q_i)
    Rc: np.ndarray           #: blkdiag(R_i)
    deterministic: np.ndarray  #: mask of [v; c] in X
    #: 's', 'q', 'eta' slices of X per vehicle; 'v', 'c'; 'zeta_nu', 'zeta_n': each
    #: vehicle's process and sensor noise in zeta
    index: dict[str, list[slice]]
    h: float
    # the pieces, for the per-eigenvalue verdict
    sampled: tuple[SampledAgent, ...]
    laws: tuple[VehicleLaw, ...]
    observer: SampledObserver
    LG: np.ndarray
    cohesion: float
    estimator: str

    def initial_state(self, v0: Any, x0s: Sequence[Any], w0s: Sequence[Any],
                      eta0s: Sequence[Any] | None = None) -> np.ndarray:
        """X(0): leader v0, c = 1, vehicles [x0; w0], Kalman q0 = [x0; w0], eta0 (default 0).

        Parameters
        ----------
        v0 : Any
            Leader state at t = 0.
        x0s, w0s : Sequence[Any]
            Per vehicle initial state and disturbance.
        eta0s : Sequence[Any] or None, optional
            Per vehicle initial observer state (default zero).

        Returns
        -------
        np.ndarray
            X(0).
        """
        X = np.zeros(self.Phi.shape[0])
        X[self.index["v"][0]] = v0
        X[self.index["c"][0]] = 1.0
        for i, sl in enumerate(self.index["s"]):
            X[sl] = np.concatenate([np.asarray(x0s[i], float), np.asarray(w0s[i], float)])
            if self.index["q"]:
                X[self.index["q"][i]] = X[sl]
            if eta0s is not None:
                X[self.index["eta"][i]] = eta0s[i]
        return X


def estimate_rows(sa: SampledAgent, s: slice, q: slice | None, n: slice, nX: int, nZ: int,
                  dtype: Any = float) -> tuple[np.ndarray, np.ndarray]:
    """est = [xhat; what] = Ex X + En zeta of one vehicle: the truth s (ideal, ``q`` None) or
    its current Kalman estimate q + L (y - M q), y = M s + n.

    Parameters
    ----------
    sa : SampledAgent
        The vehicle.
    s, q, n : slice, slice or None, slice
        Its sampled state and Kalman state in X, its sensor noise in zeta.
    nX, nZ : int
        Sizes of X and zeta.
    dtype : Any, optional
        float, or complex for the per-eigenvalue blocks.

    Returns
    -------
    tuple[np.ndarray, np.ndarray]
        (Ex, En).
    """
    ns = sa.Ad.shape[0]
    Ex, En = np.zeros((ns, nX), dtype), np.zeros((ns, nZ), dtype)
    if q is not None:
        Ex[:, q] = np.eye(ns) - sa.L @ sa.M
        Ex[:, s] = sa.L @ sa.M
        En[:, n] = sa.L
    else:
        Ex[:, s] = np.eye(ns)
    return Ex, En


def add_vehicle_rows(Phi: np.ndarray, Gam: np.ndarray, sampled: Sequence[SampledAgent],
                     idx: Mapping[str, list[slice]], nu: Sequence[slice],
                     Ux: Sequence[np.ndarray], Un: Sequence[np.ndarray],
                     Estx: Sequence[np.ndarray], Estn: Sequence[np.ndarray],
                     kalman: bool) -> None:
    """Add every vehicle's rows to the loop, in place: s_i+ = Ad s_i + Bd u_i + nu_i and,
    with Kalman estimates, q_i+ = Ad est_i + Bd u_i (u_i = Ux X + Un zeta, est_i = Estx X +
    Estn zeta)."""
    for i, sa in enumerate(sampled):
        si = idx["s"][i]
        Phi[si, si] += sa.Ad
        Phi[si] += sa.Bd @ Ux[i]
        Gam[si, nu[i]] += np.eye(sa.Ad.shape[0])
        Gam[si] += sa.Bd @ Un[i]
        if kalman:
            qi = idx["q"][i]
            Phi[qi] += sa.Ad @ Estx[i] + sa.Bd @ Ux[i]
            Gam[qi] += sa.Ad @ Estn[i] + sa.Bd @ Un[i]


def _assemble(sampled: Sequence[SampledAgent], laws: Sequence[VehicleLaw], LG: np.ndarray,
              g: np.ndarray, obs: SampledObserver, H: np.ndarray, offsets: Sequence[np.ndarray],
              cohesion: float, kalman: bool,
              outputs: Sequence[np.ndarray] | None = None) -> dict[str, Any]:
    """The stacked matrices (real, or complex when LG is: the per-eigenvalue blocks).
    ``outputs``: each vehicle's output matrix [C, 0] of its errors when its measurement
    rows M are other sensors (default: M)."""
    N = len(sampled)
    l_ = obs.Phi.shape[0]
    dt = complex if np.iscomplexobj(LG) else float
    ns = [sa.Ad.shape[0] for sa in sampled]
    ps = [law.Kx.shape[1] for law in laws]
    ms = [law.Kx.shape[0] for law in laws]
    ss = [sa.M.shape[0] for sa in sampled]
    # indices in X
    pos = l_ + 1
    idx: dict[str, list[slice]] = {"v": [slice(0, l_)], "c": [slice(l_, l_ + 1)], "s": [],
                                   "q": [], "eta": []}
    for n in ns:
        idx["s"].append(slice(pos, pos + n))
        pos += n
    if kalman:
        for n in ns:
            idx["q"].append(slice(pos, pos + n))
            pos += n
    for _ in range(N):
        idx["eta"].append(slice(pos, pos + l_))
        pos += l_
    nX = pos
    # indices in zeta
    nu, nn, pos = [], [], 0
    for n in ns:
        nu.append(slice(pos, pos + n))
        pos += n
    for s in ss:
        nn.append(slice(pos, pos + s))
        pos += s
    nZ = pos
    ic, iv = l_, idx["v"][0]
    # estimates est_i = Ex X + En zeta, then eps_i = Px X + Pn zeta
    Epsx = [np.zeros((p, nX), dt) for p in ps]
    Epsn = [np.zeros((p, nZ), dt) for p in ps]
    Ux = [np.zeros((m, nX), dt) for m in ms]
    Un = [np.zeros((m, nZ), dt) for m in ms]
    Estx, Estn = [], []
    for i, (sa, law) in enumerate(zip(sampled, laws)):
        Ex, En = estimate_rows(sa, idx["s"][i], idx["q"][i] if kalman else None, nn[i], nX,
                               nZ, dt)
        Estx.append(Ex)
        Estn.append(En)
        T = np.hstack([np.eye(ps[i]), -law.Xw])
        Epsx[i] = T @ Ex
        Epsx[i][:, idx["eta"][i]] -= law.X
        Epsx[i][:, ic] -= law.xc
        Epsn[i] = T @ En
        Sw = np.hstack([np.zeros((ms[i], ps[i])), law.Uw])
        Ux[i] = Sw @ Ex - law.Kx @ Epsx[i]
        Ux[i][:, idx["eta"][i]] += law.U
        Ux[i][:, ic] += law.uc
        Un[i] = Sw @ En - law.Kx @ Epsn[i]
    if cohesion != 0.0:
        for i in range(N):
            for j in np.flatnonzero(LG[i]):
                Ux[i] -= cohesion * LG[i, j] * (laws[i].Kx @ Epsx[j])
                Un[i] -= cohesion * LG[i, j] * (laws[i].Kx @ Epsn[j])
    Gx, Geta = np.vstack(Ux), np.vstack(Un)
    Phi = np.zeros((nX, nX), dt)
    Gam = np.zeros((nX, nZ), dt)
    Phi[iv, iv] = obs.Phi
    Phi[ic, ic] = 1.0
    B = obs.B_nbr
    add_vehicle_rows(Phi, Gam, sampled, idx, nu, Ux, Un, Estx, Estn, kalman)
    for i in range(N):
        ei = idx["eta"][i]
        Phi[ei, ei] += obs.Phi
        for j in np.flatnonzero(LG[i]):
            Phi[ei, idx["eta"][j]] -= LG[i, j] * B
        Phi[ei, iv] += g[i] * B
    # errors e_i = H v + d_i c - C_i x_i
    outs = [sa.M for sa in sampled] if outputs is None else list(outputs)
    Ce = np.zeros((sum(o.shape[0] for o in outs), nX))
    row = 0
    for i, o in enumerate(outs):
        Ce[row:row + o.shape[0], iv] = H
        Ce[row:row + o.shape[0], ic] = offsets[i]
        Ce[row:row + o.shape[0], idx["s"][i]] = -o
        row += o.shape[0]
    det = np.zeros(nX, dtype=bool)
    det[:l_ + 1] = True
    W = block_diag(*[sa.Qd for sa in sampled], *[sa.Rd for sa in sampled])
    return {"Phi": Phi, "Gam": Gam, "W": W, "Gx": Gx, "Geta": Geta, "Ce": Ce,
            "deterministic": det, "index": dict(idx, zeta_nu=nu, zeta_n=nn)}


def distributed_closed_loop(agents: Sequence[Agent], laws: Sequence[VehicleLaw],
                            graph: CommunicationGraph, observer: SampledObserver, H: Any, *,
                            cohesion: float = 0.0, estimator: str = TRUTH,
                            convention: str = "intensity") -> DistributedLoop:
    """The stacked sampled closed loop of all vehicles (module docstring).

    Parameters
    ----------
    agents : Sequence[Agent]
        The vehicles.
    laws : Sequence[VehicleLaw]
        Their designs (:func:`design_laws`).
    graph : CommunicationGraph
        Who hears whom.
    observer : SampledObserver
        The sampled observer (F, h, mu) shared by all vehicles.
    H : Any
        Leader output matrix, s x l.
    cohesion : float, optional
        Coupling gain c of the cohesion term (0: off).
    estimator : str, optional
        ``ideal`` (est = truth) or ``kalman`` (each vehicle filters its own y).
    convention : str, optional
        Noise convention (docs/theory.md section 4).

    Returns
    -------
    DistributedLoop
        Phi, Gam, W, Gx, Geta, Ce and the pieces.
    """
    if len(agents) != graph.N or len(laws) != graph.N:
        raise ModelError(f"{len(agents)} vehicles and {len(laws)} laws for a graph of "
                         f"{graph.N} vehicles")
    h = observer.h
    sampled = tuple(sample_agent(a, h, convention=convention, estimator=estimator,
                                 where=f"vehicle {i}") for i, a in enumerate(agents, start=1))
    LG = graph.consensus_matrix()
    g = np.diag(graph.pinning_matrix()).copy()
    H = np.asarray(H, dtype=float)
    parts = _assemble(sampled, laws, LG, g, observer, H, [a.offset for a in agents],
                      float(cohesion), filtered(estimator))
    return DistributedLoop(**parts, Qc=block_diag(*[a.Q for a in agents]),
                           Rc=block_diag(*[a.R for a in agents]), h=h, sampled=sampled,
                           laws=tuple(laws), observer=observer, LG=LG,
                           cohesion=float(cohesion), estimator=estimator)
