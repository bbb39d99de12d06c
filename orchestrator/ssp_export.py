"""Export a scenario's three FMUs as an SSP 1.0 archive (System Structure and Parameterization).

Layout of the ``.ssp`` (a ZIP archive, SSP 1.0 section 3)::

    SystemStructure.ssd          the system: three components, their connectors, the
                                 connections, a parameter binding per component, the
                                 default experiment (start 0, stop T) and an annotation
                                 with the step size h and the coupling our master uses
    resources/AuvPlant.fmu       the FMUs, built for the scenario (its values are also
    resources/AuvEstimator.fmu   their start values)
    resources/AuvController.fmu
    resources/plant.ssv          one parameter set per component: every parameter of
    resources/estimator.ssv      the FMU with the scenario's value, under the FMU's own
    resources/controller.ssv     variable name (``A[1,2]``, ``h``, ``seed``, ``tracking``)

Each component binds its set (``<ParameterBinding source="resources/plant.ssv">``): by
SSP 1.0 the names in a component's parameter source are the FMU's variable names, so no
ParameterMapping is needed. (A single set with hierarchical names ``plant.A[1,2]`` bound
at the system level would be equivalent; per-component sets are the plainest case for
importing tools.)

Connections (scalar, FMI structured names): plant -> estimator ``y, ybar`` and the truth
``x, w, z`` (read by the estimator only in mode 'ideal'), estimator -> controller
``xhat, what, zhat``, controller -> plant and estimator ``u``. The plant's tracking
error ``e`` is declared as an unconnected output connector so that a tool records it.
:func:`check_connections` refuses, naming the variable, a connector an FMU lacks, a
connection that does not go from an output to an input, two outputs driving one input,
mismatched types and an FMU input left unconnected.

What SSP cannot say: the order of evaluation within a step. Our master
(:mod:`orchestrator.master`) runs the exact discrete-time loop (Gauss-Seidel in the order
plant, estimator, controller, with the direct feedthrough declared in the FMUs'
ModelStructure); a tool that steps every FMU on the previous step's values (Jacobi) runs a
different, delayed loop. See :func:`fmpy_parameter_set` for what fmpy's
``simulate_ssp`` does with this archive.
"""
from __future__ import annotations

import tempfile
import zipfile
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from lxml import etree

from fmu_common.interface import element_names

from .fmu_build import FMU_KINDS
from .master import LOOP_CONNECTIONS, fmu_parameters, signal_size
from .scenario import Scenario
from .workflow import build, scenario_config

__all__ = ["COMPONENTS", "OBSERVED_OUTPUTS", "SIGNAL_CONNECTIONS", "SSC_NS", "SSD_NS", "SSV_NS",
           "Connection", "SspExportError", "Variable", "check_connections", "export_ssp",
           "fmpy_parameter_set", "fmu_variables", "parameter_set_path", "scalar_connections"]

SSD_NS = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC_NS = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV_NS = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
_NSMAP_SSD = {"ssd": SSD_NS, "ssc": SSC_NS}
_NSMAP_SSV = {"ssv": SSV_NS, "ssc": SSC_NS}

#: component order in the SSD (also our master's evaluation order)
COMPONENTS = ("plant", "estimator", "controller")
#: (source component, signal, destination component): vector signals, same name both ends
SIGNAL_CONNECTIONS: tuple[tuple[str, str, str], ...] = LOOP_CONNECTIONS
#: unconnected outputs declared as connectors so that an SSP tool records them
OBSERVED_OUTPUTS: tuple[tuple[str, str], ...] = (("plant", "e"),)


def parameter_set_path(component: str) -> str:
    """Where a component's parameter set lives in the archive."""
    return f"resources/{component}.ssv"

_ANNOTATION_TYPE = "org.auv-cosim.master"


class SspExportError(ValueError):
    """The system cannot be exported; the message names the component and variable."""


@dataclass(frozen=True)
class Connection:
    """One scalar connection ``start_element.start_connector -> end_element.end_connector``."""

    start_element: str
    start_connector: str
    end_element: str
    end_connector: str

    def __str__(self) -> str:
        return (f"{self.start_element}.{self.start_connector} -> "
                f"{self.end_element}.{self.end_connector}")


@dataclass(frozen=True)
class Variable:
    """What an FMU's modelDescription says about one variable."""

    causality: str
    type: str
    unit: str | None = None
    start: str | None = None


