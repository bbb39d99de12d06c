"""Fleet scenario files: bad input is a ScenarioError naming the vehicle or edge; regulator
problems without a solution are reported by tracking_law and by the controller FMU; the
paper's example as a fleet of one generic vehicle."""
from __future__ import annotations

import copy
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from controller_fmu.regulator import tracking_law
from orchestrator.analysis.reference import run_monolithic
from orchestrator.cosim.instance import CosimError, Extracted, FmuInstance
from orchestrator.running import build, scenario_config
from orchestrator.scenario import SCENARIO_DIR, ScenarioError, load_scenario
from orchestrator.scenario.generator import scenario_toml as dumps
from plant_model.linalg_checks import ModelError
from support.loop import fmu_parameters, run_cosimulation

BASE = tomllib.loads((SCENARIO_DIR / "formation-4.toml").read_text())
EDGES = BASE["graph"]["edges"]           # [[1, 2, 1.0], [1, 3, 1.0], [2, 4, 0.5], [3, 4, 0.5]]


# --------------------------------------------------------------------------------------
def write_variant(tmp_path: Path, change, name: str = "variant") -> Path:
    data = copy.deepcopy(BASE)
    change(data)
    path = tmp_path / f"{name}.toml"
    path.write_text(dumps(data))
    return path


def load_error(tmp_path: Path, change) -> str:
    path = write_variant(tmp_path, change)
    with pytest.raises(ScenarioError) as err:
        load_scenario(path)
    msg = str(err.value)
    assert str(path) in msg, msg          # every message names the file
    return msg


def test_the_writer_round_trips_formation_4(tmp_path):
    path = write_variant(tmp_path, lambda d: None)
    assert tomllib.loads(path.read_text()) == BASE
    a, b = load_scenario(path), load_scenario("formation-4")
    for k in ("A", "Bz", "H", "x0", "W_x", "V_y"):
        np.testing.assert_array_equal(getattr(a.system, k), getattr(b.system, k))


# --------------------------------------------------------------------------------------
# graph
def test_vehicle_without_path_from_the_leader(tmp_path):
    msg = load_error(tmp_path, lambda d: d["graph"].update(edges=[[1, 2, 1.0], [1, 3, 1.0],
                                                                  [4, 2, 0.5]]))
    assert "[graph]" in msg and "vehicle 4 has no path from the leader" in msg, msg
    assert "pinned: 1" in msg


def test_several_vehicles_without_path_are_all_named(tmp_path):
    msg = load_error(tmp_path, lambda d: d["graph"].update(pinning=[[4, 1.0]]))
    assert "vehicles 1, 2, 3 have no path from the leader" in msg, msg


def test_negative_edge_weight(tmp_path):
    msg = load_error(tmp_path, lambda d: d["graph"].update(
        edges=[[1, 2, 1.0], [1, 3, 1.0], [2, 4, -0.5], [3, 4, 0.5]]))
    assert "edge 2 -> 4" in msg and "-0.5" in msg and "positive" in msg, msg


def test_negative_and_zero_pinning_weight(tmp_path):
    msg = load_error(tmp_path, lambda d: d["graph"].update(pinning=[[1, -1.0]]))
    assert "pinning of vehicle 1" in msg and "positive" in msg, msg
    msg = load_error(tmp_path, lambda d: d["graph"].update(pinning=[[1, 0.0]]))
    assert "pinning of vehicle 1" in msg and "weight 0 must be positive" in msg, msg


def test_self_loop(tmp_path):
    msg = load_error(tmp_path, lambda d: d["graph"].update(edges=EDGES + [[3, 3, 1.0]]))
    assert "edge 3 -> 3 is a self-loop" in msg, msg


def test_edge_to_a_vehicle_that_does_not_exist(tmp_path):
    msg = load_error(tmp_path, lambda d: d["graph"].update(edges=EDGES + [[4, 5, 1.0]]))
    assert "edge 4 -> 5" in msg and "vehicle 5 does not exist" in msg and "1..4" in msg, msg
    # the leader is not a vehicle: edges from 0 are refused with a hint to the pinning
    msg = load_error(tmp_path, lambda d: d["graph"].update(edges=EDGES + [[0, 4, 1.0]]))
    assert "vehicle 0 does not exist" in msg and "pinning" in msg, msg


def test_duplicate_edge(tmp_path):
    msg = load_error(tmp_path, lambda d: d["graph"].update(edges=EDGES + [[1, 2, 2.0]]))
    assert "edge 1 -> 2 is given twice" in msg, msg


