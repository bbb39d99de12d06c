"""Export the three FMUs as an Open Simulation Platform (OSP / libcosim) system.

:func:`export_osp` builds the FMUs of a scenario into a folder and writes beside them

- ``OspSystemStructure.xml``: the three simulators (``plant``, ``estimator``,
  ``controller``), the scenario's parameter values as ``InitialValues`` (Real, Integer
  and String), ``BaseStepSize`` = h, ``EndTime`` = T, ``Algorithm`` fixedStep and one
  ``VariableConnection`` per scalar signal::

      plant.y, ybar, x, w, z   -> estimator.y, ybar, x, w, z   (x, w, z: the truth, read
                                                                 only in mode 'ideal')
      estimator.xhat, what, zhat -> controller.xhat, what, zhat
      controller.u             -> plant.u, estimator.u

- ``<model>_OspModelDescription.xml`` per FMU (libcosim looks for the file of that name
  next to the FMU): units and variable groups. Every array of the interface is a
  ``Generic`` group of its name (parameters with the unit their modelDescription
  declares). For a fleet, the vehicle signals hold typed OSP-IS groups per vehicle
  inside that Generic group, chosen from the unit of the vehicle model's quantity:
  positions (m) ``LinearDisplacement``, velocities and the ocean current (m/s)
  ``LinearVelocity``, the control forces u (N) ``Force``, with ``axis`` x, y, z for the
  NED axes. The paper's example is dimensionless: its signals are Generic groups only.

Before anything is written the connections are checked (:func:`check_connections`):
a variable an FMU lacks, a connection of two outputs or of two inputs, a type mismatch,
an input fed twice or left unconnected is refused with ``export refused: ...`` naming the
variable. What is written is validated against OSP's XML schemas shipped in
``orchestrator/osp_schemas/`` (see the README there for where they come from).

:func:`run_libcosim` runs an exported system in libcosim through libcosimpy and returns
its traces in the layout of :class:`orchestrator.master.RunResult`. libcosim's fixed-step
algorithm steps every simulator, then transfers outputs to inputs: every FMU sees the
other FMUs' outputs of the previous communication point
(``run_cosimulation(..., coupling="jacobi")`` does the same thing on fmpy).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
from lxml import etree

from fmu_common.interface import UNIT_DEFINITIONS, element_names
from .fmu_build import FMU_KINDS, interface_of
from .master import ESTIMATOR_OUTPUTS, LOOP_CONNECTIONS, PLANT_OUTPUTS, fmu_parameters, signal_size
from .scenario import Scenario

__all__ = ["ExportError", "Connection", "VariableInfo", "SCHEMA_DIR", "OSP_SYSTEM_NS",
           "OSP_MD_NS", "SIMULATORS", "check_connections", "system_connections",
           "fmu_variables", "export_osp", "validate_osp_file", "run_libcosim",
           "libcosim_version", "quiet_libcosim", "typed_groups_used", "jacobi_closed_loop",
           "predict_stationary_jacobi"]

SCHEMA_DIR = Path(__file__).resolve().parent / "osp_schemas"
OSP_SYSTEM_NS = "http://opensimulationplatform.com/MSMI/OSPSystemStructure"
OSP_MD_NS = "https://open-simulation-platform.com/OspModelDescription/1.0.1"
_SCHEMA_FILES = {"OspSystemStructure": "OspSystemStructure.xsd",
                 "OspModelDescription": "OspModelDescription-1.0.1.xsd"}

#: simulator (instance) name in the system -> key of orchestrator.fmu_build.FMU_KINDS
SIMULATORS = ("plant", "estimator", "controller")

#: OSP-IS typed variable group for a quantity of this unit (at most 3 variables each)
TYPED_GROUP_OF_UNIT = {"m": "LinearDisplacement", "m/s": "LinearVelocity", "N": "Force",
                       "m/s2": "LinearAcceleration", "rad": "AngularDisplacement",
                       "rad/s": "AngularVelocity"}
_GROUP_SUFFIX = {"LinearDisplacement": "displacement", "LinearVelocity": "velocity",
                 "Force": "force", "LinearAcceleration": "acceleration",
                 "AngularDisplacement": "angle", "AngularVelocity": "angular_velocity"}
#: order of the typed groups in OSP's schema (xs:sequence of GenericType / VariableGroupsType)
_GROUP_ORDER = ("Variable", "Generic", "Force", "Torque", "Voltage", "Pressure",
                "LinearVelocity", "AngularVelocity", "Current", "VolumeFlowRate",
                "LinearDisplacement", "AngularDisplacement", "Charge", "Volume",
                "LinearAcceleration", "AngularAcceleration")


class ExportError(ValueError):
    """The system cannot be exported; the message starts with ``export refused:``."""


@dataclass(frozen=True)
class VariableInfo:
    """What the connection check needs to know of an FMU variable."""

    causality: str          #: parameter, calculatedParameter, input, output, local, independent
    type: str               #: Real, Integer, Boolean, String, Enumeration


@dataclass(frozen=True)
class Connection:
    """``source`` (simulator, variable) feeds ``target`` (simulator, variable)."""

    source: tuple[str, str]
    target: tuple[str, str]

    def __str__(self) -> str:
        return f"{self.source[0]}.{self.source[1]} -> {self.target[0]}.{self.target[1]}"


def _refuse(msg: str) -> ExportError:
    return ExportError(f"export refused: {msg}")


def check_connections(variables: Mapping[str, Mapping[str, VariableInfo]],
                      connections: Sequence[Connection]) -> None:
    """Refuse (:class:`ExportError`, ``export refused: ...``) a connection that names a
    simulator or a variable that does not exist, connects two outputs or two inputs,
    connects anything but an output to an input, or connects variables of different
    types; an input fed by two connections; an input of any simulator left unconnected.

    ``variables``: simulator name -> variable name -> :class:`VariableInfo`.
    """
    fed: dict[tuple[str, str], Connection] = {}
    for c in connections:
        ends = []
        for role, (sim, name) in (("source", c.source), ("target", c.target)):
            if sim not in variables:
                raise _refuse(f"connection {c}: there is no simulator {sim!r} "
                              f"(simulators: {', '.join(variables)})")
            info = variables[sim].get(name)
            if info is None:
                raise _refuse(f"connection {c}: simulator {sim!r} has no variable {name!r}")
            ends.append(info)
        src, tgt = ends
        if src.causality == "output" and tgt.causality == "output":
            raise _refuse(f"connection {c} connects two outputs "
                          f"({c.source[0]}.{c.source[1]} and {c.target[0]}.{c.target[1]})")
        if src.causality == "input" and tgt.causality == "input":
            raise _refuse(f"connection {c} connects two inputs "
                          f"({c.source[0]}.{c.source[1]} and {c.target[0]}.{c.target[1]})")
        if src.causality != "output":
            raise _refuse(f"connection {c}: source {c.source[0]}.{c.source[1]} is "
                          f"{'an' if src.causality[0] in 'aeiou' else 'a'} {src.causality}, "
                          "not an output")
        if tgt.causality != "input":
            raise _refuse(f"connection {c}: target {c.target[0]}.{c.target[1]} is "
                          f"{'an' if tgt.causality[0] in 'aeiou' else 'a'} {tgt.causality}, "
                          "not an input")
        if src.type != tgt.type:
            raise _refuse(f"connection {c} connects a {src.type} output to a {tgt.type} input")
        if c.target in fed:
            raise _refuse(f"input {c.target[0]}.{c.target[1]} is fed twice ({fed[c.target]} "
                          f"and {c})")
        fed[c.target] = c
    for sim, names in variables.items():
        for name, info in names.items():
            if info.causality == "input" and (sim, name) not in fed:
                raise _refuse(f"input {sim}.{name} is not connected")


def system_connections(dims: Mapping[str, int]) -> list[Connection]:
    """The closed loop's connections, one per scalar, for the dimensions ``dims``."""
    return [Connection((src, name), (tgt, name))
            for src, signal, tgt in LOOP_CONNECTIONS
            for name in element_names(signal, (signal_size(signal, dims),))]


