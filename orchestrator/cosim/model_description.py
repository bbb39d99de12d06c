"""The modelDescription.xml of a built FMU completed: units, InitialUnknowns, output
dependencies and a DefaultExperiment (pythonfmu writes none of them)."""
from __future__ import annotations

from typing import Any

import numpy as np
from lxml import etree

from fmu_common.interface import UNIT_DEFINITIONS, ArraySpec, expand

__all__ = ["format_value", "patch_model_description"]


def format_value(v: Any) -> str:
    """A start value as the modelDescription writes it: floats by repr (round-trip exact)."""
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    return str(v)


def patch_model_description(xml: bytes, specs: list[ArraySpec], *, T: float, h: float) -> bytes:
    """Add units, InitialUnknowns, output dependencies and a DefaultExperiment.

    Parameters
    ----------
    xml : bytes
        The modelDescription.xml pythonfmu wrote.
    specs : list[ArraySpec]
        The slave's interface table (:func:`interface_of`).
    T : float
        Stop time of the default experiment, s.
    h : float
        Step size of the default experiment, s.

    Returns
    -------
    bytes
        The completed modelDescription.xml (UTF-8, pretty-printed).

    Raises
    ------
    ValueError
        If a unit has no entry in UNIT_DEFINITIONS.
    """
    root = etree.fromstring(xml)
    by_name = {name: spec for spec, _, name in expand(specs)}
    variables = root.find("ModelVariables")
    index: dict[str, int] = {}
    units_used: list[str] = []
    for i, sv in enumerate(variables.findall("ScalarVariable"), start=1):
        name = sv.get("name")
        spec = by_name[name]
        index[name] = i
        typ = sv[0]
        if spec.unit:
            typ.set("unit", spec.unit)
            if spec.unit not in units_used:
                units_used.append(spec.unit)
        for bound in ("min", "max"):
            if getattr(spec, bound) is not None:
                typ.set(bound, str(getattr(spec, bound)))
        if spec.causality == "output":
            sv.set("initial", "calculated")
            typ.attrib.pop("start", None)
        elif typ.get("start") is not None and spec.type == "Real":
            typ.set("start", format_value(float(typ.get("start"))))
    for old in root.findall("UnitDefinitions"):
        root.remove(old)
    if units_used:
        unknown = [u for u in units_used if u not in UNIT_DEFINITIONS]
        if unknown:
            raise ValueError(f"no SI definition for unit(s) {unknown}; add them to "
                             "UNIT_DEFINITIONS")
        ud = etree.Element("UnitDefinitions")
        for u in units_used:
            unit = etree.SubElement(ud, "Unit", name=u)
            etree.SubElement(unit, "BaseUnit", {k: str(v) for k, v in UNIT_DEFINITIONS[u].items()})
        root.insert(list(root).index(root.find("CoSimulation")) + 1, ud)
    for old in root.findall("DefaultExperiment"):
        root.remove(old)
    de = etree.Element("DefaultExperiment", startTime="0.0", stopTime=format_value(float(T)),
                       stepSize=format_value(float(h)))
    root.insert(list(root).index(variables), de)
    ms = root.find("ModelStructure")
    for child in list(ms):
        ms.remove(child)
    outputs = etree.SubElement(ms, "Outputs")
    initial = etree.SubElement(ms, "InitialUnknowns")
    spec_names: dict[str, list[str]] = {}
    for spec, _, name in expand(specs):
        spec_names.setdefault(spec.name, []).append(name)
    for spec, _, name in expand(specs):
        if spec.causality != "output":
            continue
        deps = [index[n] for d in spec.depends_on for n in spec_names[d]]
        attrs = {"index": str(index[name]), "dependencies": " ".join(map(str, deps))}
        if deps:
            attrs["dependenciesKind"] = " ".join(["dependent"] * len(deps))
        etree.SubElement(outputs, "Unknown", attrs)
        # initial values depend on every parameter and input: no dependency list
        etree.SubElement(initial, "Unknown", index=str(index[name]))
    if not len(outputs):
        ms.remove(outputs)
    if not len(initial):
        ms.remove(initial)
    etree.indent(root, space="  ")
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)
