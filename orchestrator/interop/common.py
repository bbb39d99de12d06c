"""What every foreign system format shares: the export error, value text, unit elements and
the connection check of a :class:`SystemDescription` against its FMUs.

The system formats (OSP, SSP) and the cross-check files are written from one
:class:`~orchestrator.cosim.system.SystemDescription`; this module holds the pieces they
would otherwise each carry a copy of.
"""
from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from lxml import etree

from fmu_common.interface import UNIT_DEFINITIONS

from ..cosim.checks import Variable, connection_problems, fmu_variables, system_variables
from ..cosim.system import SystemDescription

__all__ = ["ExportError", "value_text", "unit_definitions", "append_units",
           "check_system", "built_variables"]


class ExportError(ValueError):
    """A system cannot be exported; the message starts with ``export refused:`` and names
    every problem found."""

    def __init__(self, problems: list[str] | str) -> None:
        self.problems = [problems] if isinstance(problems, str) else list(problems)
        super().__init__("export refused: " + "; ".join(self.problems))


def value_text(typ: str, value: Any) -> str:
    """A value as the text of an XML attribute of FMI type ``typ``.

    Parameters
    ----------
    typ : str
        FMI type: Real, Integer, Enumeration, Boolean or String.
    value : Any
        The value.

    Returns
    -------
    str
        Real as Python's repr (the shortest text that reads back to the same double),
        Integer and Enumeration as a whole number, Boolean as true / false, else ``str``.
    """
    if typ == "Real":
        return repr(float(value))
    if typ in ("Integer", "Enumeration"):
        return str(int(value))
    if typ == "Boolean":
        return "true" if bool(value) and value != "false" else "false"
    return str(value)


def unit_definitions(units: list[str] | set[str]) -> dict[str, dict[str, int]]:
    """SI base-unit exponents of ``units`` (fmu_common.interface.UNIT_DEFINITIONS).

    Parameters
    ----------
    units : list[str] or set[str]
        Unit names.

    Returns
    -------
    dict[str, dict[str, int]]
        Unit -> base unit -> exponent, in the order given.

    Raises
    ------
    ExportError
        Naming the units without a definition.
    """
    unknown = [u for u in units if u not in UNIT_DEFINITIONS]
    if unknown:
        raise ExportError(f"no SI definition for unit(s) {', '.join(map(repr, unknown))}")
    return {u: UNIT_DEFINITIONS[u] for u in units}


def append_units(parent: etree._Element, container: str, unit_tag: str, base_tag: str,
                 units: Mapping[str, Mapping[str, int]]) -> etree._Element | None:
    """Append ``<container><unit_tag name=u><base_tag kg=.. m=.. s=../></unit_tag>...``.

    Parameters
    ----------
    parent : etree._Element
        The element to append to.
    container : str
        Tag of the container (namespaced as given).
    unit_tag : str
        Tag of one unit.
    base_tag : str
        Tag of a unit's base-unit exponents (zero exponents are left out).
    units : Mapping[str, Mapping[str, int]]
        Unit -> base unit -> exponent (:func:`unit_definitions`).

    Returns
    -------
    etree._Element or None
        The container, or None (nothing appended) for no units.
    """
    if not units:
        return None
    box = etree.SubElement(parent, container)
    for name, base in units.items():
        unit = etree.SubElement(box, unit_tag, name=name)
        etree.SubElement(unit, base_tag, {k: str(v) for k, v in base.items() if v})
    return box


def built_variables(system: SystemDescription, fmus: Mapping[str, Path | str]
                    ) -> dict[str, dict[str, Variable]]:
    """Component -> the variables of the FMU it instantiates (read once per FMU file).

    Parameters
    ----------
    system : SystemDescription
        The system.
    fmus : Mapping[str, Path or str]
        FMU key (``Component.fmu``) -> .fmu path.

    Returns
    -------
    dict[str, dict[str, Variable]]
        Component name -> FMI scalar name -> :class:`Variable`.
    """
    per_fmu = {key: fmu_variables(fmus[key]) for key in {c.fmu for c in system.components}}
    return {c.name: per_fmu[c.fmu] for c in system.components}


def check_system(system: SystemDescription, fmus: Mapping[str, Path | str] | None = None,
                 fmu_files: Mapping[str, str] | None = None) -> dict[str, dict[str, Variable]]:
    """Refuse a system whose connections or parameters do not match its FMUs' variables.

    Parameters
    ----------
    system : SystemDescription
        The system.
    fmus : Mapping[str, Path or str] or None, optional
        The built FMUs (FMU key -> path); None: check against the interface tables
        (before anything is built).
    fmu_files : Mapping[str, str] or None, optional
        Component -> FMU file name, to name it in messages.

    Returns
    -------
    dict[str, dict[str, Variable]]
        The variables checked, per component.

    Raises
    ------
    ExportError
        Listing every problem.
    """
    variables = built_variables(system, fmus) if fmus is not None else system_variables(system)
    names = dict(fmu_files or {})
    if fmus is not None and not names:
        names = {c.name: Path(fmus[c.fmu]).name for c in system.components}
    problems = connection_problems(variables, system.scalar_connections(), fmu_names=names)
    for comp in system.components:
        for name in comp.parameters:
            var = variables[comp.name].get(name)
            if var is None or var.causality != "parameter":
                problems.append(f"parameter {comp.name}.{name}: the FMU "
                                f"{names.get(comp.name, comp.model)} has no such parameter")
    if problems:
        raise ExportError(problems)
    return variables
