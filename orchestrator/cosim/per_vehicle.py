"""The per-vehicle deployment as a system: one vehicle, estimator and controller FMU per AUV.

Components (``deployment = "per-vehicle"``): ``leader`` (AuvLeader), and per vehicle
i = 1..N ``vehicle_i`` (AuvVehicle), ``estimator_i`` (AuvVehicleEstimator) and
``controller_i`` (AuvVehicleController for ``architecture = "distributed"``,
AuvCentralController for ``"centralized"``). One FMU per kind serves every vehicle: what
differs per vehicle is parameter values (model, offset, slot weights, gain rows). Wiring::

    vehicle_i.y (x, w only in mode ideal) -> estimator_i.y (x, w)
    estimator_i.xhat, what                 -> controller_i.xhat, what
    controller_i.u                         -> vehicle_i.u, estimator_i.u
    distributed:  controller_j.eta, eps    -> controller_i.nbr[k].eta, eps  (slot k: j -> i)
                  leader.z                 -> controller_i.z                (pinned i only;
                                              none for a planned path every vehicle knows)
    centralized:  estimator_j.xhat, what   -> controller_i.vehicle[j].xhat, what  (all j)
                  leader.z                 -> controller_i.z                (all i)

Every input is connected, as SSP and OSP hosts expect: an unused neighbour slot (weight 0)
and the leader input of a vehicle that is not pinned (a0 = 0) are fed from the vehicle's
own controller (its eta and eps), which they do not weigh.

A vehicle whose model names a ``stack`` in the registry (``remus100-6dof-guided``) has its
force go through those FMUs, ``guidance_i`` and ``autopilot_i``, to a vehicle FMU that
takes actuator commands (:mod:`orchestrator.cosim.guided`); its estimator still takes u.

:func:`stacked_traces` puts the per-vehicle traces back into the stacked layout (y, x, w,
z, e, u, xhat, what of the fleet; e_i = H_l z_l + d_i - C_i x_i from the truth), so the
statistics, formation figures and recording of the stacked deployment apply unchanged.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from controller_fmu.vehicle_law import (
    ARCHITECTURES,
    DEPLOYMENTS,
    DistributedSettings,
    centralized_rows,
    observer_start,
)
from estimator_fmu.registry import TRUTH, estimator_kind
from plant_model.acoustic.links import link_sender
from plant_model.fixed_order import rows_times_transpose
from plant_model.per_vehicle import leader_system
from plant_model.system import LinearSystem
from plant_model.vehicle_fmu import fmu_port_config
from plant_model.vehicle_models import REGISTRY, get

from .build import FMU_KINDS, interface_of
from .guided import setpoint_traces, stack_configs, stack_connections
from .per_vehicle_network import network_connections
from .system import Component, Connection, SystemDescription, component_parameters

if TYPE_CHECKING:
    from plant_model.fleet_model import Fleet, LeaderSpec

    from ..scenario import Scenario

__all__ = ["ARCHITECTURES", "DEPLOYMENTS", "DistributedSettings", "FleetSlots",
           "fleet_slots", "link_traces", "per_vehicle_configs", "per_vehicle_system",
           "stacked_traces"]

@dataclass(frozen=True)
class FleetSlots:
    """Neighbour slots of every vehicle: S = max(1, largest in-degree)."""

    neighbours: np.ndarray       #: (N, S) 1-based vehicle heard in slot k (own number if unused)
    weights: np.ndarray          #: (N, S) a_ij (0: unused)
    pinning: np.ndarray          #: (N,) a_i0

    @property
    def S(self) -> int:
        """Slots per vehicle."""
        return int(self.weights.shape[1])


def fleet_slots(fleet: Fleet) -> FleetSlots:
    """The graph of a fleet as fixed-size neighbour slots.

    Parameters
    ----------
    fleet : Fleet
        The fleet (its graph is validated: every vehicle reachable from the leader).

    Returns
    -------
    FleetSlots
        Slots in the order of the edges; unused ones name the vehicle itself, weight 0.
    """
    graph = fleet.graph
    N = graph.N
    heard: list[list[tuple[int, float]]] = [[] for _ in range(N)]
    for j, i, a in graph.edges:
        heard[int(i) - 1].append((int(j), float(a)))
    S = max([1] + [len(h) for h in heard])
    nb = np.tile(np.arange(1, N + 1)[:, None], (1, S))
    w = np.zeros((N, S))
    for i, h in enumerate(heard):
        for k, (j, a) in enumerate(h):
            nb[i, k], w[i, k] = j, a
    pin = np.zeros(N)
    for i, a in graph.pinning:
        pin[int(i) - 1] = float(a)
    return FleetSlots(neighbours=nb, weights=w, pinning=pin)


def _leader(ld: LeaderSpec) -> dict[str, np.ndarray]:
    F, z0, W = leader_system(ld.F, ld.z0, ld.W_z)
    return {"F": F, "H": ld.H, "z0": z0, "W_z": W}


def _mapping(view: LinearSystem, leader: Mapping[str, np.ndarray]) -> dict[str, Any]:
    """The FMU start values of one vehicle: its own matrices, the leader's F, H, z0, W_z."""
    keys = ("A", "B1", "B2", "C", "K", "x0", "w0", "Q", "R", "W_x", "W_w", "V_y", "V_ybar")
    out = {k: np.asarray(getattr(view, k)).tolist() for k in keys}
    out.update({k: np.asarray(v).tolist() for k, v in leader.items()})
    out["noise_convention"] = view.noise_convention
    return out