def scalar_connections(dims: Mapping[str, int]) -> list[Connection]:
    """The scalar connections of the loop for the dimensions ``dims`` (n, m, r, p, l)."""
    out = []
    for src, signal, dst in SIGNAL_CONNECTIONS:
        for name in element_names(signal, (signal_size(signal, dims),)):
            out.append(Connection(src, name, dst, name))
    return out


def fmu_variables(fmu: Path | str) -> dict[str, Variable]:
    """Variable name -> :class:`Variable` from an FMU's modelDescription.xml."""
    from fmpy import read_model_description
    md = read_model_description(str(fmu), validate=False)
    return {v.name: Variable(v.causality, v.type, v.unit, v.start) for v in md.modelVariables}


def check_connections(variables: Mapping[str, Mapping[str, Variable]],
                      connections: Iterable[Connection], *,
                      fmu_names: Mapping[str, str] | None = None) -> None:
    """Refuse a connection set that a co-simulation cannot run, naming every problem.

    ``variables``: component name -> its FMU's variables (:func:`fmu_variables`).
    Problems: a component or variable that does not exist; a connection whose start is
    not an output or whose end is not an input (two outputs connected, an input driving
    something); an input driven by more than one connection; different types at the two
    ends; an input of an FMU that no connection drives.
    """
    connections = list(connections)
    label = dict(fmu_names or {})
    problems: list[str] = []

    def where(comp: str) -> str:
        return f"{comp} ({label[comp]})" if comp in label else comp

    drivers: dict[tuple[str, str], list[Connection]] = {}
    for c in connections:
        ends = (("start", c.start_element, c.start_connector, "output"),
                ("end", c.end_element, c.end_connector, "input"))
        ok = True
        for side, comp, name, want in ends:
            if comp not in variables:
                problems.append(f"connection {c}: no component named {comp!r} "
                                f"(components: {', '.join(variables)})")
                ok = False
                continue
            var = variables[comp].get(name)
            if var is None:
                problems.append(f"connection {c}: {where(comp)} has no variable {name!r}")
                ok = False
            elif var.causality != want:
                if side == "end" and var.causality == "output":
                    what = "two outputs connected"
                else:
                    what = f"the {side} must be an {want}"
                problems.append(f"connection {c}: {comp}.{name} is an {var.causality}, "
                                f"{what}")
                ok = False
        if not ok:
            continue
        t0 = variables[c.start_element][c.start_connector].type
        t1 = variables[c.end_element][c.end_connector].type
        if t0 != t1:
            problems.append(f"connection {c}: types differ ({t0} -> {t1})")
        drivers.setdefault((c.end_element, c.end_connector), []).append(c)
    for (comp, name), cs in drivers.items():
        if len(cs) > 1:
            problems.append(f"input {comp}.{name} is driven by {len(cs)} outputs "
                            f"({', '.join(f'{c.start_element}.{c.start_connector}' for c in cs)})")
    for comp, vs in variables.items():
        missing = [n for n, v in vs.items() if v.causality == "input" and (comp, n) not in drivers]
        if missing:
            problems.append(f"{where(comp)}: input(s) not connected: {', '.join(missing)}")
    if problems:
        raise SspExportError("the SSP connections are inconsistent: " + "; ".join(problems))


def _q(ns: str, tag: str) -> str:
    return f"{{{ns}}}{tag}"


def _value_text(typ: str, value: Any) -> str:
    if typ == "Real":
        return repr(float(value))
    if typ == "Integer":
        return str(int(value))
    if typ == "Boolean":
        return "true" if bool(value) else "false"
    return str(value)


def _units_element(ns_parent: str, units: dict[str, dict[str, int]]) -> etree._Element:
    el = etree.Element(_q(ns_parent, "Units"))
    for name, base in units.items():
        u = etree.SubElement(el, _q(SSC_NS, "Unit"), name=name)
        etree.SubElement(u, _q(SSC_NS, "BaseUnit"), {k: str(v) for k, v in base.items() if v})
    return el


def _unit_definitions(fmu: Path) -> dict[str, dict[str, int]]:
    from fmpy import read_model_description
    md = read_model_description(str(fmu), validate=False)
    out = {}
    for u in md.unitDefinitions:
        b = u.baseUnit
        out[u.name] = {k: getattr(b, k) for k in ("kg", "m", "s", "A", "K", "mol", "cd", "rad")}
    return out