def fmu_variables(fmu: Path | str) -> dict[str, VariableInfo]:
    """Name -> (causality, type) of every variable of an FMU, from its modelDescription."""
    from fmpy import read_model_description
    md = read_model_description(str(fmu))
    return {v.name: VariableInfo(v.causality, v.type) for v in md.modelVariables}


# ----------------------------------------------------------------------------- groups

@dataclass(frozen=True)
class _Element:
    unit: str            #: "" when the quantity has no unit
    vehicle: int | None  #: 1-based vehicle, None outside a fleet
    component: str       #: e.g. "n", "v_e", "X_d"


def _signal_layout(sc: Scenario) -> dict[str, list[_Element]]:
    """Per element of each loop signal: its unit and vehicle (fleets of vehicle models
    with units), else unit-less elements."""
    d = sc.system.dims
    names = ("y", "ybar", "x", "w", "z", "e", "u", "xhat", "what", "zhat")
    plain = {s: [_Element("", None, str(i + 1)) for i in range(signal_size(s, d))] for s in names}
    if sc.fleet is None:
        return plain
    from plant_model.fleet import fleet_vehicles
    models = fleet_vehicles(sc.fleet)
    per = {"x": ("state_names", "state_units"), "u": ("input_names", "input_units"),
           "w": ("disturbance_names", "disturbance_units"),
           "y": ("output_names", "output_units")}
    per.update({"xhat": per["x"], "what": per["w"], "e": per["y"], "ybar": per["y"]})
    out = dict(plain)
    for sig, (nattr, uattr) in per.items():
        elems = [_Element(u, i, nm) for i, mdl in enumerate(models, start=1)
                 for nm, u in zip(getattr(mdl, nattr), getattr(mdl, uattr))]
        if len(elems) == signal_size(sig, d):      # else: keep the unit-less layout
            out[sig] = elems
    return out


