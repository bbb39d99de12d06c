"""``model = "fmu"``: a vehicle the user brings as an FMI 2.0 co-simulation FMU.

The scenario names the FMU (a path, relative to the scenario file) and a port map from the
project's signals to the FMU's scalar variables (docs/scenarios.md, "A vehicle brought as
an FMU")::

    [vehicles.params]
    fmu = "torpedo.fmu"
    inputs  = { speed = "U_d", heading = "psi_d", depth = "z_d" }   # or force = [3 names]
    outputs = { position = ["n", "e", "d"], velocity = ["v_n", "v_e", "v_d"] }
    start   = { position = ["n0", "e0", "d0"] }                     # optional parameters

Inputs are either a NED force (``force``: north, east, down, N) or set-points (``speed``
through the water, m/s; ``heading`` (the course), rad; ``depth``, m, positive down; and
optionally their rates ``speed_rate``, ``heading_rate``, ``depth_rate``), which the
guidance FMU (controller_fmu/guidance.py) computes from the controller's force. Outputs:
NED position (m) and velocity over ground (m/s). ``start``: the FMU parameters that take
the vehicle's start position (m) and velocity (m/s) from the scenario.

The design model is identified from the FMU (:mod:`plant_model.vehicle_fmu_identification`):
per NED axis M_a v_a' = u_a - D_a v_a (M kg, D kg/s) from its frequency responses at a
trim, the registry's ``ned`` layout. The FMU is checked here, before anything runs: a
missing file, a file that is not a co-simulation FMU, a port naming a variable the FMU
does not have or one of the wrong causality, an input of the FMU left out of the port
map: each refused in one line naming the port and the variable (the registry prefixes
the vehicle).
"""
from __future__ import annotations

import hashlib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .linalg_checks import ModelError, as_positive
from .vehicles import VehicleModel, remus100

__all__ = ["FMU_PARAMS", "GUIDED_FMU_STACK", "FmuPorts", "SETPOINT_PORTS", "VehicleFmuPorts",
           "fmu_explicit_params", "fmu_ports", "fmu_stack",
           "guidance_model"]

#: the per-vehicle FMU kinds between the controller and a set-point vehicle FMU
GUIDED_FMU_STACK = ("guidance",)

#: the parameters of a ``model = "fmu"`` vehicle
FMU_PARAMS = ("fmu", "inputs", "outputs", "start", "cruise_speed", "step", "amplitude",
              "horizontal")
#: set-point ports -> the guidance output that feeds each (controller_fmu.guidance)
SETPOINT_PORTS = {"speed": "speed", "heading": "course", "depth": "depth",
                  "speed_rate": "speed_rate", "heading_rate": "course_rate",
                  "depth_rate": "depth_rate"}
_AXES = ("north", "east", "down")


@dataclass(frozen=True)
class FmuPorts:
    """A vehicle FMU and its port map, checked against its modelDescription."""

    path: Path                          #: the .fmu (absolute)
    digest: str                         #: SHA-256 of the file's bytes
    kind: str                           #: "force" or "setpoints"
    inputs: tuple[tuple[str, str], ...]  #: (port, FMU variable): force[1..3] or set-points
    position: tuple[str, str, str]      #: FMU outputs: north, east, down (m)
    velocity: tuple[str, str, str]      #: FMU outputs: v_north, v_east, v_down (m/s)
    start_position: tuple[str, ...]     #: FMU parameters set to the start position (or ())
    start_velocity: tuple[str, ...]     #: FMU parameters set to the start velocity (or ())
    model_identifier: str               #: its co-simulation model identifier
    native: bool                        #: compiled code, no Python inside (not pythonfmu)
    cruise_speed: float = 1.5           #: trim speed of the identification, m/s
    step: float = 0.05                  #: communication step of the identification, s
    amplitude: float = 2.0              #: force amplitude of the identification, N
    horizontal: str = "together"        #: "together": one M, D for north and east

    @property
    def force(self) -> tuple[str, ...]:
        """The FMU inputs of the NED force (N), north, east, down (force kind)."""
        return tuple(v for _, v in self.inputs) if self.kind == "force" else ()


def _names(port: str, value: Any, n: int) -> tuple[str, ...]:
    ok = (isinstance(value, (list, tuple)) and len(value) == n
          and all(isinstance(v, str) and v for v in value))
    if not ok:
        raise ModelError(f"fmu port {port}: expected a list of {n} variable names "
                         f"[{', '.join(_AXES[:n]) if n == 3 else '...'}], got {value!r}")
    return tuple(value)