# --------------------------------------------------------------------------------------
# vehicles
def test_offsets_of_the_wrong_count(tmp_path):
    msg = load_error(tmp_path, lambda d: d["vehicles"].update(offsets=BASE["vehicles"]["offsets"][:3]))
    assert "[vehicles]" in msg and "offsets" in msg and "4 rows of 3" in msg and "(3, 3)" in msg, msg
    msg = load_error(tmp_path, lambda d: d["vehicles"].update(
        offsets=[row[:2] for row in BASE["vehicles"]["offsets"]]))
    assert "offsets" in msg and "4 rows of 3" in msg and "(4, 2)" in msg, msg


def test_ragged_or_non_numeric_offsets(tmp_path):
    """Was numpy's raw 'inhomogeneous shape' / 'could not convert' without section or key."""
    msg = load_error(tmp_path, lambda d: d["vehicles"].update(
        offsets=[[10.0, 0.0, 0.0], [0.0, -10.0], [0.0, 10.0, 0.0], [-10.0, 0.0, 0.0]]))
    assert "[vehicles]" in msg and "offsets" in msg and "4 rows of 3" in msg, msg
    msg = load_error(tmp_path, lambda d: d["vehicles"].update(
        offsets=[[10.0, 0.0, 0.0], [0.0, "west", 0.0], [0.0, 10.0, 0.0], [-10.0, 0.0, 0.0]]))
    assert "[vehicles]" in msg and "offsets" in msg and "numbers" in msg, msg


def test_override_offset_of_the_wrong_length_names_the_vehicle(tmp_path):
    msg = load_error(tmp_path, lambda d: d["vehicles"].update(
        overrides=[{"vehicle": 3, "offset": [1.0, 2.0]}]))
    assert "vehicle 3 offset" in msg and "length 2" in msg, msg


def test_unknown_vehicle_model(tmp_path):
    msg = load_error(tmp_path, lambda d: d["vehicles"].update(model="remus600"))
    assert "vehicle 1: unknown vehicle model 'remus600'" in msg and "remus100, remus100-6dof, remus100-fitted, generic" in msg, msg
    msg = load_error(tmp_path, lambda d: d["vehicles"].update(
        overrides=[{"vehicle": 3, "model": "glider"}]))
    assert "vehicle 3: unknown vehicle model 'glider'" in msg, msg


# --------------------------------------------------------------------------------------
# regulator problems with no solution: the scenario loads, the regulator law is refused
GENERIC_HEAD = """
name = "{name}"
[simulation]
T = 10.0
h = 0.01
estimator = "kalman"
tracking = "regulator"
"""

# C (sI - A)^-1 B1 = -s / ((s + 1)(s + 2)): a transmission zero at 0, the eigenvalue of a
# constant leader. The coupling acts through B1 (Gamma = B1 k'), a state feedback, which
# leaves the zeros of the stacked plant where they are.
ZERO_AT_LEADER = GENERIC_HEAD.format(name="zero-at-leader") + """
[leader]
path = "explicit"
F = [[0.0]]
H = [[1.0]]
z0 = [1.0]
[vehicles]
count = 2
model = "generic"
params = { A = [[-1.0, 0.0], [0.0, -2.0]], B1 = [[1.0], [1.0]], B2 = [[1.0], [0.0]], C = [[1.0, -2.0]] }
[graph]
edges = [[1, 2, 1.0]]
pinning = [[1, 1.0]]
coupling = [[0.1, 0.1], [0.1, 0.1]]
[noise]
process = 0.01
position = 0.01
"""

# two outputs (position, velocity) and one input per vehicle
FEWER_INPUTS = GENERIC_HEAD.format(name="fewer-inputs") + """
[leader]
path = "explicit"
F = [[0.0, 1.0], [0.0, 0.0]]
H = [[1.0, 0.0], [0.0, 1.0]]
z0 = [0.0, 0.5]
[vehicles]
count = 2
model = "generic"
params = { A = [[0.0, 1.0], [0.0, -1.0]], B1 = [[0.0], [1.0]], B2 = [[0.0], [1.0]], C = [[1.0, 0.0], [0.0, 1.0]] }
[graph]
consensus = "in-plant"
edges = [[1, 2, 1.0]]
pinning = [[1, 1.0]]
"""


def _load_text(tmp_path: Path, text: str, name: str):
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return load_scenario(path)