def _typed_groups(sig: str, names: list[str], elems: list[_Element]) -> list[tuple[str, str, list]]:
    """(group type, group name, [(variable, unit, axis)]) of the typed groups of one
    signal: per vehicle, runs of consecutive elements of one unit that OSP-IS has a type
    for, at most 3 per group, named ``<signal>.vehicle[i].<displacement|velocity|force>``;
    a run of 3 gets the axes x, y, z (the vehicle models' NED north, east, down)."""
    groups: list[tuple[str, str, list]] = []
    seen: dict[str, int] = {}
    k = 0
    while k < len(elems):
        e = elems[k]
        kind = TYPED_GROUP_OF_UNIT.get(e.unit)
        j = k + 1
        while (j < len(elems) and j - k < 3 and elems[j].unit == e.unit
               and elems[j].vehicle == e.vehicle):
            j += 1
        if kind is not None and e.vehicle is not None:
            axes = ("x", "y", "z") if j - k == 3 else (None,) * (j - k)
            base = f"{sig}.vehicle[{e.vehicle}].{_GROUP_SUFFIX[kind]}"
            seen[base] = seen.get(base, 0) + 1
            name = base if seen[base] == 1 else f"{base}_{seen[base]}"
            groups.append((kind, name,
                           [(names[i], elems[i].unit, axes[i - k]) for i in range(k, j)]))
        k = j
    return groups


def _md_element(tag: str, **attrs: str) -> etree._Element:
    return etree.Element(f"{{{OSP_MD_NS}}}{tag}", {k: v for k, v in attrs.items() if v})


