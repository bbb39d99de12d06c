"""The design model of a vehicle the user brings as an FMU, identified from its frequency
responses (``model = "fmu"``, :mod:`plant_model.vehicle_fmu`).

The experiment is the REMUS 100's (:mod:`orchestrator.analysis.remus_response`): at a trim
(straight and level at the cruise speed U0 north), a sinusoidal NED force A sin(w t) (N)
is added on one axis a (north, east, down) to the trim force; after the transient and one
period, the velocity over ground on that axis is fitted over two periods to
c + a_s sin(w t) + b_s cos(w t); G_a(w) = (a_s + j b_s) / A (m/s per N), divided by
the zero-order hold's sinc(w h / 2) exp(-j w h / 2) (the force is held over each step h:
the design model is discretized the same way in the run), at the eight
frequencies :data:`~plant_model.first_order_fit.FIT_OMEGAS` (0.02 to 0.3 rad/s).
Then M_a, D_a of G_f = 1 / (D_a + j w M_a) by the relative-error fit of
:mod:`plant_model.first_order_fit`, per axis (``horizontal = "separate"``) or with
north and east together (``"together"``, the default, as ``remus100-fitted``: a vehicle
steered by its heading turns the same whichever horizontal direction it flies).

- **Force inputs**: the FMU takes the force. The trim force F0 north is found first by
  constant-force runs, F0 <- F0 U0 / v (v the speed it settles at; a linear drag in one
  pass, a quadratic one in a few), and the settling time of that run (velocity within 1 %
  of its end value, at least 10 s) starts every sinusoidal run.
- **Set-point inputs** (speed, heading, depth): the force goes through the same guidance
  law the run uses (:mod:`controller_fmu.guidance`: M0 v_ref' = u - D0 v_ref per NED axis,
  then speed = |v_ref|, course, depth and their rates), with M0, D0 the linear REMUS 100's
  at U0 (:func:`plant_model.vehicle_fmu.guidance_model`); trim force D0 U0 north. So the
  identified model is what the controller drives: the guidance and the user's vehicle with
  its own autopilot, as one force-to-velocity response. Fitting the set-point response
  directly would leave out the guidance the controller's force passes through; with it, a
  vehicle that followed its set-points perfectly would be identified as (M0, D0), and
  its autopilot's lag shows as extra inertia.

The result is cached by the FMU file's SHA-256 and the experiment's settings in
``<FMU cache>/identified/`` (:func:`fmu_common.cache.fmu_cache_dir`): a second run
reads it. The fit's quality, |G - G_f| / |G| over the frequencies, is printed on stderr
once per process.
"""
from __future__ import annotations

import hashlib
import json
import math
import shutil
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from .first_order_fit import FIT_OMEGAS, fit_errors, fit_first_order_response, sine_response
from .linalg_checks import ModelError
from .vehicle_fmu import FmuPorts, fmu_ports, guidance_model
from .vehicles import VehicleModel, _ned_axes_model

__all__ = ["Identified", "fmu_vehicle_from_params", "identified", "identify", "response_of"]

#: bump when the experiment changes: cached identifications then no longer match
EXPERIMENT_VERSION = 1
#: start depth of a set-point FMU with start parameters, m
START_DEPTH = 20.0
_AXIS_NAMES = ("north", "east", "down")
_printed: set[str] = set()
_memo: dict[str, Identified] = {}