def _parameter_set_xml(name: str, params: list[tuple[str, str, str, str | None]],
                       units: dict[str, dict[str, int]]) -> bytes:
    """An SSV ParameterSet; ``params``: (name, type, value text, unit or None)."""
    root = etree.Element(_q(SSV_NS, "ParameterSet"), nsmap=_NSMAP_SSV, version="1.0", name=name)
    ps = etree.SubElement(root, _q(SSV_NS, "Parameters"))
    used: dict[str, dict[str, int]] = {}
    for pname, typ, text, unit in params:
        p = etree.SubElement(ps, _q(SSV_NS, "Parameter"), name=pname)
        attrs = {"value": text}
        if typ == "Real" and unit:
            attrs["unit"] = unit
            used[unit] = units[unit]
        etree.SubElement(p, _q(SSV_NS, typ), attrs)
    if used:
        root.append(_units_element(SSV_NS, used))
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


def _system_structure_xml(sc: Scenario, fmu_files: Mapping[str, str],
                          variables: Mapping[str, Mapping[str, Variable]],
                          connections: list[Connection],
                          units: dict[str, dict[str, int]]) -> bytes:
    root = etree.Element(_q(SSD_NS, "SystemStructureDescription"), nsmap=_NSMAP_SSD,
                         version="1.0", name=sc.name, generationTool="auv-cosim",
                         description=f"scenario {sc.name}: plant, estimator and controller FMUs "
                                     f"of the AUV consensus tracking loop, h = {sc.h} s")
    system = etree.SubElement(root, _q(SSD_NS, "System"), name="auv_loop")
    elements = etree.SubElement(system, _q(SSD_NS, "Elements"))
    # connectors of each component: every connected variable, in the FMU's order
    used_names: dict[str, set[str]] = {c: set() for c in COMPONENTS}
    for c in connections:
        used_names[c.start_element].add(c.start_connector)
        used_names[c.end_element].add(c.end_connector)
    for comp, sig in OBSERVED_OUTPUTS:
        used_names[comp].update(n for n, v in variables[comp].items()
                                if n == sig or n.startswith(sig + "["))
    used_units: dict[str, dict[str, int]] = {}
    for comp in COMPONENTS:
        el = etree.SubElement(elements, _q(SSD_NS, "Component"), name=comp,
                              type="application/x-fmu-sharedlibrary",
                              source=fmu_files[comp], implementation="CoSimulation")
        conns = etree.SubElement(el, _q(SSD_NS, "Connectors"))
        for name, var in variables[comp].items():
            if name not in used_names[comp]:
                continue
            cn = etree.SubElement(conns, _q(SSD_NS, "Connector"), name=name, kind=var.causality)
            attrs = {}
            if var.type == "Real" and var.unit:
                attrs["unit"] = var.unit
                used_units[var.unit] = units[var.unit]
            etree.SubElement(cn, _q(SSC_NS, var.type), attrs)
        pbs = etree.SubElement(el, _q(SSD_NS, "ParameterBindings"))
        etree.SubElement(pbs, _q(SSD_NS, "ParameterBinding"),
                         type="application/x-ssp-parameter-set",
                         source=parameter_set_path(comp))
    cons = etree.SubElement(system, _q(SSD_NS, "Connections"))
    for c in connections:
        etree.SubElement(cons, _q(SSD_NS, "Connection"), startElement=c.start_element,
                         startConnector=c.start_connector, endElement=c.end_element,
                         endConnector=c.end_connector)
    if used_units:
        root.append(_units_element(SSD_NS, used_units))
    de = etree.SubElement(root, _q(SSD_NS, "DefaultExperiment"), startTime="0.0",
                          stopTime=repr(float(sc.T)))
    anns = etree.SubElement(de, _q(SSD_NS, "Annotations"))
    ann = etree.SubElement(anns, _q(SSC_NS, "Annotation"), type=_ANNOTATION_TYPE)
    master = etree.SubElement(ann, "FixedStepMaster", stepSize=repr(float(sc.h)),
                              steps=str(sc.steps), order=" ".join(COMPONENTS),
                              coupling="gauss-seidel")
    master.text = ("Within a step evaluate plant, estimator, controller in this order, each "
                   "input set from the outputs of the same step (the estimator's and the "
                   "controller's outputs feed through directly), then step all three.")
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


