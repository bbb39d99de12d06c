"""orchestrator.scenario: the TOML loader and the built-in paper scenario.

Bad files are written to tmp_path from the built-in paper.toml with one change each.
"""
from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from estimator_fmu.registry import ESTIMATOR_MODES
from orchestrator.scenario import (
    SCENARIO_DIR,
    Scenario,
    ScenarioError,
    builtin_scenarios,
    load_scenario,
    scenario_from_dict,
)
from orchestrator.scenario.generator import scenario_toml as dump_toml
from plant_model.system import MATRIX_NAMES

PAPER_TOML = SCENARIO_DIR / "paper.toml"


def paper_dict() -> dict:
    return tomllib.loads(PAPER_TOML.read_text())


@pytest.fixture
def write(tmp_path):
    """write(change) -> path of paper.toml with ``change(data)`` applied."""
    def _write(change, name="case.toml"):
        data = paper_dict()
        change(data)
        path = tmp_path / name
        path.write_text(dump_toml(data))
        return path
    return _write


def load_error(path) -> str:
    with pytest.raises(ScenarioError) as exc:
        load_scenario(path)
    msg = str(exc.value)
    assert str(path) in msg, msg            # every message names the file
    return msg


# the built-in scenario --------------------------------------------------------------
def test_builtin_list_contains_paper():
    assert "paper" in builtin_scenarios()


def test_paper_scenario_matches_notes(paper_mapping):
    """paper.toml against the matrices typed in from docs/theory.md section 9 (conftest.py)."""
    sc = load_scenario("paper")
    assert isinstance(sc, Scenario)
    assert sc.name == "paper"
    assert sc.T == 300.0 and sc.h == 0.01 and sc.seed == 0 and sc.estimator == "kalman"
    assert sc.steps == 30_000
    assert sc.source == "built-in scenario 'paper'"
    for name in MATRIX_NAMES + ("x0", "w0", "z0"):
        np.testing.assert_array_equal(getattr(sc.system, name), np.array(paper_mapping[name]),
                                      err_msg=name)
    assert sc.system.noise_convention == "intensity"


def test_default_argument_is_paper():
    a, b = load_scenario(), load_scenario("paper")
    np.testing.assert_array_equal(a.system.B1, b.system.B1)
    assert a.T == b.T


def test_round_trip_through_a_file_by_str_and_path(write):
    path = write(lambda d: None)
    for spec in (path, str(path)):
        sc = load_scenario(spec)
        assert sc.source == str(path)
        ref = load_scenario("paper")
        for name in MATRIX_NAMES:
            np.testing.assert_array_equal(getattr(sc.system, name), getattr(ref.system, name))


def test_name_defaults_to_the_file_stem(write):
    path = write(lambda d: d.pop("name"), name="my_case.toml")
    assert load_scenario(path).name == "my_case"


def test_optional_sections_and_keys_take_defaults(write):
    def change(d):
        del d["noise"], d["cost"]
        del d["simulation"]["seed"], d["simulation"]["estimator"]
        del d["vehicles"]["x0"], d["reference"]["z0"], d["disturbance"]["w0"]
    sc = load_scenario(write(change))
    s = sc.system
    assert sc.seed == 0 and sc.estimator == "kalman"
    np.testing.assert_array_equal(s.Q, np.eye(2))
    np.testing.assert_array_equal(s.R, np.eye(2))
    assert not np.any(s.W_x) and not np.any(s.V_ybar)
    np.testing.assert_array_equal(s.initial_state(), np.zeros(6))


def test_noise_convention_and_matrices_are_read(write):
    def change(d):
        d["noise"]["convention"] = "per_sample"
        d["noise"]["W_x"] = [[2.0, 0.5], [0.5, 1.0]]
        d["cost"]["R"] = 0.5
    s = load_scenario(write(change)).system
    assert s.noise_convention == "per_sample"
    np.testing.assert_array_equal(s.W_x, [[2.0, 0.5], [0.5, 1.0]])
    np.testing.assert_array_equal(s.R, 0.5 * np.eye(2))


@pytest.mark.parametrize("mode", ESTIMATOR_MODES)
def test_every_estimator_mode_is_accepted(write, mode):
    assert load_scenario(write(lambda d: d["simulation"].update(estimator=mode))).estimator == mode


def test_integer_numbers_are_accepted(write):
    def change(d):
        d["simulation"]["T"] = 10
        d["vehicles"]["A"] = [[-1, 0], [0, -1]]
    sc = load_scenario(write(change))
    assert sc.T == 10.0 and isinstance(sc.T, float)
    np.testing.assert_array_equal(sc.system.A, -np.eye(2))