@dataclass(frozen=True)
class Identified:
    """M, D per NED axis (kg, kg/s) and the responses they were fitted to."""

    M: tuple[float, float, float]
    D: tuple[float, float, float]
    omegas: tuple[float, ...]                       #: rad/s
    responses: tuple[tuple[complex, ...], ...]      #: per axis, G at each omega (m/s per N)
    kind: str                                       #: "force" or "setpoints"
    name: str                                       #: the FMU's file name
    digest: str                                     #: its SHA-256
    cached: bool = False                            #: read from the cache

    def errors(self) -> np.ndarray:
        """(3, frequencies): |G - G_f| / |G| per axis and frequency."""
        return np.array([fit_errors(np.array(self.omegas), np.array(g), m, d)
                         for g, m, d in zip(self.responses, self.M, self.D)])

    def summary(self) -> dict[str, Any]:
        """JSON-ready: M, D, the fit's RMS and max relative error overall and per axis."""
        e = self.errors()
        return {"M": list(self.M), "D": list(self.D), "kind": self.kind,
                "rms_error": float(np.sqrt(np.mean(e ** 2))), "max_error": float(e.max()),
                "axis_rms_error": [float(np.sqrt(np.mean(r ** 2))) for r in e],
                "omegas": list(self.omegas), "digest": self.digest}

    def text(self) -> str:
        """One line: the model and the fit's quality."""
        s = self.summary()
        via = ("set-points through the guidance" if self.kind == "setpoints"
               else "force inputs")
        axes = ", ".join(f"{a} {100 * r:.1f} %" for a, r in zip(_AXIS_NAMES,
                                                                 s["axis_rms_error"]))
        return (f"vehicle FMU {self.name}: design model identified ({via}, "
                f"{min(self.omegas):g}-{max(self.omegas):g} rad/s): M = "
                f"[{', '.join(f'{m:.4g}' for m in self.M)}] kg, D = "
                f"[{', '.join(f'{d:.4g}' for d in self.D)}] kg/s; fit error RMS "
                f"{100 * s['rms_error']:.1f} %, max {100 * s['max_error']:.1f} % "
                f"({axes}){'; from the cache' if self.cached else ''} "
                f"[sha256 {self.digest[:12]}]")


class _Run:
    """One instance of the FMU, fed per step by :meth:`step`."""

    def __init__(self, ports: FmuPorts, unzipped: str, h: float, T: float,
                 start: tuple[np.ndarray, np.ndarray] | None) -> None:
        from fmpy import read_model_description
        from fmpy.fmi2 import FMU2Slave
        md = read_model_description(str(ports.path), validate=False)
        vr = {v.name: v.valueReference for v in md.modelVariables}
        self.slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                               modelIdentifier=ports.model_identifier,
                               instanceName="identification")
        self.ins = [vr[n] for _, n in ports.inputs]
        self.outs = [vr[n] for n in (*ports.position, *ports.velocity)]
        self.h = h
        s = self.slave
        s.instantiate()
        s.setupExperiment(startTime=0.0, stopTime=T)
        s.enterInitializationMode()
        if start is not None:
            names = [*ports.start_position, *ports.start_velocity]
            vals = [*start[0][:len(ports.start_position)], *start[1][:len(ports.start_velocity)]]
            if names:
                s.setReal([vr[n] for n in names], [float(v) for v in vals])
        s.exitInitializationMode()

    def read(self) -> np.ndarray:
        """[n, e, d, v_n, v_e, v_d] (m, m/s)."""
        return np.array(self.slave.getReal(self.outs))

    def step(self, k: int, values: np.ndarray) -> None:
        """Set the inputs (in port order), then advance from t = k h."""
        self.slave.setReal(self.ins, [float(v) for v in values])
        self.slave.doStep(currentCommunicationPoint=k * self.h, communicationStepSize=self.h)

    def close(self) -> None:
        try:
            self.slave.terminate()
        finally:
            self.slave.freeInstance()


