"""N vehicles on a communication graph, stacked into the paper's system (eq. 1-6).

Vehicle i (1..N) with model (A_ii, B1i, B2i, C_i) from :mod:`plant_model.vehicles` runs the
consensus protocol of eq. 1 on top of its own dynamics, with a coupling matrix Gamma on
the state (identity by default) and formation offsets delta_i (state space) / d_i (output):

    x_i' = A_ii x_i + B1i u_i + B2i w_i + m_i
           + Gamma [ sum_j a_ij ((x_j - delta_j) - (x_i - delta_i)) + a_i0 (x_0 - (x_i - delta_i)) ]
    y_i  = C_i x_i + n_i,      target of vehicle i: H_l z_l + d_i

where x_0 = T_i z_l is the leader's state in the vehicle's state space
(:func:`plant_model.vehicle_targets.leader_state_map`). Stacked (L the in-degree Laplacian,
G = diag(a_i0), :mod:`plant_model.graph`):

    A  = blkdiag(A_ii) - (L + G) kron Gamma
    Bz = [ (G kron Gamma) blkdiag(T_i) ,  ((L + G) kron Gamma) delta ]  acting on z = [z_l; c]
    H  = [ 1_N kron H_l ,  d ]                                          (c == 1 carries the offsets)
    B1, B2, C, K, Q, R and the noise intensities block diagonal per vehicle

``consensus = "protocol"`` (in the spec's ``graph``) takes the protocol out of the
physics: the plant is blkdiag(A_ii) with Bz = 0 and the controller applies the protocol as
a force, u_cons = Kc [x; w; z] with B1 Kc = [-(L + G) kron Gamma, 0, Bz] (Kc = blkdiag(B1i^+)
times that; it exists iff Gamma's range lies within every B1i's range). The returned
system carries a :class:`ConsensusProtocol` in ``meta["consensus"]``: the in-plant system
the law is designed on, and Kc. Held over a step, the force makes the same sampled loop as
the co-simulation; the in-plant form differs from it by O(h).

The constant state c (F entry 0, no noise, c(0) = 1) is appended to the leader's state
only when some offset is non-zero. The leader z_l' = F_l z_l (+ m_z) is shared by all
vehicles. Each vehicle's disturbance is its own exosystem: an ocean current as a
first-order Gauss-Markov process per axis (w' = -w / tau + m_w, stationary standard
deviation sigma in m/s, intensity 2 sigma^2 / tau), or K_i, W_w,i given explicitly.

The fleet is described by a JSON-ready ``spec`` (built by the scenario loader, shipped in
the FMUs' resources and rebuilt from their parameters):

    {"vehicles": [{"model", "params", "x0", "offset", "current" | "disturbance",
                   "W_x", "V_y", "V_ybar", "Q", "R"}, ...],
     "graph": {"edges": [[j, i, a_ij], ...], "pinning": [[i, a_i0], ...], "coupling"},
     "leader": {"kind", "F", "H", "z0", "W_z"},
     "noise_convention": "intensity" | "per_sample"}
"""
from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.linalg import block_diag

from .bounds import Bound
from .graph import CommunicationGraph, communication_graph
from .linalg_checks import ModelError, as_matrix, as_vector
from .system import LinearSystem
from .vehicle_models import DEFAULT_MODEL, get, make_vehicle
from .vehicle_targets import leader_state_map, state_offset
from .vehicles import VehicleModel

__all__ = ["CONSENSUS_FORMS", "CURRENT_SPEED", "MAX_CURRENT_SPEED", "check_current_speeds",
           "ConsensusProtocol", "FleetInfo", "consensus_force_gain",
           "fleet_vehicles", "fleet_graph", "fleet_system", "fleet_info", "disturbance_of",
           "resolve_fleet_spec"]

#: where the consensus protocol of eq. 1 acts: in the plant's dynamics (the paper's
#: stacked model) or as a force the controller applies (what a real fleet does)
CONSENSUS_FORMS = ("in-plant", "protocol")


