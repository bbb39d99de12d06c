"""A fleet scenario whose stacked model would not fit in memory is refused when it is
loaded, before the model is allocated (orchestrator/scenario/size.py): by the loader, by
`auv-cosim run` on such a file, in one line with the vehicles, the states, the estimate
and the memory available."""
from __future__ import annotations

import json
import resource
import subprocess
import sys
from pathlib import Path

import pytest

from orchestrator.scenario import ScenarioError, scenario_from_dict
from orchestrator.scenario.errors import validate_scenario
from orchestrator.scenario.generator import grid_fleet
from orchestrator.scenario.schema_fleet import FleetScenario
from orchestrator.scenario.size import MODEL_BYTES_PER_STATE2, check_fleet_model

ROOT = Path(__file__).resolve().parents[1]


def _value(v) -> str:
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_value(x)}" for k, x in v.items()) + " }"
    return json.dumps(v)


def toml_text(data: dict) -> str:
    """A generated scenario as TOML (its values are numbers, strings, lists and tables)."""
    top = [f"{k} = {_value(v)}" for k, v in data.items() if not isinstance(v, dict)]
    sections = [f"[{k}]\n" + "\n".join(f"{kk} = {_value(vv)}" for kk, vv in v.items())
                for k, v in data.items() if isinstance(v, dict)]
    return "\n".join(top) + "\n\n" + "\n\n".join(sections) + "\n"


def test_the_estimate_follows_the_states_and_the_limit_is_the_memory_available():
    fleet = validate_scenario(FleetScenario, grid_fleet(50, T=1.0), "grid-50")
    states = sum(m.p + m.r for m in fleet.vehicles.models) + len(fleet.leader.leader_path.z0) + 1
    need = check_fleet_model(fleet, "grid-50", available=10**12)
    assert need == MODEL_BYTES_PER_STATE2 * states * states
    with pytest.raises(ScenarioError) as exc:
        check_fleet_model(fleet, "grid-50", available=need)     # 80 % of it is too little
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith(f"grid-50: the stacked model of 50 vehicles "
                                              f"({states} states) needs about ")
    assert "of memory available; use fewer vehicles" in msg


def test_the_loader_refuses_2000_vehicles_before_building_them():
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    with pytest.raises(ScenarioError) as exc:
        scenario_from_dict(grid_fleet(2000, T=0.1), "grid-2000")
    msg = str(exc.value)
    assert "\n" not in msg
    assert msg.startswith("grid-2000: the stacked model of 2000 vehicles (18006 states) needs")
    grown_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before
    assert grown_kb < 500_000                      # the model alone would be 36 GB


def test_run_on_a_2000_vehicle_file_is_one_line_and_writes_nothing(tmp_path):
    (tmp_path / "big.toml").write_text(toml_text(grid_fleet(2000, T=0.1)))
    r = subprocess.run([sys.executable, "-m", "orchestrator.cli", "run", "--scenario",
                        "big.toml", "--out", "out"], capture_output=True, text=True,
                       cwd=tmp_path, timeout=300, env={"PYTHONPATH": str(ROOT),
                                                       "PATH": "/usr/bin:/bin"})
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert lines[0].startswith("auv-cosim run: error: big.toml: the stacked model of 2000 "
                               "vehicles (18006 states) needs about ")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.toml"]
