"""The co-simulation as data: components, connections and the step size.

A :class:`SystemDescription` is the single place the wiring of a co-simulation is
written. The master (:mod:`orchestrator.cosim.master`) derives its evaluation order and
its batched get/set plans from it; the OSP, SSP and cross-check exports
(:mod:`orchestrator.interop`) write it in other tools' formats; the recording names its
traces after its outputs.

- a :class:`Component` is one FMU instance: its name in the system, which FMU (a key of
  :data:`orchestrator.cosim.build.FMU_KINDS`), the FMU's interface table (named arrays,
  :class:`fmu_common.interface.ArraySpec`, with units and direct feedthrough) and the
  parameter values the run sets in initialization mode (FMI scalar names);
- a :class:`Connection` feeds an output array of one component to an input array of
  another, element by element (scalar connections ``y[1] -> y[1]``, ...); it may carry data
  only when a component's parameter has a given value (``when``): the truth signals reach
  the estimator only in mode ``ideal``. Exports write every connection (an FMU input must
  be connected); the master drops the ones that carry nothing in the run, so they cost
  nothing per step.

:func:`closed_loop_system` is the paper's loop (one plant, one estimator, one controller,
also for a stacked fleet)::

    plant.y, ybar, x, w, z   -> estimator.y, ybar, x, w, z  (x, w, z only if estimator.mode = ideal)
    estimator.xhat, what, zhat -> controller.xhat, what, zhat
    controller.u             -> plant.u, estimator.u
"""
from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from estimator_fmu.registry import TRUTH
from fmu_common.interface import ArraySpec, element_names

from .build import FMU_KINDS, interface_of

__all__ = ["Component", "Connection", "ScalarConnection", "SystemDescription",
           "closed_loop_system", "component_parameters", "evaluation_order", "AlgebraicLoopError"]


class AlgebraicLoopError(ValueError):
    """Outputs that depend on themselves within a step through direct feedthrough."""


@dataclass(frozen=True)
class Component:
    """One FMU instance of a system."""

    name: str                                   #: instance name in the system
    fmu: str                                    #: key of FMU_KINDS (which FMU)
    interface: tuple[ArraySpec, ...]            #: the FMU's arrays (parameters, inputs, outputs)
    parameters: Mapping[str, Any] = field(default_factory=dict)  #: FMI scalar name -> value

    def arrays(self, causality: str) -> list[ArraySpec]:
        """The arrays of one causality, in the FMU's order.

        Parameters
        ----------
        causality : str
            'parameter', 'input' or 'output'.

        Returns
        -------
        list[ArraySpec]
            The matching arrays of the interface table.
        """
        return [s for s in self.interface if s.causality == causality]

    def array(self, name: str) -> ArraySpec:
        """The array ``name`` of the interface table.

        Parameters
        ----------
        name : str
            The array's name (e.g. ``y``).

        Returns
        -------
        ArraySpec
            Its spec.

        Raises
        ------
        KeyError
            If the component has no such array.
        """
        for s in self.interface:
            if s.name == name:
                return s
        raise KeyError(f"component {self.name!r} ({self.fmu}) has no variable array {name!r}")

    @property
    def model(self) -> str:
        """The FMU's model identifier (AuvPlant, ...)."""
        return FMU_KINDS[self.fmu].model


@dataclass(frozen=True)
class ScalarConnection:
    """``source`` (component, variable) feeds ``target`` (component, variable)."""

    source: tuple[str, str]
    target: tuple[str, str]

    def __str__(self) -> str:
        return f"{self.source[0]}.{self.source[1]} -> {self.target[0]}.{self.target[1]}"


@dataclass(frozen=True)
class Connection:
    """Output array ``source.output`` feeds input array ``target.input`` element by element.

    ``when``: (component, parameter, value): the connection carries data only when that
    parameter has that value in the run (None: always)."""

    source: str
    output: str
    target: str
    input: str
    when: tuple[str, str, Any] | None = None

    def __str__(self) -> str:
        return f"{self.source}.{self.output} -> {self.target}.{self.input}"