def test_with_run_overrides_and_checks():
    sc = load_scenario("paper")
    sc2 = sc.with_run(T=1.0, h=0.1, seed=3, estimator="classical")
    assert (sc2.T, sc2.h, sc2.seed, sc2.estimator, sc2.steps) == (1.0, 0.1, 3, "classical", 10)
    assert sc.T == 300.0                                # the original is unchanged
    with pytest.raises(ScenarioError, match=r"\[simulation\] h = -1\.0"):
        sc.with_run(h=-1.0)
    with pytest.raises(ScenarioError, match=r"\[simulation\] T = 0\.001 must be at least one step"):
        sc.with_run(T=0.001)
    with pytest.raises(ScenarioError, match=r"estimator 'ekf' is unknown"):
        sc.with_run(estimator="ekf")


# file-level problems ------------------------------------------------------------------
def test_missing_file(tmp_path):
    path = tmp_path / "nope.toml"
    with pytest.raises(ScenarioError, match=r"scenario file .*nope\.toml does not exist"):
        load_scenario(path)


def test_unknown_builtin_name_lists_the_builtins():
    with pytest.raises(ScenarioError) as exc:
        load_scenario("no_such_scenario")
    msg = str(exc.value)
    assert "unknown scenario 'no_such_scenario'" in msg and "paper" in msg