def test_fewer_inputs_than_outputs_loads_but_has_no_regulator(tmp_path):
    # the identity coupling acts on x1, which the single input cannot reach: in-plant only
    with pytest.raises(ScenarioError, match="rows for x1 cannot be produced by any force"):
        _load_text(tmp_path, FEWER_INPUTS.replace('consensus = "in-plant"\n', ""), "fewer0")
    sc = _load_text(tmp_path, FEWER_INPUTS, "fewer")
    assert (sc.system.m, sc.system.p) == (2, 4)
    tracking_law(sc.system, "lq")                 # the paper's law exists
    with pytest.raises(ModelError) as err:
        tracking_law(sc.system, "regulator")
    msg = str(err.value)
    assert "2 inputs" in msg and "4 outputs" in msg and "at least as many inputs as outputs" in msg, msg


def test_transmission_zero_at_a_leader_eigenvalue_loads_but_has_no_regulator(tmp_path):
    sc = _load_text(tmp_path, ZERO_AT_LEADER, "zero")
    assert sc.tracking == "regulator"
    tracking_law(sc.system, "lq")
    with pytest.raises(ModelError) as err:
        tracking_law(sc.system, "regulator")
    msg = str(err.value)
    assert "eigenvalue 0 of the exosystem F (reference)" in msg and "transmission zero" in msg, msg


def test_controller_fmu_reports_the_missing_regulator_as_an_fmi_error(tmp_path):
    sc = _load_text(tmp_path, ZERO_AT_LEADER, "zero")
    fmus = build(sc, tmp_path / "fmus")
    cfg = scenario_config(sc)
    ex = Extracted({"controller": fmus["controller"]})
    try:
        params = fmu_parameters("controller", cfg)
        assert params["tracking"] == "regulator"
        bad = FmuInstance("controller", fmus["controller"], ex.dirs["controller"], "ctrl_reg")
        try:
            with pytest.raises(CosimError) as err:
                bad.initialize(params, T=1.0)
            msg = str(err.value)
            assert "ExitInitializationMode" in msg and re.search(r"status [34]", msg), msg
            assert "transmission zero" in msg and "eigenvalue 0" in msg, msg
            assert any(s in ("Error", "Fatal") and "transmission zero" in m
                       for s, m in bad.messages), bad.messages
        finally:
            bad.close()
        # the same FMU with the paper's law initializes and computes u
        good = FmuInstance("controller", fmus["controller"], ex.dirs["controller"], "ctrl_lq")
        try:
            good.initialize(dict(params, tracking="lq"), T=1.0)
            u = good.slave.getReal([good.vr["u[1]"], good.vr["u[2]"]])
            assert np.all(np.isfinite(u))
        finally:
            good.close()
    finally:
        ex.cleanup()
    # and the master stops with a named error instead of crashing
    with pytest.raises(CosimError, match="controller FMU.*transmission zero"):
        run_cosimulation(fmus, cfg, mode="kalman", seed=0, steps=10)


# --------------------------------------------------------------------------------------
# the paper's example as a fleet of N = 1 generic vehicle
PAPER_FLEET = """
name = "paper-as-fleet"
[simulation]
T = 300.0
h = 0.01
seed = 0
estimator = "kalman"
[leader]
path = "explicit"
F = [[-0.1, 1.0], [-1.0, -0.2]]
H = [[0.2, 4.0], [2.0, 5.0]]
z0 = [0.4, 0.5]
noise = 2.0
[vehicles]
count = 1
model = "generic"
params = { A = [[-1.0, 0.0], [0.0, -1.0]], B1 = [[3.0, 2.0], [4.0, 5.0]], B2 = [[-0.1, 0.0], [0.0, 1.0]], C = [[1.0, 2.0], [3.0, 4.0]] }
x0 = [[0.0, 0.0]]
[graph]
edges = []
pinning = [[1, 1.0]]
{coupling}
[disturbance]
K = [[-5.0, 1.0], [-1.0, -9.0]]
W_w = 2.0
w0 = [0.3, 0.4]
[noise]
convention = "intensity"
process = 2.0
position = 2.0
reference = 2.0
[cost]
Q = 1.0
R = 1.0
"""
ZERO_COUPLING = "coupling = [[0.0, 0.0], [0.0, 0.0]]"


def paper_fleet(coupling: str) -> str:
    return PAPER_FLEET.replace("{coupling}", coupling)


SYSTEM_KEYS = ("A", "B1", "B2", "Bz", "C", "F", "H", "K", "x0", "w0", "z0", "Q", "R",
               "W_x", "W_w", "W_z", "V_y", "V_ybar")


