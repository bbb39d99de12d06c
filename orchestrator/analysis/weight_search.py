"""The [design] section at work: vehicle limits, the weight search and the path check.

For a fleet spec (:mod:`plant_model.fleet`) and the [design] options:

1. every vehicle's limits (:class:`plant_model.remus100.limits.VehicleLimits`): for
   ``remus100-6dof`` simulated from its own data (:func:`plant_model.remus100.limits.
   remus_limits`); for the linear NED models the top speed of their parameters
   (``REMUS100_MAX_SPEED`` for ``remus100``; ``[design] max_speed`` overrides), no turn
   radius or depth rate unless [design] gives them; for ``generic`` none;
2. its maximum force per axis, u_max = D_a U_max (N): the design model's drag at the top
   speed (D_a from B1, B2 of the NED layout), or ``[design] u_max`` as given;
3. the weight scale r (R = r I) of :func:`controller_fmu.weight_design.choose_weight`:
   per distinct vehicle the LQ gain of its design model, its closed-loop bandwidth and its
   noise-driven force covariance (sampled at h with its own steady Kalman filter on a
   position fix every step, or the true state for ``ideal``); the fleet's bandwidth is the
   fastest vehicle's, its force ratio the worst vehicle's worst axis;
4. the path check (:mod:`plant_model.path_feasibility`) over [0, T].
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import lru_cache
from typing import Any

import numpy as np

from controller_fmu.vehicle_law import vehicle_law
from controller_fmu.weight_design import (
    choose_weight,
    closed_loop_bandwidth,
    noise_force_covariance,
)
from estimator_fmu.registry import STEADY_FILTER, TRUTH, estimator_kind
from plant_model.fleet import fleet_vehicles
from plant_model.linalg_checks import ModelError
from plant_model.path_feasibility import (
    Finding,
    finding_lines,
    path_findings,
    path_samples,
    path_states,
)
from plant_model.remus100.limits import VehicleLimits
from plant_model.vehicle_models import REGISTRY, get
from plant_model.vehicles import VehicleModel

from .distributed import Agent, agents_from_fleet_spec, sample_agent

__all__ = ["PATH_DT", "DesignResult", "check_path_horizon", "design_fleet", "force_limits",
           "path_verdict", "vehicle_band", "vehicle_limits"]

#: the path check's and the path force ratio's sampling interval, s
PATH_DT = 0.1
#: values per sample they hold besides the exosystem's states (velocity, acceleration,
#: speeds, radii, the per-vehicle tests)
PATH_VALUES_PER_SAMPLE = 16


def check_path_horizon(states: int, T: float, dt: float = PATH_DT,
                       available: int | None = None) -> int:
    """Refuse, before it samples anything, a horizon whose path samples (every ``dt`` s
    over [0, T]) would not fit in memory: bytes = 8 samples (states + 16), on the one
    memory rule (:func:`orchestrator.scenario.size.memory_short`). A [design] scenario
    with ``T = 1e9`` is refused here, at once, wherever it is loaded.

    Parameters
    ----------
    states : int
        The leader exosystem's states l.
    T, dt : float
        Horizon and sampling interval, s.
    available : int, optional
        Bytes available (default: the kernel's figure).

    Returns
    -------
    int
        The path samples' estimated bytes, 8 samples (states + 16).

    Raises
    ------
    ModelError
        ``[design] path check: T = ... s: ... samples need about ... GB, more than ...``.
    """
    from ..scenario.size import MEMORY_SHARE, memory_short
    n = path_samples(T, dt)
    need = 8 * n * (states + PATH_VALUES_PER_SAMPLE)
    short = memory_short(need, available)
    if short is not None:
        raise ModelError(f"[design] path check: T = {T:g} s sampled every {dt:g} s is "
                         f"{n:.4g} samples of the leader's path: about {need / 1e9:.3g} GB, "
                         f"more than {MEMORY_SHARE:.0%} of the {short / 1e9:.3g} GB of "
                         "memory available; shorten T")
    return need


def vehicle_limits(model: VehicleModel, options: Mapping[str, Any]) -> VehicleLimits:
    """The limits of one vehicle (module docstring, item 1); [design] max_speed,
    min_turn_radius, max_depth_rate override what the model gives."""
    given = {k: options.get(k) for k in ("max_speed", "min_turn_radius", "max_depth_rate")}
    entry = get(model.name)
    lim = (entry.limits(model) if entry.limits is not None else
           VehicleLimits(None, None, None, f"{model.name}: no limits known"))
    over = {k: float(v) for k, v in given.items() if v is not None}
    if over:
        lim = replace(lim, **over, source=(lim.source + "; " if lim.source else "")
                      + "[design] " + ", ".join(over))
    return lim


def vehicle_band(models: Sequence[VehicleModel]) -> float:
    """``[design] bandwidth = "vehicle"``: the smallest over the fleet's vehicles of the
    band where each responds like its linear design model (rad/s;
    :func:`orchestrator.analysis.remus_response.valid_band` at the design's cruise speed).

    Raises
    ------
    ModelError
        If a vehicle is not nonlinear (a linear model is its own design model: no band).
    """
    bands = []
    for mdl in models:
        if not get(mdl.name).nonlinear:
            raise ModelError(f"[design] bandwidth = \"vehicle\" needs nonlinear vehicles "
                             f"({', '.join(e.name for e in REGISTRY.values() if e.nonlinear)}); "
                             f"a {mdl.name!r} vehicle is its own design model: give the "
                             "bandwidth in rad/s")
        M = 1.0 / np.diag(np.asarray(mdl.B1, float)[3:6, :3])
        D = -np.diag(np.asarray(mdl.A, float)[3:6, 3:6]) * M
        data = tuple(sorted((k, tuple(v) if isinstance(v, list) else v)
                            for k, v in mdl.parameters["nonlinear"].items()))
        bands.append(_band(data,
                           tuple(M), tuple(D), float(mdl.parameters["cruise_speed"])))
    return min(bands)


@lru_cache(maxsize=32)
def _band(data: tuple, M: tuple, D: tuple, U0: float) -> float:
    from plant_model.remus100.models import remus_from_parameters

    from .remus_response import valid_band
    return valid_band(remus_from_parameters(dict(data)), np.array(M), np.array(D), U0)


def force_limits(model: VehicleModel, lim: VehicleLimits, u_max: Any = None) -> np.ndarray:
    """The maximum force per input (N): ``u_max`` as given (a number for every axis or one
    per input), else D_a * U_max of a NED design model (module docstring, item 2).

    Raises
    ------
    ModelError
        Naming ``u_max`` when it is needed and cannot be derived, or has the wrong size.
    """
    m = model.q
    if u_max is not None and not isinstance(u_max, str):
        out = np.broadcast_to(np.asarray(u_max, float), (m,)).copy() if np.ndim(u_max) == 0 \
            else np.asarray(u_max, float)
        if out.shape != (m,) or not np.all(out > 0) or not np.all(np.isfinite(out)):
            raise ModelError(f"u_max must be a positive number or {m} positive numbers (N), "
                             f"got {u_max!r}")
        return out
    entry = get(model.name)
    if entry.layout != "ned" or lim.max_speed is None:
        raise ModelError(f"u_max: the maximum force of a {model.name!r} vehicle cannot be "
                         "derived (no NED drag or no top speed); give [design] u_max in N")
    Bv = np.diag(np.asarray(model.B1, float)[3:6, :3])
    Av = np.diag(np.asarray(model.A, float)[3:6, 3:6])
    D = -Av / Bv                       # M v' = -D v + u: A_vv = -D/M, B_v = 1/M
    return D * float(lim.max_speed)


@dataclass(frozen=True)
class DesignResult:
    """What [design] chose and found (summary.json ``design``)."""

    R: float | None                 #: the chosen input weight scale (R = r I), 1/N^2
    binding: str | None             #: which target set R
    bandwidth: float | None         #: the fleet's closed-loop bandwidth at R, rad/s
    force_3sigma: list[float] | None  #: worst vehicle's predicted 3-sigma force per axis, N
    force_ratio: float | None       #: its worst axis over that axis's u_max
    force_vehicle: int | None       #: the worst vehicle (1-based)
    bandwidth_target: float | None
    force_budget: float | None
    u_max: list[list[float]]        #: per vehicle its maximum force per axis, N
    clip: bool                      #: the controllers clip their force at u_max
    limits: list[dict[str, Any]]    #: per vehicle its limits
    findings: list[Finding] = field(default_factory=list)
    checked: bool = True            #: the path was checked (path_check is not "off")
    #: the largest force the target path itself needs, M_a a_a + D_a v_a over u_max_a (the
    #: worst vehicle and axis; R-independent, not in the budget; None: not a NED model)
    path_force_ratio: float | None = None
    #: the path check's current (m/s, standard deviation per axis) and the lateral
    #: acceleration the controller adds (m/s^2: its 3-sigma noise force over the mass)
    current_sigma: float = 0.0
    lateral_margin: float = 0.0
    #: the bandwidth target is the band where the vehicle follows its design model
    bandwidth_from_vehicle: bool = False

    def lines(self) -> list[str]:
        """The printout: the choice in one line, then one line per path finding."""
        out = []
        if self.R is not None:
            why = {"bandwidth": "the bandwidth target sets it",
                   "force_budget": "the force budget sets it",
                   "range": "both targets met at the smallest R searched"}[self.binding or "range"]
            force = ("" if self.force_3sigma is None else
                     f"predicted 3-sigma force {max(self.force_3sigma):.3g} N = "
                     f"{self.force_ratio:.3g} of u_max (vehicle {self.force_vehicle})"
                     + ("" if self.force_budget is None else f", budget {self.force_budget:g}")
                     + "; ")
            out.append(f"design: R = {self.R:.4g} ({why}): {force}bandwidth "
                       f"{self.bandwidth:.3g} rad/s"
                       + ("" if self.bandwidth_target is None
                          else f" (target {self.bandwidth_target:.3g} rad/s"
                          + (": the band where the vehicle follows its design model within "
                             "20 deg and 25 %)" if self.bandwidth_from_vehicle else ")"))
                       + ("" if self.path_force_ratio is None else
                          f"; the path itself needs up to {self.path_force_ratio:.2g} of "
                          "u_max"))
        out += [f"path check: {line}" for line in finding_lines(self.findings)]
        return out

    def summary(self) -> dict[str, Any]:
        """The JSON entries (``design.R``, ``design.bandwidth``, ``design.force_3sigma``...)."""
        return {"R": self.R, "binding": self.binding, "bandwidth": self.bandwidth,
                "force_3sigma": self.force_3sigma, "force_ratio": self.force_ratio,
                "force_vehicle": self.force_vehicle, "bandwidth_target": self.bandwidth_target,
                "bandwidth_from_vehicle": self.bandwidth_from_vehicle,
                "force_budget": self.force_budget, "u_max": self.u_max, "clip": self.clip,
                "limits": self.limits, "path_findings": finding_lines(self.findings),
                "path_force_ratio": self.path_force_ratio,
                "printout": self.lines()}

    def over(self, T: float, F: np.ndarray, H: np.ndarray, z0: np.ndarray) -> DesignResult:
        """The same design with the path checked over [0, T] (a run's own horizon)."""
        from types import SimpleNamespace
        if self.checked:
            check_path_horizon(np.asarray(F).shape[0], T)
        lims = [SimpleNamespace(**lim) for lim in self.limits]
        return replace(self, findings=path_findings(
            F, H, z0, T, lims, current_sigma=self.current_sigma,
            lateral_margin=self.lateral_margin) if self.checked else [])


def path_verdict(design: DesignResult | None) -> dict[str, Any]:
    """``path_feasible`` (the [design] path check found nothing; None without [design] or
    with ``path_check = "off"``) and ``path_findings`` (its lines, "; "-joined): the
    feasibility verdict beside a run's figures (envelope points, campaign rows)."""
    if design is None or not design.checked:
        return {"path_feasible": None, "path_findings": None}
    return {"path_feasible": not design.findings,
            "path_findings": "; ".join(finding_lines(design.findings)) or None}


def _noise_gain(agent: Agent, r: float, leader: Mapping[str, np.ndarray], tracking: str,
                regulator: str, h: float) -> tuple[np.ndarray, np.ndarray]:
    """(Kx, Ks on [x; w]) of the vehicle's law at R = r I: u_noise = -Kx xhat + (Uw + Kx Xw)
    what (controller_fmu.vehicle_law)."""
    law = vehicle_law(A=agent.A, B1=agent.B, B2=agent.E, C=agent.C, K=agent.Kw, Q=agent.Q,
                      R=r * np.eye(agent.B.shape[1]), F=leader["F"], H=leader["H"],
                      offset=agent.offset, tracking=tracking, regulator=regulator, h=h)
    return law.Kx, np.hstack([law.Kx, -law.gain_what])


def path_force_ratio(models: Sequence[VehicleModel], umax: Sequence[np.ndarray],
                     F: np.ndarray, H: np.ndarray, z0: np.ndarray, T: float,
                     dt: float = PATH_DT) -> float | None:
    """max over t, vehicles and axes of |M_a a_a(t) + D_a v_a(t)| / u_max_a: the force the
    target path needs in still water (v = H F z, a = H F^2 z; M_a = 1 / B_v, D_a = -A_vv M_a
    of a NED design model). None when a model is not NED or there is no u_max."""
    if not umax or any(get(m.name).layout != "ned" for m in models):
        return None
    Z = path_states(F, z0, T, dt)
    V, A = Z @ (H @ F).T, Z @ (H @ F @ F).T
    worst = 0.0
    for mdl, lim in zip(models, umax):
        M = 1.0 / np.diag(np.asarray(mdl.B1, float)[3:6, :3])
        D = -np.diag(np.asarray(mdl.A, float)[3:6, 3:6]) * M
        worst = max(worst, float(np.max(np.abs(A * M + V * D) / lim)))
    return worst


def _key(a: Agent) -> bytes:
    return b"".join(np.ascontiguousarray(x, float).tobytes()
                    for x in (a.A, a.B, a.C, a.E, a.Kw, a.Q, a.W_x, a.W_w, a.V_y))


def design_fleet(spec: Mapping[str, Any], options: Mapping[str, Any], *, h: float,
                 T: float, estimator: str, tracking: str, regulator: str = "continuous",
                 current_sigma: float = 0.0) -> DesignResult:
    """Limits, u_max, the weight search (when ``bandwidth`` or ``force_budget`` is given)
    and the path check of a fleet spec (module docstring).

    Parameters
    ----------
    spec : Mapping[str, Any]
        The fleet spec (its vehicles' R is ignored by the search).
    options : Mapping[str, Any]
        The [design] table: bandwidth (rad/s), force_budget (fraction), u_max (N, a
        number, per axis, or "vehicle"), max_speed, min_turn_radius, max_depth_rate.
    h, T : float
        Communication step and horizon, s.
    estimator, tracking, regulator : str
        The run's estimator (``ideal`` samples the true state; any other the steady
        Kalman filter), tracking law and regulator form.
    current_sigma : float, optional
        The current's standard deviation per axis (m/s) the path check counts
        (:func:`plant_model.path_feasibility.path_findings`).

    Returns
    -------
    DesignResult
        What was chosen and found; R None without a target.

    Raises
    ------
    ModelError
        A target that cannot be met, a relation that is not monotone, u_max not derivable.
    """
    models = fleet_vehicles(spec)
    from_vehicle = options.get("bandwidth") == "vehicle"
    if from_vehicle:
        options = {**options, "bandwidth": vehicle_band(models)}
    limits = [vehicle_limits(mdl, options) for mdl in models]
    u_opt = options.get("u_max")
    needs_force = options.get("force_budget") is not None or u_opt is not None
    umax = ([force_limits(mdl, lim, u_opt if u_opt != "vehicle" else None)
             for mdl, lim in zip(models, limits)] if needs_force else [])
    ld = spec["leader"]
    F, H, z0 = (np.asarray(ld[k], float) for k in ("F", "H", "z0"))
    checked = options.get("path_check") != "off"
    if checked or umax:                            # both sample the path over [0, T]
        check_path_horizon(F.shape[0], T)

    def check(margin: float) -> list:
        return (path_findings(F, H, z0, T, limits, current_sigma=current_sigma,
                              lateral_margin=margin) if checked else [])

    findings = check(0.0)
    base = dict(R=None, binding=None, bandwidth=None, force_3sigma=None, force_ratio=None,
                force_vehicle=None, bandwidth_target=options.get("bandwidth"),
                force_budget=options.get("force_budget"),
                u_max=[u.tolist() for u in umax], clip=u_opt is not None,
                limits=[{"max_speed": lim.max_speed, "min_turn_radius": lim.min_turn_radius,
                         "max_depth_rate": lim.max_depth_rate, "source": lim.source}
                        for lim in limits], findings=findings, checked=checked,
                path_force_ratio=path_force_ratio(models, umax, F, H, z0, T),
                current_sigma=current_sigma, bandwidth_from_vehicle=from_vehicle)
    if options.get("bandwidth") is None and options.get("force_budget") is None:
        return DesignResult(**base)
    agents, _, leader = agents_from_fleet_spec(spec)
    mode = TRUTH if estimator_kind(estimator).uses_truth else STEADY_FILTER
    groups: dict[bytes, list[int]] = {}
    for i, a in enumerate(agents):
        groups.setdefault(_key(a) + (umax[i].tobytes() if umax else b""), []).append(i)
    reps = [(idx[0], sample_agent(agents[idx[0]], h, convention=spec.get(
        "noise_convention", "intensity"), estimator=mode)) for idx in groups.values()]

    def bandwidth_of(r: float) -> float:
        return max(closed_loop_bandwidth(agents[i].A, agents[i].B,
                                         _noise_gain(agents[i], r, leader, tracking,
                                                     regulator, h)[0]) for i, _ in reps)

    def sigma3(r: float) -> list[tuple[float, int, np.ndarray]]:
        out = []
        for i, sa in reps:
            Ks = _noise_gain(agents[i], r, leader, tracking, regulator, h)[1]
            Suu = noise_force_covariance(sa.Ad, sa.Bd, Ks, sa.Qd, sa.M, sa.Rd, sa.L)
            f3 = 3.0 * np.sqrt(np.clip(np.diag(Suu), 0.0, None))
            out.append((float(np.max(f3 / umax[i])), i + 1, f3))
        return out

    choice = choose_weight(bandwidth_of, lambda r: max(s[0] for s in sigma3(r))
                           if umax else 0.0, bandwidth=options.get("bandwidth"),
                           force_budget=options.get("force_budget"))
    per_vehicle = sigma3(choice.r) if umax else []
    worst = max(per_vehicle, key=lambda s: s[0]) if umax else None
    # the controller's lateral 3-sigma acceleration on top of the path's (NED models)
    margin = max((max(f3[:2]) * float(np.asarray(models[i - 1].B1, float)[3, 0])
                  for _, i, f3 in per_vehicle if get(models[i - 1].name).layout == "ned"),
                 default=0.0)
    base.update(findings=check(margin), lateral_margin=margin)
    return DesignResult(**{**base, "R": choice.r, "binding": choice.binding,
                           "bandwidth": bandwidth_of(choice.r),
                           "force_3sigma": None if worst is None else worst[2].tolist(),
                           "force_ratio": None if worst is None else worst[0],
                           "force_vehicle": None if worst is None else worst[1]})


def apply_weight(spec: dict[str, Any], r: float, inputs: Sequence[int]) -> None:
    """Set every vehicle's R = r I (inputs: per vehicle its input count) in ``spec``."""
    for v, m in zip(spec["vehicles"], inputs):
        v["R"] = (r * np.eye(m)).tolist()