def _osp_model_description(kind_key: str, config: dict[str, Any],
                           layout: dict[str, list[_Element]]) -> tuple[bytes, list[str]]:
    """An OspModelDescription for one FMU; returns the bytes and the typed group types used."""
    specs = interface_of(FMU_KINDS[kind_key], config)
    units_used: list[str] = []
    typed_used: list[str] = []

    def use(unit: str | None) -> str | None:
        if unit and unit not in units_used:
            units_used.append(unit)
        return unit or None

    groups = []
    for spec in specs:
        names = element_names(spec.name, spec.shape)
        g = _md_element("Generic", name=spec.name)
        children: list[tuple[str, etree._Element]] = []
        if spec.causality != "parameter" and spec.name in layout:
            elems = layout[spec.name]
            typed = _typed_groups(spec.name, names, elems)
            in_typed = {v for _, _, vs in typed for v, _, _ in vs}
            for nm, el in zip(names, elems):
                if nm not in in_typed:
                    children.append(("Variable", _md_element("Variable", ref=nm,
                                                             unit=use(el.unit) or "")))
            for kind, gname, vs in typed:
                tg = _md_element(kind, name=gname)
                for nm, unit, axis in vs:
                    tg.append(_md_element("Variable", ref=nm, unit=use(unit) or "",
                                          axis=axis or ""))
                children.append((kind, tg))
                if kind not in typed_used:
                    typed_used.append(kind)
        else:
            for nm in names:
                children.append(("Variable", _md_element("Variable", ref=nm,
                                                         unit=use(spec.unit) or "")))
        for _, child in sorted(children, key=lambda c: _GROUP_ORDER.index(c[0])):
            g.append(child)
        groups.append(g)
    root = etree.Element(f"{{{OSP_MD_NS}}}OspModelDescription", version="1.0",
                         nsmap={None: OSP_MD_NS})
    unknown = [u for u in units_used if u not in UNIT_DEFINITIONS]
    if unknown:
        raise ExportError(f"export refused: no SI definition for unit(s) {unknown}")
    if units_used:
        ud = etree.SubElement(root, f"{{{OSP_MD_NS}}}UnitDefinitions")
        for u in units_used:
            unit = etree.SubElement(ud, f"{{{OSP_MD_NS}}}Unit", name=u)
            etree.SubElement(unit, f"{{{OSP_MD_NS}}}BaseUnit",
                             {k: str(v) for k, v in UNIT_DEFINITIONS[u].items()})
    vg = etree.SubElement(root, f"{{{OSP_MD_NS}}}VariableGroups")
    for g in groups:                     # all top-level groups are Generic
        vg.append(g)
    etree.indent(root, space="  ")
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8",
                          pretty_print=True), typed_used


# ------------------------------------------------------------------- system structure

def _fmt_real(v: Any) -> str:
    return repr(float(v))


def _system_structure(sc: Scenario, config: dict[str, Any], fmus: Mapping[str, Path],
                      variables: Mapping[str, Mapping[str, VariableInfo]],
                      connections: Sequence[Connection]) -> bytes:
    ns = OSP_SYSTEM_NS

    def el(parent, tag, **attrs):
        return etree.SubElement(parent, f"{{{ns}}}{tag}", attrs)

    root = etree.Element(f"{{{ns}}}OspSystemStructure", version="0.1", nsmap={None: ns})
    el(root, "StartTime").text = "0.0"
    el(root, "EndTime").text = _fmt_real(sc.T)
    el(root, "BaseStepSize").text = _fmt_real(sc.h)
    el(root, "Algorithm").text = "fixedStep"
    sims = el(root, "Simulators")
    for key in SIMULATORS:
        sim = el(sims, "Simulator", name=key, source=Path(fmus[key]).name)
        ivs = el(sim, "InitialValues")
        for name, value in fmu_parameters(key, config).items():
            info = variables[key].get(name)
            if info is None:
                raise _refuse(f"initial value: simulator {key!r} has no parameter {name!r}")
            iv = el(ivs, "InitialValue", variable=name)
            if info.type == "Real":
                el(iv, "Real", value=_fmt_real(value))
            elif info.type == "Integer":
                el(iv, "Integer", value=str(int(value)))
            elif info.type == "Boolean":
                el(iv, "Boolean", value="true" if value else "false")
            else:
                el(iv, "String", value=str(value))
    conns = el(root, "Connections")
    for c in connections:
        vc = el(conns, "VariableConnection")
        el(vc, "Variable", simulator=c.source[0], name=c.source[1])
        el(vc, "Variable", simulator=c.target[0], name=c.target[1])
    etree.indent(root, space="  ")
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


_SCHEMAS: dict[str, etree.XMLSchema] = {}


def _schema(kind: str) -> etree.XMLSchema:
    if kind not in _SCHEMAS:
        _SCHEMAS[kind] = etree.XMLSchema(etree.parse(str(SCHEMA_DIR / _SCHEMA_FILES[kind])))
    return _SCHEMAS[kind]