def _digest(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def fmu_ports(params: Mapping[str, Any]) -> FmuPorts:
    """The port map of ``params`` checked against the FMU's modelDescription.

    Raises
    ------
    ModelError
        In one line naming the port and the variable (module docstring).
    """
    unknown = sorted(str(k) for k in params if k not in FMU_PARAMS)
    if unknown:
        raise ModelError(f"unknown fmu parameter(s) {', '.join(unknown)}; accepted: "
                         f"{', '.join(FMU_PARAMS)}")
    raw = params.get("fmu")
    if not isinstance(raw, str) or not raw:
        raise ModelError(f"fmu: the path of the vehicle's .fmu file is required, got {raw!r}")
    path = Path(raw).expanduser().resolve()
    if not path.is_file():
        raise ModelError(f"fmu: no file {raw!r} (looked for {path})")
    from fmpy import read_model_description
    try:
        md = read_model_description(str(path), validate=False)
    except Exception as exc:                # not a zip, no modelDescription.xml, bad XML
        raise ModelError(f"fmu: {path.name} is not an FMU ({str(exc).splitlines()[0]})") \
            from None
    if md.fmiVersion != "2.0":
        raise ModelError(f"fmu: {path.name} is FMI {md.fmiVersion}; an FMI 2.0 "
                         "co-simulation FMU is needed")
    if md.coSimulation is None:
        raise ModelError(f"fmu: {path.name} is not a co-simulation FMU (model exchange "
                         "only); export it for co-simulation")
    var = {v.name: v for v in md.modelVariables}

    def check(port: str, name: str, causality: tuple[str, ...]) -> str:
        if name not in var:
            have = [v.name for v in md.modelVariables if v.causality in causality]
            raise ModelError(f"fmu port {port}: {path.name} has no variable {name!r} (its "
                             f"{'/'.join(causality)}s: {', '.join(have[:12]) or 'none'})")
        v = var[name]
        if v.causality not in causality:
            raise ModelError(f"fmu port {port}: variable {name!r} of {path.name} is "
                             f"{v.causality}, not {' or '.join(causality)}")
        if v.type != "Real":
            raise ModelError(f"fmu port {port}: variable {name!r} of {path.name} is "
                             f"{v.type}, not Real")
        return name

    ins = params.get("inputs")
    if not isinstance(ins, Mapping) or not ins:
        raise ModelError("fmu port inputs: a table, either force = [north, east, down] or "
                         f"set-points {', '.join(SETPOINT_PORTS)}; got {ins!r}")
    if "force" in ins:
        if set(ins) != {"force"}:
            raise ModelError(f"fmu port inputs: force and set-points cannot be mixed "
                             f"(got {', '.join(map(str, ins))})")
        kind = "force"
        pairs = tuple((f"force[{k + 1}]", check(f"inputs.force[{k + 1}]", n, ("input",)))
                      for k, n in enumerate(_names("inputs.force", ins["force"], 3)))
    else:
        bad = sorted(str(k) for k in ins if k not in SETPOINT_PORTS)
        if bad:
            raise ModelError(f"fmu port inputs.{bad[0]}: not a port; inputs are force = "
                             f"[3 names] or set-points {', '.join(SETPOINT_PORTS)}")
        missing = [p for p in ("speed", "heading", "depth") if p not in ins]
        if missing:
            raise ModelError(f"fmu port inputs.{missing[0]}: required with set-point "
                             "inputs (speed, heading, depth)")
        kind = "setpoints"
        pairs = tuple((p, check(f"inputs.{p}", ins[p] if isinstance(ins[p], str) else
                                str(ins[p]), ("input",))) for p in SETPOINT_PORTS if p in ins)
    outs = params.get("outputs")
    if not isinstance(outs, Mapping) or set(outs) != {"position", "velocity"}:
        raise ModelError("fmu port outputs: a table position = [north, east, down], "
                         f"velocity = [v_north, v_east, v_down]; got {outs!r}")
    pos = tuple(check(f"outputs.position[{k + 1}]", n, ("output",))
                for k, n in enumerate(_names("outputs.position", outs["position"], 3)))
    vel = tuple(check(f"outputs.velocity[{k + 1}]", n, ("output",))
                for k, n in enumerate(_names("outputs.velocity", outs["velocity"], 3)))
    start = params.get("start", {})
    if not isinstance(start, Mapping) or set(start) - {"position", "velocity"}:
        raise ModelError(f"fmu port start: a table with position and/or velocity (3 FMU "
                         f"parameters each); got {start!r}")
    s_pos, s_vel = (tuple(check(f"start.{key}[{k + 1}]", n, ("parameter",))
                          for k, n in enumerate(_names(f"start.{key}", start[key], 3)))
                    if key in start else () for key in ("position", "velocity"))
    mapped = {n for _, n in pairs}
    left = [v.name for v in md.modelVariables if v.causality == "input" and v.name not in mapped]
    if left:
        raise ModelError(f"fmu port inputs: input {left[0]!r} of {path.name} is not in the "
                         "port map (every input of the vehicle FMU must be fed)")
    horizontal = params.get("horizontal", "together")
    if horizontal not in ("together", "separate"):
        raise ModelError(f"fmu horizontal = {horizontal!r} is not one of together, separate")
    tool = (md.generationTool or "").lower()
    return FmuPorts(
        path=path, digest=_digest(path), kind=kind, inputs=pairs, position=pos,
        velocity=vel, start_position=s_pos, start_velocity=s_vel,
        model_identifier=md.coSimulation.modelIdentifier,
        native="pythonfmu" not in tool and not md.coSimulation.needsExecutionTool,
        cruise_speed=as_positive("cruise_speed", params.get("cruise_speed", 1.5), "m/s"),
        step=as_positive("step", params.get("step", 0.05), "s"),
        amplitude=as_positive("amplitude", params.get("amplitude", 2.0), "N"),
        horizontal=horizontal)


def guidance_model(ports: FmuPorts) -> tuple[np.ndarray, np.ndarray]:
    """(M, D) per NED axis (kg, kg/s) of the guidance that turns the controller's force into
    a set-point FMU's set-points: the linear ``remus100`` at the cruise speed (a REMUS
    100-class torpedo; it scales the virtual force, the identification measures the rest)."""
    lin = remus100(cruise_speed=ports.cruise_speed)
    return (np.array(lin.parameters["total_mass"], float),
            np.array(lin.parameters["damping"], float))


def fmu_explicit_params(model: VehicleModel) -> dict[str, Any]:
    """The parameters of a vehicle FMU as given, its path made absolute."""
    spec = dict(model.parameters["spec"])
    spec["fmu"] = str(model.parameters["ports"].path)
    return spec


def fmu_stack(model: VehicleModel) -> tuple[str, ...]:
    """The guidance before a set-point vehicle FMU; nothing before a force one."""
    return GUIDED_FMU_STACK if model.parameters["ports"].kind == "setpoints" else ()


def fmu_port_config(ports: FmuPorts, mode: str, *, truth: bool, sensors: bool, where: str,
                    first: list[Mapping[str, Any]]) -> dict[str, Any]:
    """The port map as JSON-ready data (a per-vehicle FMU configuration's ``fmu``).

    Raises
    ------
    ModelError
        In one line naming the vehicle: an estimator ``mode`` that reads the truth
        (``truth``: its registry row's ``uses_truth``; the FMU has no current to give),
        navigation ``[sensors]`` (the FMU outputs its position, not REMUS navigation), or
        another FMU than vehicle 1's (one FMU file per fleet: ``first`` is vehicle 1's
        configurations).
    """
    if truth:
        raise ModelError(f"{where}: estimator {mode} needs the true current, which a vehicle "
                         f"FMU ({ports.path.name}) does not give; use a filter")
    if sensors:
        raise ModelError(f"{where}: [sensors] models REMUS navigation; a vehicle FMU "
                         f"({ports.path.name}) gives its own position: leave [sensors] out")
    for cfg in (c.get("vehicle_fmu") for c in first):
        if cfg is not None and cfg["fmu"]["digest"] != ports.digest:
            raise ModelError(f"{where}: its FMU {ports.path} differs from vehicle 1's "
                             f"{cfg['fmu']['path']}; a fleet flies one vehicle FMU")
    return {"path": str(ports.path), "digest": ports.digest, "kind": ports.kind,
            "inputs": [list(p) for p in ports.inputs], "position": list(ports.position),
            "velocity": list(ports.velocity), "start_position": list(ports.start_position),
            "start_velocity": list(ports.start_velocity), "native": ports.native}


class VehicleFmuPorts:
    """The interface of a vehicle FMU's component in a per-vehicle system: the project's
    arrays, each element named by the port map (:attr:`ArraySpec.scalars`)."""

    @staticmethod
    def interface(config: Mapping[str, Any]) -> list[Any]:
        """Parameters ``start_position``, ``start_velocity`` (those the port map names,
        start values the vehicle's x0); inputs ``u`` (force, N) or one per set-point
        (the guidance's output names: speed, course, depth, ...); outputs ``y`` (position,
        m), ``x`` (position and velocity, the design model's state), ``velocity`` (m/s)."""
        from fmu_common.interface import ArraySpec
        f = config["fmu"]
        x0 = [float(v) for v in config["system"]["x0"]]
        specs = []
        for key, vals in (("start_position", x0[:3]), ("start_velocity", x0[3:6])):
            if f[key]:
                specs.append(ArraySpec(key, (3,), "parameter", f"the vehicle's {key[6:]}",
                                       start=vals, scalars=tuple(f[key])))
        if f["kind"] == "force":
            specs.append(ArraySpec("u", (3,), "input", "NED force", start=[0.0] * 3,
                                   unit="N", scalars=tuple(n for _, n in f["inputs"])))
        else:
            specs += [ArraySpec(SETPOINT_PORTS[p], (), "input", f"set-point {p}", start=0.0,
                                scalars=(n,)) for p, n in f["inputs"]]
        pos, vel = tuple(f["position"]), tuple(f["velocity"])
        return specs + [
            ArraySpec("y", (3,), "output", "NED position", unit="m", scalars=pos),
            ArraySpec("x", (6,), "output", "NED position and velocity", scalars=pos + vel),
            ArraySpec("velocity", (3,), "output", "NED velocity", unit="m/s", scalars=vel)]