@dataclass(frozen=True)
class SystemDescription:
    """Components, connections and the communication step of a co-simulation."""

    name: str
    components: tuple[Component, ...]
    connections: tuple[Connection, ...]
    h: float                                    #: communication step, s
    T: float                                    #: stop time, s (start 0)

    def component(self, name: str) -> Component:
        """The component ``name``.

        Parameters
        ----------
        name : str
            Instance name in the system.

        Returns
        -------
        Component
            The component.

        Raises
        ------
        KeyError
            If there is no such component (the message lists the components).
        """
        for c in self.components:
            if c.name == name:
                return c
        raise KeyError(f"system {self.name!r} has no component {name!r} "
                       f"(components: {', '.join(c.name for c in self.components)})")

    @property
    def names(self) -> list[str]:
        """The components' names, in system order."""
        return [c.name for c in self.components]

    def active(self, c: Connection) -> bool:
        """Does ``c`` carry data with the components' parameter values?

        Parameters
        ----------
        c : Connection
            A connection of this system.

        Returns
        -------
        bool
            True if ``c.when`` is None or its parameter has the given value.
        """
        if c.when is None:
            return True
        comp, par, value = c.when
        return self.component(comp).parameters.get(par) == value

    def active_connections(self) -> list[Connection]:
        """The connections that carry data in this run (:meth:`active`).

        Returns
        -------
        list[Connection]
            In the order of the description.
        """
        return [c for c in self.connections if self.active(c)]

    def scalar_connections(self, *, active_only: bool = False) -> list[ScalarConnection]:
        """One connection per scalar, in the order of the connections and elements.

        The variable-level checks are in :mod:`orchestrator.cosim.checks`.

        Parameters
        ----------
        active_only : bool, optional
            Only the connections that carry data in this run.

        Returns
        -------
        list[ScalarConnection]
            ``y[1] -> y[1]``, ... for every array connection.

        Raises
        ------
        ValueError
            Naming an array connection whose two ends differ in size.
        """
        out = []
        for c in (self.active_connections() if active_only else self.connections):
            src, dst = self.component(c.source), self.component(c.target)
            a, b = _find(src, c.output), _find(dst, c.input)
            shape_a = a.shape if a else (b.shape if b else ())
            na = a.elements if a else element_names(c.output, shape_a)
            nb = b.elements if b else element_names(c.input, shape_a)
            if len(na) != len(nb):
                raise ValueError(f"connection {c}: {c.source}.{c.output} has {len(na)} "
                                 f"elements, {c.target}.{c.input} has {len(nb)}")
            out += [ScalarConnection((c.source, x), (c.target, y)) for x, y in zip(na, nb)]
        return out

    def with_parameters(self, component: str, **values: Any) -> SystemDescription:
        """A copy with some parameter values of one component replaced.

        Parameters
        ----------
        component : str
            The component's name.
        **values : Any
            FMI scalar parameter name -> new value.

        Returns
        -------
        SystemDescription
            The new description.

        Raises
        ------
        KeyError
            If there is no such component.
        """
        comps = tuple(replace(c, parameters={**c.parameters, **values}) if c.name == component
                      else c for c in self.components)
        self.component(component)
        return replace(self, components=comps)

    def outputs(self) -> Iterator[tuple[Component, ArraySpec]]:
        """Every output array of every component, in system order.

        Yields
        ------
        tuple[Component, ArraySpec]
            The component and one of its output arrays.
        """
        for comp in self.components:
            for spec in comp.arrays("output"):
                yield comp, spec

    def output_width(self) -> int:
        """Values per step of every output of every component (a trace row's width)."""
        return sum(spec.size for _, spec in self.outputs())

    def trace_names(self) -> dict[tuple[str, str], str]:
        """(component, output) -> the name of its trace.

        The output's name where no other component has an output of that name, else
        ``component.output``.

        Returns
        -------
        dict[tuple[str, str], str]
            Trace name of every output array.
        """
        count: dict[str, int] = {}
        for _, spec in self.outputs():
            count[spec.name] = count.get(spec.name, 0) + 1
        return {(c.name, s.name): s.name if count[s.name] == 1 else f"{c.name}.{s.name}"
                for c, s in self.outputs()}


def _find(comp: Component, name: str) -> ArraySpec | None:
    for s in comp.interface:
        if s.name == name:
            return s
    return None