def export_ssp(sc: Scenario, out_path: Path | str, *,
               fmus: Mapping[str, Path] | None = None) -> Path:
    """Build the scenario's FMUs (or take ``fmus`` already built for it) and write them
    with the system structure to ``out_path``.

    Raises :class:`SspExportError` (naming the variable) if the connections do not match
    the FMUs' variables, and before anything is written.
    """
    out_path = Path(out_path)
    cfg = scenario_config(sc)
    with tempfile.TemporaryDirectory(prefix="auv_ssp_") as tmp:
        fmus = dict(fmus) if fmus is not None else build(sc, Path(tmp) / "fmus")
        variables = {comp: fmu_variables(fmus[comp]) for comp in COMPONENTS}
        fmu_files = {comp: f"resources/{FMU_KINDS[comp].model}.fmu" for comp in COMPONENTS}
        connections = scalar_connections(cfg["dims"])
        check_connections(variables, connections,
                          fmu_names={c: Path(f).name for c, f in fmu_files.items()})
        units: dict[str, dict[str, int]] = {}
        for comp in COMPONENTS:
            units.update(_unit_definitions(fmus[comp]))
        ssv: dict[str, bytes] = {}
        for comp in COMPONENTS:
            params: list[tuple[str, str, str, str | None]] = []
            for name, value in fmu_parameters(comp, cfg).items():
                var = variables[comp].get(name)
                if var is None or var.causality != "parameter":
                    raise SspExportError(f"parameter {comp}.{name}: {FMU_KINDS[comp].model}.fmu "
                                         "has no such parameter")
                params.append((name, var.type, _value_text(var.type, value), var.unit))
            ssv[comp] = _parameter_set_xml(f"{sc.name}.{comp}", params, units)
        ssd = _system_structure_xml(sc, fmu_files, variables, connections, units)
        out_path.parent.mkdir(parents=True, exist_ok=True)
        tmp_out = out_path.with_name(out_path.name + ".part")
        with zipfile.ZipFile(tmp_out, "w", zipfile.ZIP_DEFLATED) as z:
            z.writestr("SystemStructure.ssd", ssd)
            for comp in COMPONENTS:
                z.write(fmus[comp], fmu_files[comp])
            for comp in COMPONENTS:
                z.writestr(parameter_set_path(comp), ssv[comp])
        tmp_out.replace(out_path)
    return out_path


def fmpy_parameter_set(ssp: Path | str, *, strings: str = "check"):
    """The archive's component parameter bindings as the ``parameter_set`` of fmpy's
    ``simulate_ssp``.

    fmpy 0.3.x reads ParameterBindings (``read_ssd`` parses the ``.ssv`` and validates it
    against the schema) but ``simulate_ssp`` never applies them: it applies only a
    ``parameter_set`` passed by the caller, with names ``<component>.<variable>``, after
    fmi2SetupExperiment and before fmi2EnterInitializationMode, and it can set Real,
    Integer, Enumeration and Boolean values but not String ones ("Unsupported type").
    This function collects the bindings of every component of the top-level system into
    such a set (names prefixed with the component's name; ParameterMappings are not
    supported and refused). String parameters are left out; with ``strings='check'``
    (default) each left-out String must equal the FMU's start value, so leaving it out
    changes nothing (otherwise :class:`SspExportError`); ``strings='drop'`` drops them.
    """
    from fmpy.ssp.ssd import Component, Parameter, ParameterSet, read_ssd

    ssp = str(ssp)
    ssd = read_ssd(ssp)
    out = ParameterSet(name="bindings")
    for comp in ssd.system.elements:
        if not isinstance(comp, Component):
            continue
        starts: dict[str, Variable] | None = None
        for binding in comp.parameterBindings:
            if binding.parameterMapping:
                raise SspExportError(f"component {comp.name}: parameter mappings are not supported")
            if binding.prefix:
                raise SspExportError(f"component {comp.name}: binding prefixes are not supported")
            for pset in binding.parameterValues:
                for p in pset.parameters:
                    if p.type == "String":
                        if strings == "check":
                            if starts is None:
                                with tempfile.TemporaryDirectory() as tmp:
                                    with zipfile.ZipFile(ssp) as z:
                                        z.extract(comp.source, tmp)
                                    starts = fmu_variables(Path(tmp) / comp.source)
                            start = starts[p.name].start if p.name in starts else None
                            if start != p.value:
                                raise SspExportError(
                                    f"parameter {comp.name}.{p.name} = {p.value!r} is a String, "
                                    "which fmpy's simulate_ssp cannot set, and differs from "
                                    f"the FMU's start value {start!r}")
                        continue
                    out.parameters.append(Parameter(name=f"{comp.name}.{p.name}", type=p.type,
                                                    value=p.value, unit=p.unit))
    return out