def test_invalid_toml(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(PAPER_TOML.read_text().replace("T = 300.0", "T = = 300.0"))
    assert "not valid TOML" in load_error(path)


# one change each: structure -------------------------------------------------------------
def test_unknown_section(write):
    msg = load_error(write(lambda d: d.update(plant={"A": 1.0})))
    assert "unknown section(s) or key(s): plant" in msg


def test_unknown_top_level_key(write):
    msg = load_error(write(lambda d: d.update(seed=3)))
    assert "unknown section(s) or key(s): seed" in msg


@pytest.mark.parametrize("section, key", [
    ("simulation", "dt"), ("vehicles", "G"), ("disturbance", "w_0"), ("reference", "z1"),
    ("noise", "W_y"), ("cost", "S"),
])
def test_unknown_key_in_section(write, section, key):
    msg = load_error(write(lambda d: d[section].update({key: 1.0})))
    assert f"unknown key(s) in [{section}]: {key}" in msg and "allowed:" in msg, msg


@pytest.mark.parametrize("section, key", [
    ("simulation", "T"), ("simulation", "h"), ("vehicles", "A"), ("vehicles", "B1"),
    ("vehicles", "B2"), ("vehicles", "C"), ("disturbance", "K"), ("reference", "F"),
    ("reference", "H"),
])
def test_missing_required_key(write, section, key):
    msg = load_error(write(lambda d: d[section].pop(key)))
    assert f"missing key(s) in [{section}]: {key}" in msg, msg


@pytest.mark.parametrize("section, keys", [
    ("simulation", "T, h"), ("vehicles", "A, B1, B2, C"), ("disturbance", "K"),
    ("reference", "F, H"),
])
def test_missing_required_section(write, section, keys):
    msg = load_error(write(lambda d: d.pop(section)))
    assert f"missing key(s) in [{section}]: {keys}" in msg, msg


def test_section_that_is_not_a_table(write):
    msg = load_error(write(lambda d: d.update(cost=1.0)))
    assert "[cost] must be a table" in msg


# one change each: run settings -------------------------------------------------------
@pytest.mark.parametrize("h", [0.0, -0.01, "0.01", float("nan"), float("inf")])
def test_bad_step(write, h):
    msg = load_error(write(lambda d: d["simulation"].update(h=h)))
    assert f"[simulation] h = {h!r} must be a positive number of seconds" in msg, msg


@pytest.mark.parametrize("T", [0.005, 0.0, -1.0, float("inf"), float("nan"), "300"])
def test_horizon_shorter_than_one_step(write, T):
    msg = load_error(write(lambda d: d["simulation"].update(T=T)))
    assert f"[simulation] T = {T!r} must be at least one step h = 0.01 s" in msg, msg


def test_horizon_of_exactly_one_step_is_fine(write):
    assert load_scenario(write(lambda d: d["simulation"].update(T=0.01))).steps == 1


@pytest.mark.parametrize("seed", [-1, 1.5, "0"])
def test_bad_seed(write, seed):
    msg = load_error(write(lambda d: d["simulation"].update(seed=seed)))
    assert f"[simulation] seed = {seed!r} must be a non-negative integer" in msg, msg


@pytest.mark.parametrize("est", ["ekf", "Kalman", ""])
def test_unknown_estimator(write, est):
    msg = load_error(write(lambda d: d["simulation"].update(estimator=est)))
    assert f"[simulation] estimator {est!r} is unknown" in msg, msg
    assert ", ".join(ESTIMATOR_MODES) in msg


# one change each: the model (errors from LinearSystem, with their section) -----------------
@pytest.mark.parametrize("section, key, value, expect", [
    ("vehicles", "A", [[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]], "A: wrong shape 2x3, expected 2x2"),
    ("vehicles", "B1", [[3.0, 2.0], [4.0, 5.0], [1.0, 1.0]], "B1: wrong shape 3x2, expected 2x?"),
    ("vehicles", "B2", [[1.0], [2.0], [3.0]], "B2: wrong shape 3x1, expected 2x?"),
    ("vehicles", "C", [[1.0, 2.0, 3.0]], "C: wrong shape 1x3, expected ?x2"),
    ("vehicles", "x0", [0.0, 0.0, 0.0], "x0: wrong length 3, expected 2"),
    ("disturbance", "K", [[-5.0]], "K: wrong shape 1x1, expected 2x2"),
    ("disturbance", "w0", [0.3], "w0: wrong length 1, expected 2"),
    ("reference", "F", [[-0.1, 1.0]], "F: wrong shape 1x2, expected 1x1"),
    ("reference", "H", [[0.2, 4.0, 1.0], [2.0, 5.0, 1.0]], "H: wrong shape 2x3, expected 2x2"),
    ("reference", "z0", [0.4], "z0: wrong length 1, expected 2"),
    ("cost", "Q", [[1.0, 0.0, 0.0]], "Q: wrong shape 1x3, expected 2x2"),
    ("noise", "V_y", [[2.0]], "V_y: wrong shape 1x1, expected 2x2"),
])
def test_wrong_shape(write, section, key, value, expect):
    msg = load_error(write(lambda d: d[section].update({key: value})))
    assert f"[{section}] {expect}" in msg, msg


@pytest.mark.parametrize("section, key, value, expect", [
    ("vehicles", "A", [[float("nan"), 0.0], [0.0, -1.0]], "A[1,1] = nan is not finite"),
    ("vehicles", "B1", [[3.0, float("inf")], [4.0, 5.0]], "B1[1,2] = inf is not finite"),
    ("reference", "z0", [0.4, float("-inf")], "z0[2] = -inf is not finite"),
    ("cost", "Q", float("nan"), "Q = nan is not finite"),
    ("noise", "W_z", float("inf"), "W_z = inf is not finite"),
])
def test_non_finite_entry(write, section, key, value, expect):
    msg = load_error(write(lambda d: d[section].update({key: value})))
    assert f"[{section}] {expect}" in msg, msg


@pytest.mark.parametrize("key, value", [
    ("Q", 0.0), ("Q", [[1.0, 0.0], [0.0, -1.0]]), ("R", -1.0), ("R", [[1.0, 2.0], [2.0, 1.0]]),
])
def test_cost_weights_not_positive_definite(write, key, value):
    msg = load_error(write(lambda d: d["cost"].update({key: value})))
    assert f"[cost] {key} must be positive definite" in msg, msg


@pytest.mark.parametrize("key", ["W_x", "W_w", "W_z", "V_y", "V_ybar"])
def test_negative_noise(write, key):
    msg = load_error(write(lambda d: d["noise"].update({key: -2.0})))
    assert f"[noise] {key} must be positive semidefinite" in msg, msg


@pytest.mark.parametrize("key", ["W_x", "V_ybar"])
def test_asymmetric_noise(write, key):
    msg = load_error(write(lambda d: d["noise"].update({key: [[2.0, 1.0], [0.0, 2.0]]})))
    assert f"[noise] {key} is not symmetric" in msg, msg


def test_unknown_noise_convention(write):
    msg = load_error(write(lambda d: d["noise"].update(convention="psd")))
    assert "[noise]" in msg and "'psd'" in msg and "intensity, per_sample" in msg, msg


def test_non_numeric_matrix(write):
    msg = load_error(write(lambda d: d["vehicles"].update(C=[["a", "b"], ["c", "d"]])))
    assert "[vehicles] C: not a numeric matrix" in msg, msg


def test_scenario_from_dict_names_the_source():
    data = paper_dict()
    data["simulation"]["h"] = 0
    with pytest.raises(ScenarioError, match=r"^my source: \[simulation\] h = 0"):
        scenario_from_dict(data, "my source")


def test_default_source_name():
    data = paper_dict()
    data["vehicles"]["A"] = [[1.0, 2.0]]
    with pytest.raises(ScenarioError, match=r"^scenario: \[vehicles\] A"):
        scenario_from_dict(data)


def test_scenario_dir_is_inside_the_package():
    assert SCENARIO_DIR.is_dir() and (SCENARIO_DIR / "paper.toml").is_file()
    import orchestrator
    assert Path(orchestrator.__file__).parent in Path(SCENARIO_DIR).parents


@pytest.mark.parametrize("key, value", [("seed", "true"), ("h", "true"), ("T", "true")])
def test_booleans_are_not_numbers(tmp_path, key, value):
    from orchestrator.scenario import SCENARIO_DIR, ScenarioError, load_scenario
    text = (SCENARIO_DIR / "paper.toml").read_text()
    lines = [f"{key} = {value}" if ln.split("=")[0].strip() == key and not ln.startswith("#") else ln
             for ln in text.splitlines()]
    p = tmp_path / "bool.toml"
    p.write_text("\n".join(lines))
    with pytest.raises(ScenarioError, match=rf"\[simulation\] {key} = True"):
        load_scenario(p)