def _simulate(ports: FmuPorts, unzipped: str, force: Any, T: float) -> np.ndarray:
    """Velocities (steps, 3) of the FMU under the NED force ``force(t)`` (N): directly for
    force inputs, through the guidance law for set-points (module docstring)."""
    from controller_fmu.guidance import depth_increment, reference_step, setpoints
    h = ports.step
    n = int(round(T / h))
    U0 = ports.cruise_speed
    start = (np.array([0.0, 0.0, START_DEPTH]), np.array([U0, 0.0, 0.0]))
    run = _Run(ports, unzipped, h, n * h, start)
    vel = np.empty((n, 3))
    try:
        y = run.read()
        if ports.kind == "setpoints":
            M0, D0 = guidance_model(ports)
            v_ref, depth, course = np.array([U0, 0.0, 0.0]), float(y[2]), 0.0
            order = {"speed": 0, "heading": 1, "depth": 2, "speed_rate": 3,
                     "heading_rate": 4, "depth_rate": 5}        # setpoints()' order
        for k in range(n):
            u = force(k * h)
            vel[k] = y[3:6]
            if ports.kind == "force":
                run.step(k, u)
            else:
                sp = setpoints(v_ref, u, M0, D0, depth, course, 0.3)
                course = float(sp[1])
                run.step(k, np.array([sp[order[p]] for p, _ in ports.inputs]))
                depth += depth_increment(v_ref[2], u[2], M0[2], D0[2], h)
                v_ref = reference_step(v_ref, u, M0, D0, h)
            y = run.read()
            if not np.all(np.isfinite(y)):
                raise ModelError(f"fmu: {ports.path.name} returned a non-finite output at "
                                 f"t = {k * h:g} s during the identification")
    finally:
        run.close()
    return vel