def per_vehicle_configs(sc: Scenario, architecture: str, *, estimator: str, seed: int,
                        tracking: str,
                        settings: DistributedSettings | None = None,
                        gain: np.ndarray | None = None,
                        network: list[dict[str, Any]] | None = None
                        ) -> list[dict[str, dict[str, Any]]]:
    """Per vehicle, the configuration of each FMU kind (vehicle 1's are the build's).

    Parameters
    ----------
    sc : Scenario
        A fleet scenario.
    architecture : str
        One of :data:`ARCHITECTURES`.
    estimator, seed, tracking : str, int, str
        Estimator (estimator_fmu.registry), noise seed, tracking law.
    settings : DistributedSettings or None, optional
        Gains of the distributed law (default :class:`DistributedSettings`).
    gain : np.ndarray or None, optional
        The stacked gain Ks (centralized; from
        :func:`controller_fmu.regulator.tracking_law` of the scenario's system).
    network : list[dict[str, Any]] or None, optional
        Per vehicle its ``AuvNetwork`` entries
        (:func:`orchestrator.cosim.per_vehicle_network.network_configs`; None: perfect links).

    Returns
    -------
    list[dict[str, dict[str, Any]]]
        Index 0 the leader's {'leader': config}, then per vehicle {'vehicle' (or the
        model's FMU kind), 'vehicle_estimator', 'vehicle_controller' |
        'central_controller', the kinds of the model's ``stack`` ('guidance', 'autopilot':
        :func:`orchestrator.cosim.guided.stack_configs`), and 'network' over acoustic
        links} -> config.
    """
    if architecture not in ARCHITECTURES:
        raise ValueError(f"architecture {architecture!r} is not one of "
                         f"{', '.join(ARCHITECTURES)}")
    settings = settings or DistributedSettings()
    views = sc.fleet.views
    leader = _leader(sc.fleet.leader)
    l0 = leader["F"].shape[0]
    v0 = views[0]
    dims = {"n": v0.n, "m": v0.m, "r": v0.r, "p": v0.p, "l": l0}
    base = {"dims": dims, "h": float(sc.h), "T": float(sc.T), "seed": int(seed),
            "estimator": estimator, "tracking": tracking, "fleet": None}
    slots = fleet_slots(sc.fleet)
    N = len(views)
    rows = (centralized_rows(gain, N, v0.n, v0.r, v0.m, l0)
            if architecture == "centralized" else None)
    eta0 = observer_start(leader["z0"], settings)
    models = sc.fleet.models
    out: list[dict[str, dict[str, Any]]] = [{"leader": dict(base, system=_mapping(v0, leader))}]
    design = sc.design
    limit = design.u_max if design is not None and design.clip else None
    for i, view in enumerate(views):
        cfg = dict(base, system=_mapping(view, leader))
        if sc.sensors is not None:              # acoustic fixes, DVL, depth at their rates
            cfg["sensors"] = sc.sensors.to_mapping()
        if sc.estimator_P0 is not None:    # [estimator] P0, one vehicle's
            cfg["P0"] = np.asarray(sc.estimator_P0, dtype=float).tolist()
        entry = get(models[i].name)
        one = {"vehicle": dict(cfg, vehicle=i + 1), "vehicle_estimator": cfg}
        par = models[i].parameters
        if entry.fmu_kind == "vehicle_fmu":  # the user's vehicle FMU through its port map
            one = {entry.fmu_kind: dict(cfg, vehicle=i + 1, fmu=fmu_port_config(
                       par["ports"], estimator, truth=estimator_kind(estimator).uses_truth,
                       sensors=sc.sensors is not None, where=f"vehicle "
                       f"{i + 1}", first=out[1:2])), "vehicle_estimator": cfg}
        elif entry.nonlinear:                # a nonlinear REMUS 100 vehicle FMU
            one = {entry.fmu_kind: dict(cfg, vehicle=i + 1, remus=par["nonlinear"],
                                        autopilot=par["autopilot"], substep=par["substep"]),
                   "vehicle_estimator": cfg}
        kinds = entry.stack_for(models[i])
        if kinds:                            # the FMUs between its controller and vehicle
            stack = stack_configs(models[i], view, sc.h, sc.T, seed)
            one.update({k: stack[k] for k in kinds})
        ctrl = cfg if limit is None else dict(cfg, u_max=list(limit[i]))
        if rows is not None:
            K, u0 = rows[i]
            one["central_controller"] = dict(ctrl, vehicles=N, gain=K.tolist(), u0=u0.tolist())
        else:
            one["vehicle_controller"] = dict(
                ctrl, slots=slots.S, offset=sc.fleet.offsets[i].tolist(),
                weights=slots.weights[i].tolist(), pinning=float(slots.pinning[i]),
                mu=settings.mu, cohesion=settings.cohesion, regulator=settings.regulator,
                eta0=eta0.tolist())
        if network is not None:
            one["network"] = dict(base, **network[i])
        out.append(one)
    return out