@dataclass(frozen=True, eq=False)
class ConsensusProtocol:
    """The protocol as control: u = u_design + gain [x; w; z] (held over each step).

    ``design`` is the in-plant stacked system the tracking law is designed on; ``gain``
    (m x (n + r + l), N and N s/m for remus100) satisfies B1 gain = [-(L + G) kron Gamma,
    0, Bz] of that system.
    """

    design: LinearSystem
    gain: np.ndarray


def consensus_force_gain(B: Any, coupling: Any,
                         state_names: tuple[str, ...] | None = None) -> np.ndarray:
    """Kc = B^+ Gamma: the consensus protocol of eq. 1 as a force through the actuators.

    The in-plant protocol adds Gamma (sum_j a_ij ((x_j - delta_j) - (x_i - delta_i))
    + a_i0 (x_0 - (x_i - delta_i))) to x_i'; as control it is u_i += Kc (...) with
    B Kc = Gamma, which exists iff range(Gamma) lies in range(B): (I - B B^+) Gamma = 0.
    For ``remus100`` with formation-4's coupling (0.02 on positions, 0.2 on velocities, in the
    velocity rows) Kc = diag(M_a) [0.02 I, 0.2 I] (N/m, N s/m); the identity coupling also
    acts on the position rows, which no force reaches, and is refused.

    Parameters
    ----------
    B : Any
        The vehicle's input matrix, p x m.
    coupling : Any
        Gamma, p x p.
    state_names : tuple[str, ...] or None, optional
        Names of the states for the message.

    Returns
    -------
    np.ndarray
        Kc, m x p (input units per state unit).

    Raises
    ------
    ModelError
        Naming the state rows of Gamma outside the actuators' reach.
    """
    B = as_matrix("B", B)
    p = B.shape[0]
    Gam = as_matrix("coupling", coupling, (p, p))
    Bp = np.linalg.pinv(B)
    miss = Gam - B @ (Bp @ Gam)
    tol = 1e-9 * max(1.0, float(np.abs(Gam).max(initial=0.0)))
    rows = np.flatnonzero(np.abs(miss).max(axis=1) > tol)
    if rows.size:
        names = state_names or tuple(f"x{k + 1}" for k in range(p))
        raise ModelError(
            "the coupling matrix acts outside the actuators' reach (range of Gamma not within "
            f"the range of B1): its rows for {', '.join(names[k] for k in rows)} cannot be "
            "produced by any force; couple through the rows B1 reaches (e.g. accelerations)")
    return Bp @ Gam


#: the strongest ocean current a scenario may give (m/s): a current's stationary standard
#: deviation per axis and each axis of its start; about the fastest tidal races on Earth
#: (Saltstraumen, some 20 knots)
MAX_CURRENT_SPEED = 10.0
#: the bound of a current's speed per axis (m/s), as a :class:`~.bounds.Bound`
CURRENT_SPEED = Bound(0.0, MAX_CURRENT_SPEED, lo_closed=True, hi_closed=True, unit="m/s",
                      why="beyond it: faster than the fastest tidal currents on Earth")


def check_current_speeds(name: str, w0: np.ndarray) -> np.ndarray:
    """``w0`` (m/s per axis) within +-:data:`MAX_CURRENT_SPEED`, else one line naming the
    entry (``name[k]``), its value and the bound."""
    for k, x in enumerate(np.asarray(w0, float).ravel(), start=1):
        if abs(x) > MAX_CURRENT_SPEED:
            raise ModelError(f"{name}[{k}] = {x:g} m/s is beyond +-{MAX_CURRENT_SPEED:g} m/s "
                             f"({CURRENT_SPEED.why})")
    return w0