def test_paper_as_a_fleet_of_one_vehicle_is_the_paper(tmp_path):
    """The paper's single vehicle has no consensus coupling: with coupling = 0 the pinning
    term a_10 Gamma (T z - x) vanishes whatever a_10 > 0 is, and the N = 1 fleet is the
    paper's system exactly (no new feature needed: a_10 = 0 or an empty pinning stay refused,
    and need not be allowed)."""
    sc = _load_text(tmp_path, paper_fleet(ZERO_COUPLING),
                    "paper1")
    paper = load_scenario("paper")
    for k in SYSTEM_KEYS:
        a, b = getattr(sc.system, k), getattr(paper.system, k)
        assert a.shape == b.shape and np.array_equal(a, b), k
    assert sc.system.noise_convention == paper.system.noise_convention
    assert (sc.T, sc.h, sc.estimator, sc.tracking) == (paper.T, paper.h, paper.estimator, paper.tracking)


def test_paper_as_a_fleet_with_the_default_coupling_is_not_the_paper(tmp_path):
    """Gamma = I (the default) pins the vehicle to the leader inside its dynamics:
    A = A_11 - a_10 I and Bz = a_10 C^-1 H: a different (also valid) system."""
    sc = _load_text(tmp_path, paper_fleet("").replace("[graph]", '[graph]\nconsensus = "in-plant"'),
                    "paper2")
    A = np.array([[-1.0, 0.0], [0.0, -1.0]])
    C = np.array([[1.0, 2.0], [3.0, 4.0]])
    H = np.array([[0.2, 4.0], [2.0, 5.0]])
    np.testing.assert_allclose(sc.system.A, A - np.eye(2), atol=1e-15)
    np.testing.assert_allclose(sc.system.Bz, np.linalg.solve(C, H), atol=1e-13)


def test_paper_as_a_fleet_needs_a_pinned_vehicle(tmp_path):
    text = paper_fleet(ZERO_COUPLING)
    with pytest.raises(ScenarioError, match="no vehicle hears the leader"):
        _load_text(tmp_path, text.replace("pinning = [[1, 1.0]]", "pinning = []"), "paper3")


def test_paper_as_a_fleet_co_simulates_like_the_paper(tmp_path):
    """The fleet FMUs (fleet parameter interface, generic model, explicit disturbance and
    leader noise) run the paper's loop: equal to the paper's monolithic reference."""
    # in-plant: one noise stream for the stacked system, as the paper's plant draws it
    sc = _load_text(tmp_path, paper_fleet(ZERO_COUPLING).replace(
        "[graph]", '[graph]\nconsensus = "in-plant"'), "paper4")
    paper = load_scenario("paper")
    fmus = build(sc, tmp_path / "fmus")
    steps = 1500
    res = run_cosimulation(fmus, scenario_config(sc), mode="kalman", seed=3, steps=steps)
    ref = run_monolithic(paper.system, paper.h, "kalman", 3, steps)
    worst = max(float(np.max(np.abs(res.traces[k] - ref[k]))) for k in ref)
    assert worst < 1e-9, worst
    assert np.std(ref["e"][:, 0]) > 0.1


def test_per_vehicle_noise_and_cost_overrides(tmp_path):
    """[[vehicles.overrides]] noise and cost change only that vehicle's blocks."""
    from plant_model.fleet import fleet_system
    text = (SCENARIO_DIR / "formation-4.toml").read_text().replace(
        "[graph]", "overrides = [{ vehicle = 3, noise = { position = 4.0 }, cost = { R = 0.5 } }]\n\n[graph]", 1)
    path = tmp_path / "f4_override.toml"
    path.write_text(text)
    sc = load_scenario(path)
    V = np.diag(sc.system.V_y).reshape(4, 3)
    R = np.diag(sc.system.R).reshape(4, 3)
    assert V[2].tolist() == [4.0] * 3 and V[[0, 1, 3]].ravel().tolist() == [0.25] * 9
    assert R[2].tolist() == [0.5] * 3 and R[[0, 1, 3]].ravel().tolist() == [0.01] * 9
    np.testing.assert_array_equal(fleet_system(sc.fleet.spec).V_y, sc.system.V_y)
    bad = tmp_path / "f4_bad.toml"
    bad.write_text(text.replace("position = 4.0", "positon = 4.0"))
    with pytest.raises(ScenarioError, match="vehicle 3.*positon"):
        load_scenario(bad)