def build_configs(configs: list[dict[str, dict[str, Any]]]) -> dict[str, dict[str, Any]]:
    """The configuration each FMU kind is built with: the leader's, then each kind's first
    vehicle's (a fleet may mix the linear and the nonlinear vehicle FMU)."""
    out: dict[str, dict[str, Any]] = {}
    for one in configs:
        for kind, cfg in one.items():
            out.setdefault(kind, cfg)
    return out


def vehicle_kind(config: Mapping[str, Any]) -> str:
    """The FMU kind of one vehicle's plant in :func:`per_vehicle_configs`' entry."""
    return next(k for k in config if k in VEHICLE_KINDS)


def stack_kinds(config: Mapping[str, Any]) -> tuple[str, ...]:
    """The FMU kinds between one vehicle's controller and its plant (its model's ``stack``)
    in :func:`per_vehicle_configs`' entry, in signal order."""
    return tuple(k for k in config if k in STACK_KINDS)


def _component(name: str, key: str, config: dict[str, Any]) -> Component:
    specs = tuple(interface_of(FMU_KINDS[key], config))
    return Component(name, key, specs, component_parameters(specs))


def per_vehicle_system(sc: Scenario, configs: list[dict[str, dict[str, Any]]],
                       architecture: str) -> SystemDescription:
    """The per-vehicle system of a fleet scenario (module docstring).

    Parameters
    ----------
    sc : Scenario
        The fleet scenario (h, T, name, graph).
    configs : list[dict[str, dict[str, Any]]]
        :func:`per_vehicle_configs` of the run.
    architecture : str
        One of :data:`ARCHITECTURES`.

    Returns
    -------
    SystemDescription
        1 + 3 N components (and per vehicle its model's stack, its network) and their
        connections.
    """
    N = len(configs) - 1
    planned = sc.distributed.leader == "planned"
    networked = "network" in configs[1]
    comps = [_component("leader", "leader", configs[0]["leader"])]
    conns: list[Connection] = []
    ctrl_key = "central_controller" if architecture == "centralized" else "vehicle_controller"
    slots = fleet_slots(sc.fleet)
    for i in range(1, N + 1):
        v, e, c = f"vehicle_{i}", f"estimator_{i}", f"controller_{i}"
        vk = vehicle_kind(configs[i])
        comps += [_component(v, vk, configs[i][vk]),
                  _component(e, "vehicle_estimator", configs[i]["vehicle_estimator"]),
                  _component(c, ctrl_key, configs[i][ctrl_key])]
        measured = "nav" if "sensors" in configs[i][vk] else "y"
        # a vehicle FMU of the user's has no current: its velocity stands in for the truth
        # w (mode ideal is refused for it), so that every input is connected
        truth = (("x", "x"), ("velocity" if vk == "vehicle_fmu" else "w", "w"))
        conns += [Connection(v, measured, e, measured),
                  *(Connection(v, a, e, b, (e, "mode", TRUTH)) for a, b in truth),
                  Connection(c, "u", e, "u")]
        stack = stack_kinds(configs[i])
        if stack:                           # force -> guidance (-> autopilot) -> vehicle
            comps += [_component(f"{k}_{i}", k, configs[i][k]) for k in stack]
            conns += stack_connections(i, stack, tuple(
                a.name for a in comps[-len(stack) - 3].arrays("input")))
        else:
            conns.append(Connection(c, "u", v, "u"))
        if networked:
            comps.append(_component(f"network_{i}", "network", configs[i]["network"]))
            conns += _networked(i, architecture, configs[i]["network"], slots,
                                pinned=architecture == "centralized" or (
                                    slots.pinning[i - 1] > 0.0 and not planned))
            continue
        if architecture == "centralized":
            conns.append(Connection("leader", "z", c, "z"))
            for j in range(1, N + 1):
                for s in ("xhat", "what"):
                    conns.append(Connection(f"estimator_{j}", s, c, f"vehicle[{j}].{s}"))
            continue
        conns += [Connection(e, "xhat", c, "xhat"), Connection(e, "what", c, "what")]
        # a planned path: every observer starts on it and no leader message is sent
        pinned = slots.pinning[i - 1] > 0.0 and not planned
        conns.append(Connection("leader", "z", c, "z") if pinned
                     else Connection(c, "eta", c, "z"))
        for k in range(slots.S):
            j = int(slots.neighbours[i - 1, k]) if slots.weights[i - 1, k] > 0.0 else i
            for s in ("eta", "eps"):
                conns.append(Connection(f"controller_{j}", s, c, f"nbr[{k + 1}].{s}"))
    return SystemDescription(name=sc.name, components=tuple(comps), connections=tuple(conns),
                             h=float(sc.h), T=float(sc.T))