def fleet_vehicles(spec: Mapping[str, Any]) -> list[VehicleModel]:
    """The vehicle models of the spec, checked to share one state dimension.

    Parameters
    ----------
    spec : Mapping[str, Any]
        The fleet spec (module docstring); reads ``vehicles``.

    Returns
    -------
    list[VehicleModel]
        One model per vehicle, in vehicle order.

    Raises
    ------
    ModelError
        If there is no vehicle, a model is invalid, or the vehicles differ in their
        numbers of states or outputs.
    """
    vehicles = spec.get("vehicles") or []
    if not vehicles:
        raise ModelError("the fleet has no vehicles")
    built: dict[str, VehicleModel] = {}       # vehicles of one model and parameters: one
    models = []                               # build (a fleet of 100 REMUS: 1, not 100)
    for i, v in enumerate(vehicles, start=1):
        model, params = v.get("model", DEFAULT_MODEL), v.get("params", {})
        key = json.dumps([model, params], sort_keys=True, default=repr)
        if key not in built:
            built[key] = make_vehicle(model, params, f"vehicle {i}")
        models.append(built[key])
    p, s = models[0].p, models[0].s
    for i, mdl in enumerate(models[1:], start=2):
        if mdl.p != p or mdl.s != s:
            raise ModelError(
                f"vehicle {i}: model {mdl.name} has {mdl.p} states and {mdl.s} outputs, "
                f"vehicle 1 has {p} and {s}; vehicles coupled on a graph must share both")
    return models


def fleet_graph(spec: Mapping[str, Any]) -> CommunicationGraph:
    """The communication graph of the spec (validated: weights, self-loops, reachability).

    Parameters
    ----------
    spec : Mapping[str, Any]
        The fleet spec; reads ``vehicles`` (their number) and ``graph``.

    Returns
    -------
    CommunicationGraph
        :func:`plant_model.graph.communication_graph` of the spec's edges and pinning
        (its ModelError if they do not make a valid graph).
    """
    g = spec.get("graph", {})
    return communication_graph(len(spec["vehicles"]), g.get("edges", []), g.get("pinning", []))


def _square(name: str, value: Any, size: int) -> np.ndarray:
    if np.ndim(value) == 0:
        return float(value) * np.eye(size)
    return as_matrix(name, value, (size, size))


