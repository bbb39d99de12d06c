"""Scenarios: TOML files (built in: ``orchestrator/scenario/builtin/``) validated into a
:class:`Scenario` (the system, the run settings and, for a fleet, its spec).

- :mod:`.loader`: the file format, validation, :func:`load_scenario`;
- :mod:`.fleet`: the sections of a fleet scenario (vehicles, graph, leader, ...);
- :mod:`.generator`: generated grid fleets (formation-20, benchmarks).
"""
from .loader import (
                     SCENARIO_DIR,
                     Scenario,
                     ScenarioError,
                     builtin_scenarios,
                     load_scenario,
                     scenario_from_dict,
)

__all__ = ["SCENARIO_DIR", "Scenario", "ScenarioError", "builtin_scenarios", "load_scenario",
           "scenario_from_dict"]