def validate_osp_file(path: Path | str) -> list[str]:
    """Problems of an OspSystemStructure.xml or *_OspModelDescription.xml against OSP's
    XML schema (empty when valid)."""
    doc = etree.parse(str(path))
    local = etree.QName(doc.getroot()).localname
    if local not in _SCHEMA_FILES:
        return [f"{path}: root element {local!r} is neither OspSystemStructure nor "
                "OspModelDescription"]
    schema = _schema(local)
    if schema.validate(doc):
        return []
    return [f"{Path(path).name}:{e.line}: {e.message}" for e in schema.error_log]


def export_osp(sc: Scenario, out_dir: Path | str) -> dict[str, Path]:
    """Build the scenario's FMUs into ``out_dir`` and write the OSP system beside them.

    Returns ``{"system": OspSystemStructure.xml, "plant" | "estimator" | "controller":
    the .fmu, "plant_osp" | "estimator_osp" | "controller_osp": its
    <model>_OspModelDescription.xml}``. Run settings (seed, estimator mode, tracking law)
    are the scenario's: use ``sc.with_run(...)`` for others.
    """
    from .workflow import build, scenario_config

    out = Path(out_dir)
    config = scenario_config(sc)
    # check the wiring on the interface tables first: nothing is built or written for a
    # system that would not connect
    planned = {key: {name: VariableInfo(spec.causality, spec.type)
                     for spec in interface_of(FMU_KINDS[key], config)
                     for name in element_names(spec.name, spec.shape)}
               for key in SIMULATORS}
    connections = system_connections(sc.system.dims)
    check_connections(planned, connections)
    fmus = build(sc, out)
    variables = {key: fmu_variables(fmus[key]) for key in SIMULATORS}
    check_connections(variables, connections)      # the FMUs as built
    paths: dict[str, Path] = {}
    layout = _signal_layout(sc)
    written: list[Path] = []
    for key in SIMULATORS:
        xml, _ = _osp_model_description(key, config, layout)
        p = out / f"{FMU_KINDS[key].model}_OspModelDescription.xml"
        p.write_bytes(xml)
        paths[key] = Path(fmus[key])
        paths[f"{key}_osp"] = p
        written.append(p)
    system = out / "OspSystemStructure.xml"
    system.write_bytes(_system_structure(sc, config, fmus, variables, connections))
    paths["system"] = system
    written.append(system)
    problems = [msg for p in written for msg in validate_osp_file(p)]
    if problems:
        raise ExportError("the exported OSP files do not validate against OSP's schemas: "
                          + "; ".join(problems))
    return paths


def typed_groups_used(sc: Scenario) -> dict[str, list[str]]:
    """The OSP-IS typed variable groups the export declares for each FMU of ``sc``."""
    from .workflow import scenario_config
    config = scenario_config(sc)
    layout = _signal_layout(sc)
    return {key: _osp_model_description(key, config, layout)[1] for key in SIMULATORS}


# ---------------------------------------------------------------------------- libcosim

def libcosim_version() -> dict[str, str]:
    """Versions of libcosimpy and of the libcosim / libcosimc libraries it ships."""
    import ctypes
    import importlib.metadata as md
    out = {}
    try:
        out["libcosimpy"] = md.version("libcosimpy")
    except md.PackageNotFoundError:
        return {"libcosimpy": "not installed"}

    class _Version(ctypes.Structure):
        _fields_ = [("major", ctypes.c_int), ("minor", ctypes.c_int), ("patch", ctypes.c_int)]

    try:
        from libcosimpy._internal import libcosimc
        lib = libcosimc()
        for key, fn in (("libcosim", "cosim_libcosim_version"),
                        ("libcosimc", "cosim_libcosimc_version")):
            f = getattr(lib, fn)
            f.restype = _Version
            f.argtypes = []
            v = f()
            out[key] = f"{v.major}.{v.minor}.{v.patch}"
    except Exception:  # noqa: BLE001 - version report only
        pass
    return out


def quiet_libcosim() -> None:
    """Only warnings and errors from libcosim (its default prints every FMI call)."""
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    log_output_level(CosimLogLevel.WARNING)