def disturbance_of(vehicle: Mapping[str, Any], r: int,
                   where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(K_i, W_w,i, w0_i) of one vehicle: a Gauss-Markov current or explicit matrices.

    A current of correlation time tau (s) and stationary standard deviation sigma (m/s)
    per axis gives K_i = -I / tau (1/s) and W_w,i = (2 sigma^2 / tau) I (m^2/s^3).

    Parameters
    ----------
    vehicle : Mapping[str, Any]
        One vehicle's entry of the spec; reads ``current`` (time_constant, default
        600 s; sigma, default 0 m/s; w0) or ``disturbance`` (K, W_w, w0).
    r : int
        Number of disturbance states of the vehicle.
    where : str
        Prefix of the error messages (e.g. "vehicle 3").

    Returns
    -------
    K : np.ndarray
        Disturbance exosystem matrix, r x r.
    W_w : np.ndarray
        Intensity of the disturbance process noise, r x r.
    w0 : np.ndarray
        Initial disturbance state, shape (r,) (m/s for a current).

    Raises
    ------
    ModelError
        If both or invalid entries are given.
    """
    if "current" in vehicle and "disturbance" in vehicle:
        raise ModelError(f"{where}: give either 'current' or 'disturbance', not both")
    if "disturbance" in vehicle:
        d = vehicle["disturbance"]
        K = as_matrix(f"{where} disturbance K", d["K"], (r, r))
        W = _square(f"{where} disturbance W_w", d.get("W_w", 0.0), r)
        w0 = as_vector(f"{where} disturbance w0", d.get("w0", np.zeros(r)), r)
        return K, W, w0
    c = vehicle.get("current", {})
    tau = float(c.get("time_constant", 600.0))
    sigma = float(c.get("sigma", 0.0))
    if not (np.isfinite(tau) and tau > 0):
        raise ModelError(f"{where}: current time_constant = {tau} must be a positive "
                         "number of seconds")
    if not (np.isfinite(sigma) and sigma >= 0):
        raise ModelError(f"{where}: current sigma = {sigma} must be a non-negative speed in m/s")
    CURRENT_SPEED.check(f"{where}: current sigma", sigma)
    w0 = check_current_speeds(f"{where} current w0",
                              as_vector(f"{where} current w0", c.get("w0", np.zeros(r)), r))
    return -np.eye(r) / tau, (2.0 * sigma ** 2 / tau) * np.eye(r), w0


def _offsets(spec: Mapping[str, Any], models: list[VehicleModel]) -> tuple[np.ndarray, np.ndarray]:
    """(d, delta): output-space offsets (N, s) and state-space offsets (N, p)."""
    s = models[0].s
    d = np.zeros((len(models), s))
    delta = np.zeros((len(models), models[0].p))
    for i, (v, mdl) in enumerate(zip(spec["vehicles"], models)):
        d[i] = as_vector(f"vehicle {i + 1} offset", v.get("offset", np.zeros(s)), s)
        delta[i] = state_offset(mdl, d[i])
    return d, delta


def noise_blocks(N: int, p: int, r: int, s: int, l_: int) -> tuple[tuple[int, ...], ...]:
    """The independent noise streams of a fleet whose protocol is a force: per vehicle
    i = 1..N the positions of its process noise (x_i, w_i) and sensor noise (y_i, ybar_i) in
    the noise row [v; n; n_z] of the stacked model, then the leader's (z).

    With no coupling in the physics the sampled process noise is block diagonal by vehicle,
    so each vehicle (and the leader) can draw its own: vehicle i from the generator seeded
    [seed, i], the leader from [seed, 0] (:class:`plant_model.plant.NoiseStream`), which a
    per-vehicle plant reproduces alone.

    Parameters
    ----------
    N, p, r, s, l_ : int
        Vehicles, states, disturbance states and outputs per vehicle; leader states.

    Returns
    -------
    tuple[tuple[int, ...], ...]
        N + 1 tuples of positions.
    """
    n, ns, P = N * p, N * (p + r) + l_, N * s
    blocks = []
    for i in range(N):
        blocks.append(tuple(range(i * p, (i + 1) * p))
                      + tuple(range(n + i * r, n + (i + 1) * r))
                      + tuple(range(ns + i * s, ns + (i + 1) * s))
                      + tuple(range(ns + P + i * s, ns + P + (i + 1) * s)))
    blocks.append(tuple(range(n + N * r, ns)))
    return tuple(blocks)


def fleet_system(spec: Mapping[str, Any], *, models: Sequence[VehicleModel] | None = None,
                 graph: CommunicationGraph | None = None) -> LinearSystem:
    """The stacked :class:`LinearSystem` of the fleet (see the module docstring).

    A = blkdiag(A_ii) - (L + G) kron Gamma, Bz = [(G kron Gamma) blkdiag(T_i),
    ((L + G) kron Gamma) delta], H = [1_N kron H_l, d]; the other matrices are block
    diagonal per vehicle.

    Parameters
    ----------
    spec : Mapping[str, Any]
        The fleet spec (module docstring).
    models, graph : optional
        Its vehicle models and graph when already parsed
        (:class:`plant_model.fleet_model.Fleet`).

    Returns
    -------
    LinearSystem
        The validated stacked system (N p states, N q inputs, N r disturbance states,
        N s outputs).

    Raises
    ------
    ModelError
        Naming the vehicle, graph or leader entry that is invalid.
    """
    models = list(models) if models is not None else fleet_vehicles(spec)
    graph = graph if graph is not None else fleet_graph(spec)
    N, p = len(models), models[0].p
    leader = spec["leader"]
    F_l = as_matrix("leader F", leader["F"])
    l0 = F_l.shape[0]
    F_l = as_matrix("leader F", F_l, (l0, l0))
    H_l = as_matrix("leader H", leader["H"], (models[0].s, l0))
    z0_l = as_vector("leader z0", leader.get("z0", np.zeros(l0)), l0)
    coupling = spec.get("graph", {}).get("coupling")
    Gam = np.eye(p) if coupling is None else as_matrix("graph coupling", coupling, (p, p))
    LG = graph.consensus_matrix()
    Gp = graph.pinning_matrix()
    d, delta = _offsets(spec, models)
    has_c = bool(np.any(d != 0.0) or np.any(delta != 0.0))
    l_ = l0 + (1 if has_c else 0)

    A = block_diag(*[mdl.A for mdl in models]) - np.kron(LG, Gam)
    Ts = [leader_state_map(mdl, H_l, F_l) for mdl in models]
    Bz = np.zeros((N * p, l_))
    Bz[:, :l0] = np.kron(Gp, Gam) @ np.vstack(Ts)
    if has_c:
        Bz[:, l0] = np.kron(LG, Gam) @ delta.reshape(-1)
    F = np.zeros((l_, l_))
    F[:l0, :l0] = F_l
    H = np.zeros((N * models[0].s, l_))
    H[:, :l0] = np.kron(np.ones((N, 1)), H_l)
    if has_c:
        H[:, l0] = d.reshape(-1)
    z0 = np.concatenate([z0_l, [1.0]]) if has_c else z0_l
    W_z = np.zeros((l_, l_))
    W_z[:l0, :l0] = _square("leader W_z", leader.get("W_z", 0.0), l0)

    Ks, Ws, w0s, x0s = [], [], [], []
    for i, (v, mdl) in enumerate(zip(spec["vehicles"], models), start=1):
        K, W, w0 = disturbance_of(v, mdl.r, f"vehicle {i}")
        Ks.append(K)
        Ws.append(W)
        w0s.append(w0)
        x0 = v.get("x0")
        x0s.append(Ts[i - 1] @ z0_l + delta[i - 1] if x0 is None
                   else as_vector(f"vehicle {i} x0", x0, p))

    def per_vehicle(key: str, size: Any, default: float) -> np.ndarray:
        return block_diag(*[_square(f"vehicle {i} {key}", v.get(key, default), size(mdl))
                            for i, (v, mdl) in enumerate(zip(spec["vehicles"], models), start=1)])

    mapping = {
        "A": A, "B1": block_diag(*[mdl.B1 for mdl in models]),
        "B2": block_diag(*[mdl.B2 for mdl in models]), "Bz": Bz,
        "C": block_diag(*[mdl.C for mdl in models]),
        "F": F, "H": H, "K": block_diag(*Ks),
        "x0": np.concatenate(x0s), "w0": np.concatenate(w0s), "z0": z0,
        "Q": per_vehicle("Q", lambda m: m.s, 1.0), "R": per_vehicle("R", lambda m: m.q, 1.0),
        "W_x": per_vehicle("W_x", lambda m: m.p, 0.0), "W_w": block_diag(*Ws), "W_z": W_z,
        "V_y": per_vehicle("V_y", lambda m: m.s, 0.0),
        "V_ybar": per_vehicle("V_ybar", lambda m: m.s, 0.0),
        "noise_convention": spec.get("noise_convention", "intensity"),
    }
    form = spec.get("graph", {}).get("consensus", "in-plant")
    if form not in CONSENSUS_FORMS:
        raise ModelError(f"graph consensus = {form!r} is not one of {', '.join(CONSENSUS_FORMS)}")
    if form == "in-plant":
        return LinearSystem.from_mapping(mapping)
    design = LinearSystem.from_mapping(mapping)
    for mdl in models:
        consensus_force_gain(mdl.B1, Gam, mdl.state_names)  # refuses an unreachable coupling
    Bplus = block_diag(*[np.linalg.pinv(mdl.B1) for mdl in models])
    r = design.r
    gain = np.zeros((design.m, N * p + r + l_))
    gain[:, :N * p] = -Bplus @ np.kron(LG, Gam)
    gain[:, N * p + r:] = Bplus @ Bz
    physics = dict(mapping, A=block_diag(*[mdl.A for mdl in models]), Bz=np.zeros_like(Bz),
                   meta={"consensus": ConsensusProtocol(design=design, gain=gain),
                         "noise_blocks": noise_blocks(N, p, models[0].r, models[0].s, l_)})
    return LinearSystem.from_mapping(physics)


def resolve_fleet_spec(spec: Mapping[str, Any]) -> dict[str, Any]:
    """A copy of ``spec`` with every default made explicit.

    Model parameters, x0, offset, current and coupling are filled in, so that an FMU can
    expose all of them as parameters with their values; edges and pinning are normalized.
    ``spec`` is the fleet spec of the module docstring; the result a new, JSON-ready spec.
    Raises ModelError if the spec is invalid.
    """
    import copy
    new = copy.deepcopy(dict(spec))
    models = fleet_vehicles(new)
    system = fleet_system(new)
    p = models[0].p
    for i, (v, mdl) in enumerate(zip(new["vehicles"], models)):
        v["params"] = get(mdl.name).explicit_params(mdl)
        v["x0"] = system.x0[i * p:(i + 1) * p].tolist()
        v["offset"] = list(np.asarray(v.get("offset", np.zeros(mdl.s)), dtype=float))
        if "disturbance" not in v:
            K, W, w0 = disturbance_of(v, mdl.r, f"vehicle {i + 1}")
            cur = v.setdefault("current", {})
            cur["time_constant"] = float(-1.0 / K[0, 0])
            cur.setdefault("sigma", 0.0)
            cur["w0"] = w0.tolist()
    g = new.setdefault("graph", {})
    if g.get("coupling") is None:
        g["coupling"] = np.eye(p).tolist()
    graph = fleet_graph(new)            # the validated, normalised edges and pins
    g["edges"] = [[j, i, a] for j, i, a in graph.edges]
    g["pinning"] = [[i, a] for i, a in graph.pinning]
    return new


@dataclass(frozen=True)
class FleetInfo:
    """Where each vehicle's quantities sit in the stacked vectors (0-based indices)."""

    N: int
    p: int                        #: states per vehicle
    q: int                        #: inputs per vehicle
    s: int                        #: outputs per vehicle
    r: int                        #: disturbance states per vehicle
    models: tuple[str, ...]
    position_index: np.ndarray | None   #: (N, 3) columns of x holding north, east, down
    leader_output: np.ndarray     #: (s, l) leader output (position) = leader_output @ z
    offsets: np.ndarray           #: (N, s) formation offsets d_i
    edges: tuple[tuple[int, int], ...]  #: (j, i), 1-based: vehicle i hears vehicle j
    pinned: tuple[int, ...]       #: 1-based vehicles that hear the leader
    output_names: tuple[str, ...]
    input_names: tuple[str, ...]
    state_names: tuple[str, ...]
    disturbance_names: tuple[str, ...]