def _networked(i: int, architecture: str, cfg: Mapping[str, Any], slots: FleetSlots,
               pinned: bool) -> list[Connection]:
    """Vehicle i's messages through its network FMU; its own estimates direct."""
    c, e = f"controller_{i}", f"estimator_{i}"
    row = [st["sender"] for st in cfg["links"]]
    fields = cfg["fields"]
    conns = network_connections(i, architecture, row, fields, pinned,
                                {"slot": "nbr[{k}].{f}"}, bool(cfg.get("range")))
    if architecture == "centralized":
        return conns + [Connection(e, s, c, f"vehicle[{i}].{s}") for s in ("xhat", "what")]
    conns += [Connection(e, "xhat", c, "xhat"), Connection(e, "what", c, "what")]
    carried = {f for f, _ in fields}
    for k, j in enumerate(row, start=1):
        for f in ("eta", "eps"):
            if j is None or f not in carried:        # unused slot, or eps not carried
                conns.append(Connection(c, f, c, f"nbr[{k}].{f}"))
    if not pinned:
        conns.append(Connection(c, "eta", c, "z"))
    return conns


def link_traces(system: SystemDescription, traces: Mapping[str, np.ndarray]
                ) -> dict[tuple[Any, int], dict[str, np.ndarray]]:
    """Per acoustic link (sender, receiver) its network FMU's ``age`` (s), ``delivered``,
    ``lost`` and ``in_flight`` traces (empty without a network).

    Parameters
    ----------
    system : SystemDescription
        A per-vehicle system.
    traces : Mapping[str, np.ndarray]
        Its traces.

    Returns
    -------
    dict[tuple[Any, int], dict[str, np.ndarray]]
        The sender is a vehicle number or "leader".
    """
    names = system.trace_names()
    out: dict[tuple[Any, int], dict[str, np.ndarray]] = {}
    for comp in system.components:
        if comp.fmu != "network":
            continue
        i = int(comp.name.rsplit("_", 1)[1])
        k = 1
        while f"link[{k}].key" in comp.parameters:
            key = int(comp.parameters[f"link[{k}].key"])
            if key:
                out[(link_sender(key), i)] = {s: traces[names[(comp.name, f"link[{k}].{s}")]][:, 0]
                                           for s in LINK_STATISTICS}
            k += 1
        if int(comp.parameters.get("leader.key", 0)):
            out[("leader", i)] = {s: traces[names[(comp.name, f"leader.{s}")]][:, 0]
                                  for s in LINK_STATISTICS}
    return out