def evaluation_order(system: SystemDescription) -> list[tuple[str, str]]:
    """The (component, output array) pairs in an order that respects direct feedthrough.

    Within one communication step an output that depends directly on an input (its
    ``depends_on``) can be read only after the output feeding that input was read and set:
    the lexicographic topological order (Kahn's algorithm, smallest rank first) of the graph
    output -> connection -> dependent output, ranks being the order of components and
    outputs in the description.

    Parameters
    ----------
    system : SystemDescription
        The system (its active connections and the outputs' ``depends_on``).

    Returns
    -------
    list[tuple[str, str]]
        Every (component, output array), in evaluation order.

    Raises
    ------
    AlgebraicLoopError
        Naming the cycle, if outputs depend on themselves through direct feedthrough.
    """
    import heapq
    from graphlib import CycleError, TopologicalSorter

    rank = {(c.name, s.name): (i, j) for i, c in enumerate(system.components)
            for j, s in enumerate(c.arrays("output"))}
    succ: dict[tuple[str, str], list[tuple[str, str]]] = {n: [] for n in rank}
    via: dict[tuple, str] = {}
    indegree = dict.fromkeys(rank, 0)
    for c in system.active_connections():
        if (c.source, c.output) not in rank:
            continue
        for spec in system.component(c.target).arrays("output"):
            dst = (c.target, spec.name)
            if c.input in spec.depends_on and dst not in succ[(c.source, c.output)]:
                succ[(c.source, c.output)].append(dst)
                via[(c.source, c.output), dst] = c.input
                indegree[dst] += 1
    ready = [(rank[n], n) for n, d in indegree.items() if d == 0]
    heapq.heapify(ready)
    order: list[tuple[str, str]] = []
    while ready:
        _, n = heapq.heappop(ready)
        order.append(n)
        for m in succ[n]:
            indegree[m] -= 1
            if indegree[m] == 0:
                heapq.heappush(ready, (rank[m], m))
    if len(order) == len(rank):
        return order
    try:                                        # find one cycle to name it
        TopologicalSorter({m: [n for n in succ if m in succ[n]] for m in rank}).prepare()
        cycle: list = []
    except CycleError as exc:
        cycle = list(exc.args[1])               # [a, b, ..., a], each feeding the next
    steps = " -> ".join(f"{a[0]}.{a[1]} (into {b[0]}.{via[a, b]})"
                        for a, b in zip(cycle, cycle[1:]))
    raise AlgebraicLoopError(
        f"system {system.name!r} has an algebraic loop: {steps} -> "
        f"{cycle[0][0]}.{cycle[0][1]}; break it with an output that does not "
        "feed through (a delay) or couple with coupling='jacobi'")


def component_parameters(specs: list[ArraySpec] | tuple[ArraySpec, ...]) -> dict[str, Any]:
    """Scalar parameter values (FMI names) of an interface table's parameters.

    Parameters
    ----------
    specs : list[ArraySpec] or tuple[ArraySpec, ...]
        An interface table.

    Returns
    -------
    dict[str, Any]
        FMI scalar name -> start value (``A[1,2]`` -> float, a String parameter -> str).
    """
    out: dict[str, Any] = {}
    for spec in specs:
        if spec.causality != "parameter":
            continue
        if spec.type == "String":
            out[spec.name] = spec.start
            continue
        flat = np.asarray(spec.start).reshape(-1)
        for name, value in zip(spec.elements, flat):
            out[name] = value
    return out


#: the closed loop's wiring: (source, output array, target, input array, when)
_LOOP = (
    ("plant", "y", "estimator", "y", None),
    ("plant", "ybar", "estimator", "ybar", None),
    *(("plant", s, "estimator", s, ("estimator", "mode", TRUTH)) for s in ("x", "w", "z")),
    *(("estimator", s, "controller", s, None) for s in ("xhat", "what", "zhat")),
    ("controller", "u", "plant", "u", None),
    ("controller", "u", "estimator", "u", None),
)


def closed_loop_system(config: dict[str, Any], name: str = "auv_loop") -> SystemDescription:
    """The paper's loop of plant, estimator and controller FMUs built for ``config``.

    Parameters
    ----------
    config : dict[str, Any]
        :func:`orchestrator.cosim.build.fmu_config`, with the run's ``mode``, ``seed`` and
        ``tracking``; the components' parameter values are the configuration's.
    name : str, optional
        The system's name.

    Returns
    -------
    SystemDescription
        Components plant, estimator, controller, the loop's connections, h and T (s).
    """
    comps = []
    for key in ("plant", "estimator", "controller"):
        specs = tuple(interface_of(FMU_KINDS[key], config))
        comps.append(Component(key, key, specs, component_parameters(specs)))
    return SystemDescription(name=name, components=tuple(comps),
                             connections=tuple(Connection(*c) for c in _LOOP),
                             h=float(config["h"]), T=float(config["T"]))