def run_libcosim(system: Path | str, config: dict[str, Any], steps: int, *,
                 record: bool = True) -> dict[str, Any]:
    """Run an exported system for ``steps`` steps of ``config['h']`` in libcosim
    (libcosimpy; time in integer nanoseconds).

    Returns ``{"traces": {signal: (steps, size) array} | None, "loop_s": seconds of
    stepping, "setup_s": seconds to load and connect the system}``. Row k of a trace is
    the value at t = k h that libcosim transferred into step k (the outputs read after
    step k - 1, or after initialization for k = 0): the layout of
    :class:`orchestrator.master.RunResult` with ``coupling="jacobi"``. ``loop_s`` times
    steps 2..steps (the first ``step()`` also initializes the FMUs and is left out, as
    run_cosimulation's loop_s leaves out initialization). ``record=False`` attaches no
    observer (timing only).
    """
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver

    d = config["dims"]
    h_ns = int(round(float(config["h"]) * 1e9))
    if h_ns <= 0 or abs(h_ns * 1e-9 - float(config["h"])) > 1e-12 * float(config["h"]):
        raise ValueError(f"h = {config['h']} s is not a whole number of nanoseconds")
    if steps < 2:
        raise ValueError("run_libcosim needs at least 2 steps")
    t0 = time.perf_counter()
    execution = CosimExecution.from_osp_config_file(str(system))
    index = {info.name.decode(): info.index for info in execution.slave_infos()}
    signals = {"plant": PLANT_OUTPUTS, "estimator": ESTIMATOR_OUTPUTS, "controller": ("u",)}
    observer = None
    refs: dict[str, tuple[int, list[int]]] = {}
    if record:
        observer = CosimObserver.create_time_series(buffer_size=steps + 1)
        execution.add_observer(observer)
        for sim, sigs in signals.items():
            vr = {v.name.decode(): v.reference for v in execution.slave_variables(index[sim])}
            for s in sigs:
                names = element_names(s, (signal_size(s, d),))
                refs[s] = (index[sim], [vr[n] for n in names])
                for r in refs[s][1]:
                    observer.start_time_series(index[sim], r, CosimVariableType.REAL)
    setup_s = time.perf_counter() - t0

    def fail(what: str) -> RuntimeError:
        from libcosimpy._internal import get_last_error_message
        return RuntimeError(f"libcosim: {what} failed: {get_last_error_message()}")

    t1 = time.perf_counter()
    if not execution.step(1):
        raise fail("initialization and first step")
    init_s = time.perf_counter() - t1
    t1 = time.perf_counter()
    if not execution.simulate_until(steps * h_ns):
        raise fail("simulate_until")
    loop_s = time.perf_counter() - t1
    traces = None
    if record:
        traces = {}
        for s, (slave, vrs) in refs.items():
            cols = []
            for r in vrs:
                # libcosimpy 0.0.6 trims the result by the number of zero step numbers,
                # which drops one sample since step 0 is a real one: ask for one more
                # (steps 0..steps exist: the observer keeps steps + 1 samples)
                _, step_no, values = observer.time_series_real_samples(slave, r, 0, steps + 1)
                step_no, values = list(step_no)[:steps], list(values)[:steps]
                if list(step_no) != list(range(len(step_no))) or len(values) != steps:
                    raise RuntimeError(f"libcosim observer returned steps {step_no[:3]}... "
                                       f"({len(values)} samples) for {s}, expected 0..{steps - 1}")
                cols.append(np.asarray(values, dtype=float))
            traces[s] = np.column_stack(cols)
    del observer, execution          # frees the FMU instances now
    return {"traces": traces, "loop_s": loop_s, "setup_s": setup_s, "init_s": init_s,
            "loop_steps": steps - 1}


# ------------------------------------------------------------ Jacobi-coupled prediction