#: the FMU kinds of a vehicle's plant (every model's in the registry)
VEHICLE_KINDS = tuple(dict.fromkeys(e.fmu_kind for e in REGISTRY.values()))
#: the FMU kinds that stand between a vehicle's controller and its plant
STACK_KINDS = tuple(dict.fromkeys(k for e in REGISTRY.values() for k in e.stack))

#: the nonlinear vehicle's extra outputs: attitude (3 per vehicle, rad), rpm, rudder and
#: stern-plane angles (rad), saturated (0/1)
NONLINEAR_OUTPUTS = ("attitude", "rpm", "rudder", "stern", "saturated")

#: the per-link outputs of a network FMU
LINK_STATISTICS = ("age", "delivered", "lost", "in_flight")


def stacked_traces(sc: Scenario, system: SystemDescription,
                   traces: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The per-vehicle traces in the stacked deployment's layout.

    Parameters
    ----------
    sc : Scenario
        The fleet scenario (offsets, leader output).
    system : SystemDescription
        The per-vehicle system that produced ``traces``.
    traces : Mapping[str, np.ndarray]
        Keyed by :meth:`SystemDescription.trace_names`.

    Returns
    -------
    dict[str, np.ndarray]
        y, x, w, z (with the constant c = 1 column when the stacked z has one), e, u, xhat,
        what; eta (N l, the observers) for the distributed architecture; and when every
        vehicle is a nonlinear one (AuvRemus6dof, AuvRemus6dofActuated) its
        :data:`NONLINEAR_OUTPUTS`; when every vehicle is flown through the guidance FMUs,
        ``setpoint`` (per vehicle its guidance's speed, course, depth;
        :func:`orchestrator.cosim.guided.setpoint_traces`).
    """
    names = system.trace_names()
    N = sum(1 for c in system.components if c.fmu in VEHICLE_KINDS)
    z_l = traces[names[("leader", "z")]]

    def cat(prefix: str, out: str) -> np.ndarray:
        return np.hstack([traces[names[(f"{prefix}_{i}", out)]] for i in range(1, N + 1)])

    out = {"y": cat("vehicle", "y"), "x": cat("vehicle", "x"),
           # a vehicle FMU of the user's has no current (zero)
           "w": np.hstack([traces[names[(f"vehicle_{i}", "w")]]
                           if (f"vehicle_{i}", "w") in names
                           else np.zeros((z_l.shape[0], 3)) for i in range(1, N + 1)]),
           "u": cat("controller", "u"), "xhat": cat("estimator", "xhat"),
           "what": cat("estimator", "what")}
    z = z_l
    if sc.system.l > z_l.shape[1]:
        z = np.hstack([z_l, np.ones((z_l.shape[0], sc.system.l - z_l.shape[1]))])
    out["z"] = z
    # e = H z - C x of the stacked system (offsets in its last column), from the truth
    # (summed over the maps' non-zero entries in a fixed order: the same bits on every BLAS
    # kernel, and faster than the dense products: plant_model.fixed_order)
    out["e"] = rows_times_transpose(z, sc.system.H) - rows_times_transpose(out["x"], sc.system.C)
    if ("controller_1", "eta") in names:
        out["eta"] = cat("controller", "eta")
    if all((f"vehicle_{i}", "saturated") in names for i in range(1, N + 1)):
        for extra in NONLINEAR_OUTPUTS:                            # nonlinear vehicles
            out[extra] = cat("vehicle", extra)
    out.update(setpoint_traces(system, traces, N))     # vehicles flown through guidance
    return out