def fleet_info(spec: Mapping[str, Any], system: LinearSystem | None = None) -> FleetInfo:
    """Layout of the stacked vectors of ``spec`` (positions, offsets, leader output).

    Parameters
    ----------
    spec : Mapping[str, Any]
        The fleet spec (module docstring).
    system : LinearSystem or None, optional
        Its stacked system, if already built (else built here).

    Returns
    -------
    FleetInfo
        Sizes per vehicle, index maps, offsets and names.
    """
    models = fleet_vehicles(spec)
    graph = fleet_graph(spec)
    system = system if system is not None else fleet_system(spec)
    N, p = len(models), models[0].p
    pos = None
    if all(mdl.position_states is not None for mdl in models):
        pos = np.array([[i * p + k for k in mdl.position_states] for i, mdl in enumerate(models)])
    d, _ = _offsets(spec, models)
    s = models[0].s
    l0 = np.asarray(spec["leader"]["F"], dtype=float).shape[0]
    leader_out = np.zeros((s, system.l))
    leader_out[:, :l0] = np.asarray(spec["leader"]["H"], dtype=float)
    return FleetInfo(
        N=N, p=p, q=models[0].q, s=s, r=models[0].r,
        models=tuple(mdl.name for mdl in models), position_index=pos,
        leader_output=leader_out,
        offsets=d, edges=tuple((int(j), int(i)) for j, i, _ in graph.edges),
        pinned=tuple(int(i) for i, _ in graph.pinning),
        output_names=models[0].output_names, input_names=models[0].input_names,
        state_names=models[0].state_names, disturbance_names=models[0].disturbance_names,
    )
