"""orchestrator.scenario.schema / schema_fleet / errors: the pydantic schemas of scenario files.

Every problem is one line naming the source, the section (from the error's location, not
from its text) and the key; pydantic's own multi-line report never gets through; the FMUs
never import pydantic.
"""
from __future__ import annotations

import copy
import subprocess
import sys
import tomllib

import pytest

from orchestrator.scenario import SCENARIO_DIR, ScenarioError, load_scenario, scenario_from_dict
from orchestrator.scenario.fleet import fleet_spec_from_dict

PAPER = tomllib.loads((SCENARIO_DIR / "paper.toml").read_text())
FLEET = tomllib.loads((SCENARIO_DIR / "formation-4.toml").read_text())


def error_of(base: dict, change) -> str:
    data = copy.deepcopy(base)
    change(data)
    with pytest.raises(ScenarioError) as exc:
        scenario_from_dict(data, "case.toml")
    msg = str(exc.value)
    assert msg.startswith("case.toml: "), msg
    assert "\n" not in msg and "Input should" not in msg and "pydantic" not in msg, msg
    return msg


# sections named by location (where the old keyword guess named none, or the wrong one) -----
@pytest.mark.parametrize("change, expect", [
    (lambda d: d["leader"].update(noise=-1.0), "[leader] noise must be positive semidefinite"),
    (lambda d: d["noise"].update(process=-1.0), "[noise] process must be positive semidefinite"),
    (lambda d: d["noise"].update(convention="psd"),
     "[noise] convention 'psd' is unknown; expected one of intensity, per_sample"),
    (lambda d: d["cost"].update(Q=0.0), "[cost] Q must be positive definite"),
    (lambda d: d["cost"].update(R=[[1.0]]), "[cost] R: wrong shape 1x1, expected 3x3"),
    (lambda d: d["graph"].update(coupling=[[1.0]]), "[graph] coupling: wrong shape 1x1, expected 6x6"),
    (lambda d: d["current"].update(w0=[1.0]), "[current] w0: wrong length 1, expected 3"),
    (lambda d: d["current"].update(sigma=-0.1), "[current] sigma = -0.1 must be a non-negative speed"),
    (lambda d: d.update(disturbance={"K": [[-1.0]]}),
     "[disturbance] give [current] or [disturbance], not both"),
])
def test_fleet_domain_errors_name_their_section(change, expect):
    assert expect in error_of(FLEET, change)


@pytest.mark.parametrize("change, expect", [
    (lambda d: d["vehicles"].update(overrides=[{"vehicle": 2, "cost": {"S": 1.0}}]),
     "unknown key(s) in [vehicles] overrides[1] (vehicle 2) cost: S (allowed: Q, R)"),
    (lambda d: d["vehicles"].update(overrides=[{"vehicle": 2, "current": {"sigma": -1.0}}]),
     "[vehicles] overrides[1] (vehicle 2) current.sigma = -1.0 must be a non-negative speed"),
    (lambda d: d["vehicles"].update(overrides=[{"vehicle": 3, "cost": {"R": -1.0}}]),
     "[vehicles] vehicle 3 cost R must be positive definite"),
    (lambda d: d["vehicles"].update(overrides=[{"model": "generic"}]),
     "missing key(s) in [vehicles] overrides[1]: vehicle"),
    (lambda d: d["vehicles"].update(overrides=[{"vehicle": 9}]),
     "[vehicles] overrides entry 1: vehicle 9 does not exist; vehicles are 1..4"),
])
def test_override_errors_name_the_entry_and_the_vehicle(change, expect):
    assert expect in error_of(FLEET, change)


# strict types ----------------------------------------------------------------------------
@pytest.mark.parametrize("base, change, expect", [
    (FLEET, lambda d: d["vehicles"].update(count=True), "[vehicles] count = True must be a positive integer"),
    (FLEET, lambda d: d["vehicles"].update(count=2.0), "[vehicles] count = 2.0 must be a positive integer"),
    (FLEET, lambda d: d["current"].update(sigma=True), "[current] sigma = True must be"),
    (FLEET, lambda d: d["simulation"].update(seed=-2), "[simulation] seed = -2 must be a non-negative integer"),
    (FLEET, lambda d: d["graph"].update(edges="x"), "[graph] edges = 'x' must be an array"),
    (PAPER, lambda d: d["cost"].update(R=True), "[cost] R: expected a number, got True"),
    (PAPER, lambda d: d.update(name=3), "name = 3 must be a string"),
    (PAPER, lambda d: d["simulation"].update(tracking="pid"),
     "[simulation] tracking 'pid' is unknown; expected one of lq, regulator"),
])
def test_strict_types(base, change, expect):
    assert expect in error_of(base, change)


# which error is reported, and how missing / unknown keys are grouped ------------------------
def test_structure_problems_come_before_bad_values():
    def change(d):
        d["simulation"]["h"] = -1.0
        d["vehicles"].pop("C")
        d["cost"]["S"] = 1.0
        d["plant"] = {}
    msg = error_of(PAPER, change)
    assert "unknown section(s) or key(s): plant" in msg, msg
    change2 = lambda d: (change(d), d.pop("plant"))                       # noqa: E731
    assert "unknown key(s) in [cost]: S (allowed: Q, R)" in error_of(PAPER, change2)
    change3 = lambda d: (change2(d), d["cost"].pop("S"))                  # noqa: E731
    assert "missing key(s) in [vehicles]: C (p x n matrix)" in error_of(PAPER, change3)


def test_missing_and_unknown_keys_of_one_table_are_listed_together():
    msg = error_of(PAPER, lambda d: (d["vehicles"].pop("B2"), d["vehicles"].pop("A")))
    assert "missing key(s) in [vehicles]: A, B2 (A: n x n matrix; B2: n x r matrix)" in msg, msg
    msg = error_of(FLEET, lambda d: d["graph"].update(weights=1, nodes=2))
    assert "unknown key(s) in [graph]: nodes, weights (allowed: edges, pinning, coupling, consensus)" in msg


def test_missing_sections_of_a_fleet():
    assert "[graph] section is missing" in error_of(FLEET, lambda d: d.pop("graph"))
    assert "missing key(s) in [leader]: path (straight, circle, lawnmower or explicit)" in \
        error_of(FLEET, lambda d: d["leader"].pop("path"))


# run settings and entry points -------------------------------------------------------------
def test_with_run_is_checked_by_the_simulation_schema():
    sc = load_scenario("paper")
    with pytest.raises(ScenarioError, match=r"^built-in scenario 'paper': \[simulation\] seed = -1 "):
        sc.with_run(seed=-1)
    with pytest.raises(ScenarioError, match=r"\[simulation\] tracking 'pid' is unknown"):
        sc.with_run(tracking="pid")
    assert sc.with_run(h=0.02, tracking="regulator").tracking == "regulator"


def test_fleet_spec_from_dict_names_the_source():
    data = copy.deepcopy(FLEET)
    data["vehicles"]["count"] = 0
    with pytest.raises(ScenarioError, match=r"^my fleet: \[vehicles\] count = 0 must be"):
        fleet_spec_from_dict(data, "my fleet")


def test_the_fmus_do_not_import_pydantic():
    code = ("import sys, plant_model, estimator_fmu, controller_fmu, fmu_common\n"
            "import plant_model.fleet, plant_model.auv_plant_slave, estimator_fmu.estimators\n"
            "import controller_fmu.regulator, controller_fmu.auv_controller_slave\n"
            "import estimator_fmu.auv_estimator_slave\n"
            "print('pydantic' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "False"
