"""Is a system's wiring consistent with its FMUs' variables? One check for the master and
every export (OSP, SSP, cross-check).

:func:`connection_problems` returns the list of all problems (empty when the system can
run), each a sentence naming the connection and the variable, as ``fmpy.validate_fmu``
returns a list: a component or variable that does not exist, a connection that does not
go from an output to an input (two outputs, two inputs, a parameter), different types at
the two ends, an input fed by more than one output, an input left unconnected.
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .system import Component, ScalarConnection, SystemDescription

__all__ = ["Variable", "fmu_variables", "interface_variables", "connection_problems",
           "system_variables"]


@dataclass(frozen=True)
class Variable:
    """What a modelDescription (or an interface table) says about one scalar variable."""

    causality: str          #: parameter, calculatedParameter, input, output, local, independent
    type: str               #: Real, Integer, Boolean, String, Enumeration
    unit: str | None = None
    start: str | None = None


def fmu_variables(fmu: Path | str | Any) -> dict[str, Variable]:
    """Name -> :class:`Variable` of every variable of an FMU, in the modelDescription's order.

    Parameters
    ----------
    fmu : Path or str or Any
        Path of the .fmu, or an fmpy ModelDescription already read.

    Returns
    -------
    dict[str, Variable]
        Causality, type, unit and start of each scalar variable.
    """
    md = fmu
    if isinstance(fmu, (str, Path)):
        from fmpy import read_model_description
        md = read_model_description(str(fmu), validate=False)
    return {v.name: Variable(v.causality, v.type, v.unit, v.start) for v in md.modelVariables}


def interface_variables(component: Component) -> dict[str, Variable]:
    """The variables a component's FMU will have, from its interface table.

    Known before the FMU is built: nothing is built for a system that would not connect.

    Parameters
    ----------
    component : Component
        The component (its interface table).

    Returns
    -------
    dict[str, Variable]
        FMI scalar name -> causality, type and unit.
    """
    return {name: Variable(spec.causality, spec.type, spec.unit)
            for spec in component.interface for name in spec.elements}


def system_variables(system: SystemDescription) -> dict[str, dict[str, Variable]]:
    """Component name -> its planned variables (:func:`interface_variables`).

    Parameters
    ----------
    system : SystemDescription
        The system.

    Returns
    -------
    dict[str, dict[str, Variable]]
        Per component, FMI scalar name -> :class:`Variable`.
    """
    return {c.name: interface_variables(c) for c in system.components}


def _a(word: str) -> str:
    return f"{'an' if word[:1].lower() in 'aeiou' else 'a'} {word}"


def connection_problems(variables: Mapping[str, Mapping[str, Variable]],
                        connections: Iterable[ScalarConnection], *,
                        fmu_names: Mapping[str, str] | None = None) -> list[str]:
    """Every problem of a set of scalar connections against the components' variables.

    Parameters
    ----------
    variables : Mapping[str, Mapping[str, Variable]]
        Component name -> variable name -> :class:`Variable`.
    connections : Iterable[ScalarConnection]
        The scalar connections to check.
    fmu_names : Mapping[str, str] or None, optional
        Component -> FMU file name, to name the FMU in the messages.

    Returns
    -------
    list[str]
        One sentence per problem (a missing component or variable, a connection that does
        not go from an output to an input of the same type, an input fed twice or not at
        all); empty when the system can run.
    """
    label = dict(fmu_names or {})
    problems: list[str] = []

    def who(comp: str) -> str:
        return f"{comp} ({label[comp]})" if comp in label else comp

    fed: dict[tuple[str, str], list[ScalarConnection]] = {}     # input -> outputs feeding it
    reached: set[tuple[str, str]] = set()                       # inputs some connection names
    for c in connections:
        ends: list[Variable] = []
        for comp, name in (c.source, c.target):
            if comp not in variables:
                problems.append(f"connection {c}: there is no component {comp!r} "
                                f"(components: {', '.join(variables)})")
            elif name not in variables[comp]:
                problems.append(f"connection {c}: {who(comp)} has no variable {name!r}")
            else:
                ends.append(variables[comp][name])
        if len(ends) < 2:
            continue
        src, tgt = ends
        s, t = f"{c.source[0]}.{c.source[1]}", f"{c.target[0]}.{c.target[1]}"
        if tgt.causality == "input":
            reached.add(c.target)
            if src.causality == "output":
                fed.setdefault(c.target, []).append(c)
        if src.causality == tgt.causality == "output":
            problems.append(f"connection {c} connects two outputs ({s} and {t})")
        elif src.causality == tgt.causality == "input":
            problems.append(f"connection {c} connects two inputs ({s} and {t})")
        elif src.causality != "output":
            problems.append(f"connection {c}: source {s} is {_a(src.causality)}, not an output")
        elif tgt.causality != "input":
            problems.append(f"connection {c}: target {t} is {_a(tgt.causality)}, not an input")
        elif src.type != tgt.type:
            problems.append(f"connection {c} connects {_a(src.type)} output to "
                            f"{_a(tgt.type)} input")
    for (comp, name), cs in fed.items():
        if len(cs) > 1:
            problems.append(f"input {comp}.{name} is fed by {len(cs)} outputs "
                            f"({', '.join(f'{a}.{b}' for a, b in (x.source for x in cs))})")
    for comp, names in variables.items():
        for name, var in names.items():
            if var.causality == "input" and (comp, name) not in reached:
                problems.append(f"input {comp}.{name} is not connected")
    return problems
