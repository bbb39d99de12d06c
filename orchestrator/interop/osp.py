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

Everything is written from the scenario's :class:`SystemDescription` (simulators =
its components, connections = its connections, one per scalar, initial values = its
parameter values). Before anything is built or written the wiring is checked
(:func:`orchestrator.interop.common.check_system`): a variable an FMU lacks, a connection
of two outputs or of two inputs, a type mismatch, an input fed twice or left unconnected
is refused with ``export refused: ...`` naming every problem. What is written is
validated against OSP's XML schemas shipped in ``orchestrator/interop/osp_schemas/`` (see
the README there for where they come from). :mod:`.libcosim` runs the result.
"""
from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from lxml import etree

from fmu_common.interface import ArraySpec

from ..atomic import write_bytes_atomically
from ..cosim.checks import Variable
from ..cosim.system import SystemDescription
from ..scenario import Scenario
from .common import ExportError, append_units, check_system, unit_definitions, value_text
from .export_set import ExportSet, SignalElement, export_set, signal_layout

__all__ = ["SCHEMA_DIR", "OSP_SYSTEM_NS", "OSP_MD_NS", "export_osp", "validate_osp_file",
           "typed_groups_used", "write_osp", "TYPED_GROUP_OF_UNIT"]

SCHEMA_DIR = Path(__file__).resolve().parent / "osp_schemas"
OSP_SYSTEM_NS = "http://opensimulationplatform.com/MSMI/OSPSystemStructure"
OSP_MD_NS = "https://open-simulation-platform.com/OspModelDescription/1.0.1"
_SCHEMA_FILES = {"OspSystemStructure": "OspSystemStructure.xsd",
                 "OspModelDescription": "OspModelDescription-1.0.1.xsd"}

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


# ----------------------------------------------------------------------------- groups

def _typed_groups(sig: str, names: list[str], elems: list[SignalElement]
                  ) -> list[tuple[str, str, list]]:
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


def _osp_model_description(specs: tuple[ArraySpec, ...],
                           layout: dict[str, list[SignalElement]]) -> tuple[bytes, list[str]]:
    """An OspModelDescription for one FMU's interface; returns the bytes and the typed
    group types used."""
    units_used: list[str] = []
    typed_used: list[str] = []

    def use(unit: str | None) -> str | None:
        if unit and unit not in units_used:
            units_used.append(unit)
        return unit or None

    groups = []
    for spec in specs:
        names = spec.elements
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
    q = f"{{{OSP_MD_NS}}}"
    append_units(root, q + "UnitDefinitions", q + "Unit", q + "BaseUnit",
                 unit_definitions(units_used))
    vg = etree.SubElement(root, q + "VariableGroups")
    for g in groups:                     # all top-level groups are Generic
        vg.append(g)
    etree.indent(root, space="  ")
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8",
                          pretty_print=True), typed_used


# ------------------------------------------------------------------- system structure

def _system_structure(system: SystemDescription, fmu_files: Mapping[str, str],
                      variables: Mapping[str, Mapping[str, Variable]]) -> bytes:
    ns = OSP_SYSTEM_NS

    def el(parent: etree._Element, tag: str, **attrs: str) -> etree._Element:
        return etree.SubElement(parent, f"{{{ns}}}{tag}", attrs)

    root = etree.Element(f"{{{ns}}}OspSystemStructure", version="0.1", nsmap={None: ns})
    el(root, "StartTime").text = "0.0"
    el(root, "EndTime").text = value_text("Real", system.T)
    el(root, "BaseStepSize").text = value_text("Real", system.h)
    el(root, "Algorithm").text = "fixedStep"
    sims = el(root, "Simulators")
    for comp in system.components:
        sim = el(sims, "Simulator", name=comp.name, source=fmu_files[comp.name])
        ivs = el(sim, "InitialValues")
        for name, value in comp.parameters.items():
            typ = variables[comp.name][name].type
            iv = el(ivs, "InitialValue", variable=name)
            el(iv, typ if typ in ("Real", "Integer", "Boolean") else "String",
               value=value_text(typ, value))
    conns = el(root, "Connections")
    for c in system.scalar_connections():
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
    """Problems of an OspSystemStructure.xml or *_OspModelDescription.xml against OSP's schema.

    Parameters
    ----------
    path : Path or str
        The XML file.

    Returns
    -------
    list[str]
        One message per schema error (``file:line: message``); empty when valid.
    """
    doc = etree.parse(str(path))
    local = etree.QName(doc.getroot()).localname
    if local not in _SCHEMA_FILES:
        return [f"{path}: root element {local!r} is neither OspSystemStructure nor "
                "OspModelDescription"]
    schema = _schema(local)
    if schema.validate(doc):
        return []
    return [f"{Path(path).name}:{e.line}: {e.message}" for e in schema.error_log]


def export_osp(sc: Scenario, out_dir: Path | str,
               system: SystemDescription | None = None,
               fmus: Mapping[str, Path] | None = None) -> dict[str, Path]:
    """Build the scenario's FMUs into ``out_dir`` and write the OSP system beside them:
    :func:`write_osp` of :func:`orchestrator.interop.export_set.export_set`.

    Parameters
    ----------
    sc : Scenario
        The scenario.
    out_dir : Path or str
        Destination folder.
    system : SystemDescription or None, optional
        The description to export (default: the scenario's loop,
        :func:`orchestrator.running.scenario_system`; use ``sc.with_run(...)`` for other
        run settings).
    fmus : Mapping[str, Path] or None, optional
        FMUs already built in ``out_dir`` (FMU key -> path; the native export's); built
        here if None.

    Returns
    -------
    dict[str, Path]
        As :func:`write_osp`.

    Raises
    ------
    ExportError
        If the wiring does not match the FMUs (before anything is built) or a written
        file does not validate against OSP's schemas.
    """
    return write_osp(export_set(sc, out_dir, system=system, fmus=fmus), out_dir)


def write_osp(export: ExportSet, out_dir: Path | str) -> dict[str, Path]:
    """Write the OSP system of ``export`` beside its FMUs (which are in ``out_dir``).

    Parameters
    ----------
    export : ExportSet
        The system, its FMUs, those beside it, the signals' units.
    out_dir : Path or str
        The folder of the FMUs.

    Returns
    -------
    dict[str, Path]
        ``{"system": OspSystemStructure.xml, <FMU key>: the .fmu,
        "<FMU key>_osp": its <model>_OspModelDescription.xml}``; for REMUS 100 vehicles
        also ``guidance`` and ``autopilot`` (AuvGuidance, AuvAutopilot): FMUs beside the
        system, not simulators in it, for a host to wire to its own vehicle
        (docs/guidance.md).

    Raises
    ------
    ExportError
        If the wiring does not match the FMUs or a written file does not validate
        against OSP's schemas.
    """
    out = Path(out_dir)
    system, fmus, layout = export.system, export.fmus, export.elements
    fmu_files = {c.name: Path(fmus[c.fmu]).name for c in system.components}
    variables = check_system(system, fmus)          # the FMUs as built
    paths: dict[str, Path] = {}
    written: list[Path] = []
    interfaces: dict[str, tuple] = {}
    for c in system.components:                     # an FMU's first component's interface
        interfaces.setdefault(c.fmu, (c.interface, layout))
    interfaces.update({k: (specs, {}) for k, specs in export.beside.items()})
    for key, (specs, elements) in interfaces.items():
        xml, _ = _osp_model_description(specs, elements)
        p = out / f"{Path(fmus[key]).stem}_OspModelDescription.xml"
        write_bytes_atomically(p, xml)
        paths[key] = Path(fmus[key])
        paths[f"{key}_osp"] = p
        written.append(p)
    system_file = out / "OspSystemStructure.xml"
    write_bytes_atomically(system_file, _system_structure(system, fmu_files, variables))
    paths["system"] = system_file
    written.append(system_file)
    problems = [msg for p in written for msg in validate_osp_file(p)]
    if problems:
        raise ExportError(["the exported OSP files do not validate against OSP's schemas",
                           *problems])
    return paths


def typed_groups_used(sc: Scenario) -> dict[str, list[str]]:
    """The OSP-IS typed variable groups the export declares for each FMU of ``sc``.

    Parameters
    ----------
    sc : Scenario
        The scenario.

    Returns
    -------
    dict[str, list[str]]
        FMU key -> the typed group types used (e.g. ``LinearDisplacement``).
    """
    from ..running.systems import scenario_system
    system = scenario_system(sc)
    layout = signal_layout(sc, system)
    return {c.fmu: _osp_model_description(c.interface, layout)[1] for c in system.components}