def jacobi_closed_loop(model, est, Ks: np.ndarray):
    """(Phi, Gam, Gx, Geta) of the loop as libcosim (``coupling="jacobi"``) runs it.

    State X[k] = [s; q; EST; U] at communication point t_k: plant state s, estimator
    state q, the estimate EST the estimator outputs at t_k (computed after its step from
    q[k] and the measurement it still holds, mvec[k-1]) and the control U that the
    controller outputs at t_k (from the estimate it held, EST[k-1]). With
    mvec[k] = Ms s[k] + J eta[k] (the same Ms, J as orchestrator.prediction.closed_loop):

        s[k+1]   = Ad s + Bd U + [I 0] eta
        q[k+1]   = Aq (Ce q + Dm mvec[k]) + Bu U
        EST[k+1] = Ce q[k+1] + Dm mvec[k]
        U[k+1]   = -Ks EST[k]

    u[k] = U[k] is the control the plant holds over step k; e[k] = E s[k].
    """
    ns, p = model.ns, model.p
    nq = est.q0.shape[0]
    ne = est.Ce.shape[0]
    m = Ks.shape[0]
    nm = 2 * p + ns
    neta = ns + 2 * p
    Ms = np.vstack([model.M, np.eye(ns)])
    J = np.zeros((nm, neta))
    J[:2 * p, ns:] = np.eye(2 * p)
    iS, iQ, iE, iU = (np.arange(a, b) for a, b in
                      ((0, ns), (ns, ns + nq), (ns + nq, ns + nq + ne),
                       (ns + nq + ne, ns + nq + ne + m)))
    nX = ns + nq + ne + m
    Phi = np.zeros((nX, nX))
    Gam = np.zeros((nX, neta))
    Phi[np.ix_(iS, iS)] = model.Ad
    Phi[np.ix_(iS, iU)] = model.Bd
    Gam[iS, :ns] = np.eye(ns)
    # q[k+1] = Aq Dm Ms s + Aq Ce q + Bu U + Aq Dm J eta
    Phi[np.ix_(iQ, iS)] = est.Aq @ est.Dm @ Ms
    Phi[np.ix_(iQ, iQ)] = est.Aq @ est.Ce
    Phi[np.ix_(iQ, iU)] = est.Bu
    Gam[iQ] = est.Aq @ est.Dm @ J
    # EST[k+1] = Ce q[k+1] + Dm Ms s + Dm J eta
    Phi[np.ix_(iE, iS)] = est.Ce @ Phi[np.ix_(iQ, iS)] + est.Dm @ Ms
    Phi[np.ix_(iE, iQ)] = est.Ce @ Phi[np.ix_(iQ, iQ)]
    Phi[np.ix_(iE, iU)] = est.Ce @ est.Bu
    Gam[iE] = est.Ce @ Gam[iQ] + est.Dm @ J
    # U[k+1] = -Ks EST[k]
    Phi[np.ix_(iU, iE)] = -Ks
    Gx = np.zeros((m, nX))
    Gx[:, iU] = np.eye(m)
    Geta = np.zeros((m, neta))
    return Phi, Gam, Gx, Geta


def predict_stationary_jacobi(system, model, est, Ks: np.ndarray) -> dict[str, Any]:
    """Stationary RMS of e and u and the cost rate of the Jacobi-coupled loop
    (:func:`jacobi_closed_loop`), from Sigma = Phi Sigma Phi' + Gam W Gam'.

    Only for loops whose every state is noise-driven and stable (the paper's example);
    returns ``{"cost_rate": None, "reason": ...}`` otherwise.
    """
    from scipy.linalg import block_diag, solve_discrete_lyapunov

    Phi, Gam, Gx, Geta = jacobi_closed_loop(model, est, Ks)
    rho = float(np.max(np.abs(np.linalg.eigvals(Phi))))
    if rho >= 1.0:
        return {"rms_e": None, "rms_u": None, "cost_rate": None, "spectral_radius": rho,
                "reason": f"the Jacobi-coupled loop is not stationary: spectral radius "
                          f"{rho:.6g} >= 1"}
    W = block_diag(model.Qd, model.Rd)
    Sigma = solve_discrete_lyapunov(Phi, Gam @ W @ Gam.T)
    ns = model.ns
    See = model.E @ Sigma[:ns, :ns] @ model.E.T
    Suu = Gx @ Sigma @ Gx.T + Geta @ W @ Geta.T
    return {"rms_e": np.sqrt(np.clip(np.diag(See), 0, None)).tolist(),
            "rms_u": np.sqrt(np.clip(np.diag(Suu), 0, None)).tolist(),
            "cost_rate": float(np.trace(system.Q @ See) + np.trace(system.R @ Suu)),
            "spectral_radius": rho, "reason": None}