def _trim(ports: FmuPorts, unzipped: str) -> tuple[float, float]:
    """(F0, settle): the trim force north (N) that holds the cruise speed, and the
    settling time (s) from the start (module docstring)."""
    U0 = ports.cruise_speed
    if ports.kind == "setpoints":
        _, D0 = guidance_model(ports)
        F = float(D0[0] * U0)
        T = 120.0
    else:
        F, T = 10.0 * ports.amplitude, 300.0
    for _ in range(8):
        v = _simulate(ports, unzipped, lambda t, F=F: np.array([F, 0.0, 0.0]), T)[:, 0]
        end = float(np.mean(v[-len(v) // 10:]))
        if not end > 0.0:
            raise ModelError(f"fmu: {ports.path.name} does not move north under a "
                             f"{F:g} N force (speed {end:g} m/s); check the port map")
        off = np.nonzero(np.abs(v - end) > 0.01 * max(abs(end), 1e-9))[0]
        settle = max(10.0, (off[-1] + 1) * ports.step if off.size else 0.0)
        if ports.kind == "setpoints" or abs(end - U0) <= 0.01 * U0:
            return F, settle
        F *= U0 / end
    return F, settle


def response_of(ports: FmuPorts, unzipped: str, axis: int, omega: float, F0: float,
                settle: float) -> complex:
    """G (m/s per N) on ``axis`` at ``omega`` (rad/s): the trim force F0 north plus
    A sin(w t) on the axis, the velocity fitted over two periods after ``settle`` s and
    one period (module docstring)."""
    A = ports.amplitude
    period = 2.0 * math.pi / omega
    t0 = max(settle, period)

    def force(t: float) -> np.ndarray:
        u = np.array([F0, 0.0, 0.0])
        u[axis] += A * math.sin(omega * t)
        return u
    vel = _simulate(ports, unzipped, force, t0 + 2.0 * period)
    t = np.arange(len(vel)) * ports.step
    keep = t >= t0
    # the force is held over each step (zero-order hold): its fundamental is the sine's
    # times sinc(w h / 2) e^(-j w h / 2), which the response is divided by
    half = 0.5 * omega * ports.step
    hold = math.sin(half) / half * complex(math.cos(half), -math.sin(half))
    return sine_response(t[keep], vel[keep, axis], omega, A) / hold


def identify(ports: FmuPorts, omegas: tuple[float, ...] = FIT_OMEGAS) -> Identified:
    """Run the experiment (module docstring) on the FMU and fit M, D per axis."""
    from fmpy import extract
    tmp = tempfile.mkdtemp(prefix="auv_identify_")
    try:
        unzipped = extract(str(ports.path), unzipdir=tmp)
        F0, settle = _trim(ports, unzipped)
        G = [tuple(response_of(ports, unzipped, a, w, F0, settle) for w in omegas)
             for a in range(3)]
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    om = np.array(omegas)
    fits = [fit_first_order_response(om, np.array(g)) for g in G]
    if ports.horizontal == "together":
        both = fit_first_order_response(np.concatenate([om, om]), np.array(G[0] + G[1]))
        fits[0] = fits[1] = both
    for a, (M, D) in enumerate(fits):
        if not (M > 0.0 and D > 0.0):
            raise ModelError(f"fmu: {ports.path.name}: the identified {_AXIS_NAMES[a]} axis "
                             f"has M = {M:.4g} kg, D = {D:.4g} kg/s, not both positive: "
                             "it does not respond like a mass and a damper to the force "
                             "(check the port map and the signs)")
    return Identified(M=tuple(f[0] for f in fits), D=tuple(f[1] for f in fits),
                      omegas=tuple(omegas), responses=tuple(G), kind=ports.kind,
                      name=ports.path.name, digest=ports.digest)


def _cache_key(ports: FmuPorts, omegas: tuple[float, ...]) -> str:
    what = [EXPERIMENT_VERSION, ports.digest, ports.kind, ports.inputs, ports.position,
            ports.velocity, ports.start_position, ports.start_velocity, ports.cruise_speed,
            ports.step, ports.amplitude, ports.horizontal, omegas, START_DEPTH]
    return hashlib.sha256(json.dumps(what).encode()).hexdigest()[:32]


def identified(ports: FmuPorts, omegas: tuple[float, ...] = FIT_OMEGAS) -> Identified:
    """:func:`identify`, or its cached result for the same FMU bytes and settings; its
    :meth:`Identified.text` printed on stderr once per process."""
    from fmu_common.cache import fmu_cache_dir
    key = _cache_key(ports, omegas)
    if key in _memo:
        return _memo[key]
    path = fmu_cache_dir() / "identified" / f"{ports.digest[:16]}-{key}.json"
    fit = None
    if path.exists():
        try:
            d = json.loads(path.read_text())
            fit = Identified(M=tuple(d["M"]), D=tuple(d["D"]), omegas=tuple(d["omegas"]),
                             responses=tuple(tuple(complex(re, im) for re, im in r)
                                             for r in d["responses"]),
                             kind=d["kind"], name=ports.path.name, digest=ports.digest,
                             cached=True)
        except (ValueError, KeyError, TypeError):
            fit = None                          # a damaged entry: identify again
    if fit is None:
        fit = identify(ports, omegas)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{id(fit)}.tmp")
        tmp.write_text(json.dumps({
            "M": fit.M, "D": fit.D, "omegas": fit.omegas, "kind": fit.kind,
            "responses": [[[g.real, g.imag] for g in r] for r in fit.responses]}))
        tmp.replace(path)
    _memo[key] = fit
    if key not in _printed:
        _printed.add(key)
        print(fit.text())          # part of the run's printout, on stdout
    return fit


def fmu_vehicle_from_params(params: Mapping[str, Any]) -> VehicleModel:
    """The design model of a vehicle FMU: its ports checked, the model identified (or read
    from the identification cache by the FMU's digest), M v' = u - D v per NED axis
    (:func:`plant_model.vehicles._ned_axes_model`, model name ``fmu``).

    Raises
    ------
    ModelError
        A bad port map or FMU (one line), or an identification that fails.
    """
    ports = fmu_ports(params)
    fit = identified(ports)
    parameters: dict[str, Any] = {
        "total_mass": list(fit.M), "damping": list(fit.D), "cruise_speed": ports.cruise_speed,
        "ports": ports, "fit": fit.summary(), "spec": dict(params)}
    if ports.kind == "setpoints":
        M0, D0 = guidance_model(ports)
        parameters.update(guidance_mass=M0.tolist(), guidance_damping=D0.tolist())
    return _ned_axes_model("fmu", np.asarray(fit.M), np.asarray(fit.D), parameters)
