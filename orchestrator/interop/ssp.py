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
    resources/AuvGuidance.fmu    REMUS 100 vehicles only: the guidance interface, beside
    resources/AuvAutopilot.fmu   the system (no component), for a host's own vehicle
                                 (docs/guidance.md)

Each component binds its set (``<ParameterBinding source="resources/plant.ssv">``): by
SSP 1.0 the names in a component's parameter source are the FMU's variable names, so no
ParameterMapping is needed. (A single set with hierarchical names ``plant.A[1,2]`` bound
at the system level would be equivalent; per-component sets are the plainest case for
importing tools.)

Components, connections (scalar, FMI structured names) and parameter values are the
scenario's :class:`SystemDescription` (:mod:`orchestrator.cosim.system`): plant ->
estimator ``y, ybar`` and the truth ``x, w, z`` (read by the estimator only in mode
'ideal'), estimator -> controller ``xhat, what, zhat``, controller -> plant and estimator
``u``. Every output is declared as a connector (the plant's tracking error ``e`` is
connected to nothing, so that a tool records it). The wiring is checked first
(:func:`orchestrator.interop.common.check_system`): a connector an FMU lacks, a connection
that does not go from an output to an input, two outputs driving one input, mismatched
types and an FMU input left unconnected are refused, every problem named.

