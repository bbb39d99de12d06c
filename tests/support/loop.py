"""The paper loop's system description, seen from the tests: parameter values and output
names of one component for a configuration."""
from __future__ import annotations

from typing import Any

from fmu_common.interface import element_names
from orchestrator.cosim.system import closed_loop_system


def fmu_parameters(component: str, config: dict[str, Any]) -> dict[str, Any]:
    """Scalar parameter values (FMI names) the master sets on one component of the loop."""
    return dict(closed_loop_system(config).component(component).parameters)


def output_names(component: str, config: dict[str, Any]) -> list[str]:
    """FMI scalar names of all outputs of one component, in the FMU's order."""
    comp = closed_loop_system(config).component(component)
    return [n for s in comp.arrays("output") for n in element_names(s.name, s.shape)]