What SSP cannot say: the order of evaluation within a step. Our master
(:mod:`orchestrator.cosim.master`) runs the exact discrete-time loop (Gauss-Seidel in the
order the FMUs' declared direct feedthrough requires, written into the annotation); a
tool that steps every FMU on the previous step's values (Jacobi) runs a different,
delayed loop. See :func:`fmpy_parameter_set` for what fmpy's
``simulate_ssp`` does with this archive.
"""
from __future__ import annotations

import tempfile
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from lxml import etree

from ..atomic import temporary_sibling
from ..cosim.build import FMU_KINDS
from ..cosim.checks import Variable, fmu_variables
from ..cosim.system import SystemDescription, evaluation_order
from ..scenario import Scenario
from .common import ExportError, append_units, check_system, unit_definitions, value_text
from .export_set import ExportSet, export_set

if TYPE_CHECKING:
    from fmpy.ssp.ssd import ParameterSet

__all__ = ["SSC_NS", "SSD_NS", "SSV_NS", "export_ssp", "write_ssp", "fmpy_parameter_set",
           "parameter_set_path"]

SSD_NS = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC_NS = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV_NS = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
_NSMAP_SSD = {"ssd": SSD_NS, "ssc": SSC_NS}
_NSMAP_SSV = {"ssv": SSV_NS, "ssc": SSC_NS}
_ANNOTATION_TYPE = "org.auv-cosim.master"


def parameter_set_path(component: str) -> str:
    """Where a component's parameter set lives in the archive.

    Parameters
    ----------
    component : str
        The component's name.

    Returns
    -------
    str
        ``resources/<component>.ssv``.
    """
    return f"resources/{component}.ssv"


def _q(ns: str, tag: str) -> str:
    return f"{{{ns}}}{tag}"


def _units(parent: etree._Element, ns: str, units: dict[str, dict[str, int]]) -> None:
    append_units(parent, _q(ns, "Units"), _q(SSC_NS, "Unit"), _q(SSC_NS, "BaseUnit"), units)


def _parameter_set_xml(name: str, params: list[tuple[str, Variable, object]]) -> bytes:
    """An SSV ParameterSet; ``params``: (name, the FMU's variable, value)."""
    root = etree.Element(_q(SSV_NS, "ParameterSet"), nsmap=_NSMAP_SSV, version="1.0", name=name)
    ps = etree.SubElement(root, _q(SSV_NS, "Parameters"))
    used: list[str] = []
    for pname, var, value in params:
        p = etree.SubElement(ps, _q(SSV_NS, "Parameter"), name=pname)
        attrs = {"value": value_text(var.type, value)}
        if var.type == "Real" and var.unit:
            attrs["unit"] = var.unit
            used += [var.unit] if var.unit not in used else []
        etree.SubElement(p, _q(SSV_NS, var.type), attrs)
    _units(root, SSV_NS, unit_definitions(used))
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


def _system_structure_xml(system: SystemDescription, fmu_files: Mapping[str, str],
                          variables: Mapping[str, Mapping[str, Variable]]) -> bytes:
    root = etree.Element(_q(SSD_NS, "SystemStructureDescription"), nsmap=_NSMAP_SSD,
                         version="1.0", name=system.name, generationTool="auv-cosim",
                         description=f"scenario {system.name}: "
                                     f"{', '.join(system.names)} FMUs of the AUV consensus "
                                     f"tracking loop, h = {system.h} s")
    sys_el = etree.SubElement(root, _q(SSD_NS, "System"), name="auv_loop")
    elements = etree.SubElement(sys_el, _q(SSD_NS, "Elements"))
    connections = system.scalar_connections()
    # connectors of each component: every output and every connected input, FMU order
    used_names: dict[str, set[str]] = {c: set() for c in system.names}
    for c in connections:
        used_names[c.target[0]].add(c.target[1])
    used_units: list[str] = []
    for comp in system.names:
        el = etree.SubElement(elements, _q(SSD_NS, "Component"), name=comp,
                              type="application/x-fmu-sharedlibrary",
                              source=fmu_files[comp], implementation="CoSimulation")
        conns = etree.SubElement(el, _q(SSD_NS, "Connectors"))
        for name, var in variables[comp].items():
            if var.causality != "output" and name not in used_names[comp]:
                continue
            cn = etree.SubElement(conns, _q(SSD_NS, "Connector"), name=name, kind=var.causality)
            attrs = {}
            if var.type == "Real" and var.unit:
                attrs["unit"] = var.unit
                used_units += [var.unit] if var.unit not in used_units else []
            etree.SubElement(cn, _q(SSC_NS, var.type), attrs)
        pbs = etree.SubElement(el, _q(SSD_NS, "ParameterBindings"))
        etree.SubElement(pbs, _q(SSD_NS, "ParameterBinding"),
                         type="application/x-ssp-parameter-set",
                         source=parameter_set_path(comp))
    cons = etree.SubElement(sys_el, _q(SSD_NS, "Connections"))
    for c in connections:
        etree.SubElement(cons, _q(SSD_NS, "Connection"), startElement=c.source[0],
                         startConnector=c.source[1], endElement=c.target[0],
                         endConnector=c.target[1])
    _units(root, SSD_NS, unit_definitions(used_units))
    steps = int(round(system.T / system.h))
    de = etree.SubElement(root, _q(SSD_NS, "DefaultExperiment"), startTime="0.0",
                          stopTime=value_text("Real", system.T))
    anns = etree.SubElement(de, _q(SSD_NS, "Annotations"))
    ann = etree.SubElement(anns, _q(SSC_NS, "Annotation"), type=_ANNOTATION_TYPE)
    order = list(dict.fromkeys(c for c, _ in evaluation_order(system)))
    master = etree.SubElement(ann, "FixedStepMaster", stepSize=value_text("Real", system.h),
                              steps=str(steps), order=" ".join(order),
                              coupling="gauss-seidel")
    master.text = (f"Within a step read the outputs of {', '.join(order)} in this order, "
                   "setting each input from the outputs of the same step (outputs with "
                   "direct feedthrough are read after the inputs they depend on), then "
                   "step all FMUs.")
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


def export_ssp(sc: Scenario, out_path: Path | str, *,
               fmus: Mapping[str, Path] | None = None,
               system: SystemDescription | None = None) -> Path:
    """Write the scenario's FMUs and system structure as an SSP archive at ``out_path``:
    :func:`write_ssp` of :func:`orchestrator.interop.export_set.export_set` (the FMUs built
    into a temporary folder unless given).

    Parameters
    ----------
    sc : Scenario
        The scenario.
    out_path : Path or str
        The ``.ssp`` file to write.
    fmus : Mapping[str, Path] or None, optional
        FMUs already built for the scenario (FMU key -> path); built here if None.
    system : SystemDescription or None, optional
        The system structure (default: the scenario's,
        :func:`orchestrator.running.scenario_system`).

    Returns
    -------
    Path
        ``out_path``, as :func:`write_ssp` writes it.

    Raises
    ------
    ExportError
        As :func:`write_ssp`, but before any FMU is built.
    """
    from ..running.systems import scenario_system
    system = system or scenario_system(sc)
    models = _models(system, fmus)
    check_system(system, fmu_files=_labels(system, models))     # before anything is built
    with tempfile.TemporaryDirectory(prefix="auv_ssp_") as tmp:
        export = export_set(sc, Path(tmp) / "fmus", system=system, fmus=fmus)
        return write_ssp(export, out_path, models=models)


def _models(system: SystemDescription, fmus: Mapping[str, Path] | None) -> dict[str, str]:
    """FMU key -> the model name its archive entry takes (the file's stem, else the kind's)."""
    return ({k: Path(f).stem for k, f in fmus.items()} if fmus is not None else
            {c.fmu: FMU_KINDS[c.fmu].model for c in system.components})


def _labels(system: SystemDescription, models: Mapping[str, str]) -> dict[str, str]:
    """Component -> the .fmu file name it has in the archive (for messages)."""
    return {c.name: f"{models[c.fmu]}.fmu" for c in system.components}


def write_ssp(export: ExportSet, out_path: Path | str, *,
              models: Mapping[str, str] | None = None) -> Path:
    """Write ``export`` as an SSP archive at ``out_path`` (under a temporary name, renamed
    when complete): SystemStructure.ssd, one parameter set per component, the FMUs in
    resources/ (those beside the system too).

    Parameters
    ----------
    export : ExportSet
        The system, its FMUs and those beside it.
    out_path : Path or str
        The ``.ssp`` file to write.
    models : Mapping[str, str] or None, optional
        FMU key -> the model name of its archive entry (default: the .fmu file's stem).

    Returns
    -------
    Path
        ``out_path``.

    Raises
    ------
    ExportError
        Naming every problem, if the connections do not match the FMUs' variables.
    """
    out_path = Path(out_path)
    system, fmus = export.system, export.fmus
    models = dict(models) if models is not None else _models(system, fmus)
    fmu_files = {c.name: f"resources/{models[c.fmu]}.fmu" for c in system.components}
    variables = check_system(system, fmus, fmu_files=_labels(system, models))
    ssv = {c.name: _parameter_set_xml(
               f"{system.name}.{c.name}",
               [(n, variables[c.name][n], v) for n, v in c.parameters.items()])
           for c in system.components}
    ssd = _system_structure_xml(system, fmu_files, variables)
    with temporary_sibling(out_path) as tmp_out, \
            zipfile.ZipFile(tmp_out, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("SystemStructure.ssd", ssd)
        for key in dict.fromkeys(c.fmu for c in system.components):
            z.write(fmus[key], f"resources/{models[key]}.fmu")
        for comp in system.names:
            z.writestr(parameter_set_path(comp), ssv[comp])
        for key in export.beside:       # beside the system: for a host's own vehicle
            z.write(fmus[key], f"resources/{Path(fmus[key]).stem}.fmu")
    return out_path


def fmpy_parameter_set(ssp: Path | str, *, strings: str = "check") -> ParameterSet:
    """The archive's component parameter bindings as the ``parameter_set`` of fmpy's simulate_ssp.

    fmpy 0.3.x reads ParameterBindings (``read_ssd`` parses the ``.ssv`` and validates it
    against the schema) but ``simulate_ssp`` never applies them: it applies only a
    ``parameter_set`` passed by the caller, with names ``<component>.<variable>``, after
    fmi2SetupExperiment and before fmi2EnterInitializationMode, and it can set Real,
    Integer, Enumeration and Boolean values but not String ones ("Unsupported type").
    This function collects the bindings of every component of the top-level system into
    such a set (names prefixed with the component's name; ParameterMappings are not
    supported and refused). String parameters are left out; with ``strings='check'``
    (default) each left-out String must equal the FMU's start value, so leaving it out
    changes nothing (otherwise :class:`ExportError`); ``strings='drop'`` drops them.

    Parameters
    ----------
    ssp : Path or str
        The ``.ssp`` archive.
    strings : str, optional
        'check' or 'drop' (see above).

    Returns
    -------
    fmpy.ssp.ssd.ParameterSet
        Parameters named ``<component>.<variable>``.

    Raises
    ------
    ExportError
        On a parameter mapping or binding prefix, or (``strings='check'``) a String
        parameter that differs from the FMU's start value.
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
                raise ExportError(f"component {comp.name}: parameter mappings are not supported")
            if binding.prefix:
                raise ExportError(f"component {comp.name}: binding prefixes are not supported")
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
                                raise ExportError(
                                    f"parameter {comp.name}.{p.name} = {p.value!r} is a String, "
                                    "which fmpy's simulate_ssp cannot set, and differs from "
                                    f"the FMU's start value {start!r}")
                        continue
                    out.parameters.append(Parameter(name=f"{comp.name}.{p.name}", type=p.type,
                                                    value=p.value, unit=p.unit))
    return out
