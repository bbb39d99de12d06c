"""Physical bounds and typed numbers: impossible vehicle data, currents, leader speeds and
turns, network timing and sensor cycles are refused by the real command in one line naming
the key (and vehicle), the value with its unit and the bound, before anything is built or
written; a bad envelope grid point fails alone."""
from __future__ import annotations

import json
import math
import re
import time
from pathlib import Path

import pytest

from orchestrator.cli import main
from orchestrator.exit_status import POINTS_FAILED
from orchestrator.scenario import SCENARIO_DIR
from plant_model.acoustic.base import MAX_MESSAGE_CYCLE_STEPS
from plant_model.acoustic.links import MAX_IN_FLIGHT
from plant_model.fleet import MAX_CURRENT_SPEED
from plant_model.leader import MAX_LEADER_SPEED
from plant_model.linalg_checks import ModelError
from plant_model.navigation import MAX_SENSOR_CYCLE_STEPS
from plant_model.remus100.dynamics import REMUS_BOUNDS, Remus100
from plant_model.remus100.models import REMUS_FIELDS, remus_from_parameters
from tests.support.cli import assert_one_line_error

SURVEY = (SCENARIO_DIR / "survey-4-remus.toml").read_text()
LINKS = (SCENARIO_DIR / "formation-4-links.toml").read_text()
FORMATION = (SCENARIO_DIR / "formation-4.toml").read_text()


def _file(tmp_path: Path, text: str, name: str = "bad.toml") -> str:
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def _refused(capsys, tmp_path: Path, text: str, *fragments: str) -> None:
    """``run`` on the scenario ``text`` exits 2 with one line holding every fragment, and
    writes nothing into --out."""
    out = tmp_path / "out"
    assert_one_line_error(capsys, ["run", "--scenario", _file(tmp_path, text), "--T", "1",
                                   "--quiet", "--out", str(out)], *fragments)
    assert not out.exists()


def _override(params: str) -> str:
    """survey-4-remus with vehicle 3's params overridden (inline TOML table)."""
    return SURVEY + f"\n[[vehicles.overrides]]\nvehicle = 3\nparams = {params}\n"


# --------------------------------------------------------------- vehicle data
@pytest.mark.parametrize("params, fragments", [
    ("{ thrust_deduction = 1.5 }",
     ("[vehicles] vehicle 3: remus100-6dof: thrust_deduction = 1.5 must be in [0, 1)",)),
    ("{ zeta_roll = -2.0 }",
     ("vehicle 3: remus100-6dof: zeta_roll = -2 must be non-negative", "relative damping")),
    ("{ delta_max = 2.0 }",
     ("vehicle 3: remus100-6dof: delta_max = 2 rad (115 deg) must be in (0, 90) deg",)),
    ("{ wake_factor = 0.0 }", ("vehicle 3: remus100-6dof: wake_factor = 0 must be in (0, 1]",)),
    ("{ T_n = 0.0 }", ("vehicle 3: remus100-6dof: T_n = 0 s must be positive",)),
    ("{ CL_stern = -0.7 }", ("CL_stern = -0.7 1/rad must be positive",)),
    ("{ n_max = \"fast\" }", ("[vehicles] vehicle 3: n_max: not a number: 'fast'",)),
    ("{ n_max = \"1525\" }",
     ("[vehicles] vehicle 3: n_max: not a number: '1525' (text: write numbers without quotes)",)),
    ("{ r_g = [0.0, 0.0, \"0.02\"] }", ("vehicle 3: r_g: not a numeric vector: '0.02' is text",)),
    ("{ autopilot = { K_u = \"300\" } }", ("vehicle 3: autopilot.K_u: not a number: '300'",)),
    ("{ autopilot = { delta_max = 3.0 } }",
     ("vehicle 3: autopilot.delta_max = 3 rad (172 deg) must be in (0, 90) deg",)),
])
def test_impossible_or_mistyped_remus_data_is_one_line(capsys, tmp_path, params, fragments):
    _refused(capsys, tmp_path, _override(params), *fragments)


@pytest.mark.parametrize("old, new, fragments", [
    ("params = { cruise_speed = 1.5 }", "params = { mass = \"31\" }",
     ("[vehicles] vehicle 1: mass: not a number: '31'",)),
    ("params = { cruise_speed = 1.5 }", "params = { time_constant = [\"20\", 20, 20] }",
     ("vehicle 1: time_constant[1]: not a number: '20'",)),
    ("[ 10.0,   0.0,  0.0],", "[ \"10\",   0.0,  0.0],",
     ("[vehicles] offsets must have one row per vehicle (4 rows of 3) of numbers; '10' is text",)),
    ("pinning = [[1, 1.0]]", "pinning = [[1, \"1.0\"]]", ("weight '1.0' is not a number",)),
    ("sigma = 0.1          # m/s", "sigma = 1e6 #",
     ("[current] sigma = 1000000.0 m/s must be in [0, 10] m/s",)),
    ("w0 = [0.1, -0.05, 0.0]", "w0 = [20.0, -0.05, 0.0]",
     ("[current] w0[1] = 20 m/s is beyond +-10 m/s",)),
    ("speed = 1.5          # m/s, nominal survey speed", "speed = 1e300",
     ("[leader] speed = 1e+300 m/s must be in [0, 100] m/s",)),
])
def test_linear_fleet_data_is_typed_and_bounded(capsys, tmp_path, old, new, fragments):
    assert old in FORMATION
    _refused(capsys, tmp_path, FORMATION.replace(old, new), *fragments)


def test_every_remus_field_has_its_bound_and_the_published_data_keeps_them():
    scalar = set(REMUS_FIELDS) - {"published_crossflow"}
    assert set(REMUS_BOUNDS) == scalar
    v = Remus100()
    for name, bound in REMUS_BOUNDS.items():
        assert bound.holds(getattr(v, name)), name
    # the FMU's parameters take the same path (remus_from_parameters)
    with pytest.raises(ModelError, match=re.escape("thrust_deduction = 1.5 must be in [0, 1)")):
        remus_from_parameters({"thrust_deduction": 1.5})
    with pytest.raises(ModelError, match=re.escape("n_max: not a number: '1525'")):
        remus_from_parameters({"n_max": "1525"})


# --------------------------------------------------------------- network timing
def test_a_message_period_below_the_step_is_refused(capsys, tmp_path):
    """Was a ZeroDivisionError ("internal error"): 1e-12 s passed as 0 steps."""
    _refused(capsys, tmp_path, LINKS.replace("period = 2.0 ", "period = 1e-12 "),
             "[network]: period = 1e-12 s is below one step h = 0.01 s")
    out = tmp_path / "o"
    assert_one_line_error(capsys, ["run", "--scenario", "formation-4-links", "--period", "1e-12",
                                   "--T", "1", "--quiet", "--out", str(out)],
                          "period = 1e-12 s is below one step h = 0.01 s")
    table = LINKS + "schedule = [{t = 0.0, down = []}]\nschedule_period = 1e-12\n"
    _refused(capsys, tmp_path, table, "[network] schedule_period = 1e-12 s is below one step")
    assert not out.exists()


def test_a_latency_of_more_messages_than_a_link_holds_is_refused_at_once(capsys, tmp_path):
    """Was a MemoryError after 35 s (one state per message in flight)."""
    start = time.perf_counter()
    _refused(capsys, tmp_path, LINKS.replace("latency = 1.0 ", "latency = 1e9 "),
             "[network]: latency = 1e+09 s is 5e+08 periods of 2 s",
             f"at most {MAX_IN_FLIGHT} messages may be in flight on a link",
             f"latency at most {2 * MAX_IN_FLIGHT:g} s at this period")
    assert time.perf_counter() - start < 20


def test_link_periods_whose_cycle_is_too_long_are_refused(capsys, tmp_path):
    links = ("links = [{from = 1, to = 2, period = 1.01}, {from = 1, to = 3, period = 1.03},"
             " {from = 2, to = 4, period = 1.07}]\n")
    _refused(capsys, tmp_path, LINKS + links,
             "[network]: the periods 1.01 s, 1.03 s, 1.07 s, 2 s repeat together every "
             "222624200 steps", f"more than the {MAX_MESSAGE_CYCLE_STEPS} steps")


# --------------------------------------------------------------- sensor cycle
SENSORS = "kind = \"remus\"\nfix_period = 9.97\ndvl_period = 0.13\ndepth_period = 0.11\n"


def test_sensor_periods_whose_cycle_is_too_long_are_refused(capsys, tmp_path):
    """Was a MemoryError: the periodic filter and its prediction, one phase per step of a
    142,571-step cycle."""
    text = SURVEY.replace("kind = \"remus\"\n",
                          SENSORS + "fix_dropout = 0.0\ndvl_dropout = 0.0\n")
    _refused(capsys, tmp_path, text,
             "[sensors] fix_period = 9.97 s, dvl_period = 0.13 s, depth_period = 0.11 s "
             "report together every 142571 steps of h = 0.01 s",
             f"more than the {MAX_SENSOR_CYCLE_STEPS} steps")


def test_the_same_periods_with_dropouts_need_no_cycle():
    """With dropouts the filter is the steady one: no cycle to unroll, nothing refused."""
    from plant_model.navigation import NavigationSensors
    table = {"fix_period": 9.97, "dvl_period": 0.13, "depth_period": 0.11}
    assert NavigationSensors.from_mapping(table).steps(0.01).tolist() == [997, 13, 11]
    lossless = NavigationSensors.from_mapping(dict(table, fix_dropout=0.0, dvl_dropout=0.0))
    with pytest.raises(ModelError, match="report together every 142571 steps"):
        lossless.steps(0.01)


def test_a_new_step_rechecks_what_depends_on_it(capsys, tmp_path):
    """--h re-checks the leader's turns, the links' and the sensors' periods."""
    out = tmp_path / "o"
    assert_one_line_error(capsys, ["run", "--scenario", "formation-4-links", "--h", "0.03",
                                   "--T", "0.6", "--quiet", "--out", str(out)],
                          "built-in scenario 'formation-4-links': [network]: period = 2 s is "
                          "not a whole number of steps h = 0.03 s")
    sensed = FORMATION + "\n[sensors]\nkind = \"remus\"\n"
    assert_one_line_error(capsys, ["run", "--scenario", _file(tmp_path, sensed, "s.toml"),
                                   "--deployment", "per-vehicle", "--h", "0.03", "--T", "0.6",
                                   "--quiet", "--out", str(out)],
                          "s.toml: [sensors] fix_period = 2 s is not a whole number of steps "
                          "h = 0.03 s")
    text = FORMATION.replace("leg_length = 90.0", "leg_length = 90.0\n")
    circle = text.split("[leader]")[0] + (
        "[leader]\npath = \"circle\"\nradius = 1.0\nspeed = 1.0\ncenter = [0.0, 0.0, 20.0]\n"
        "noise = 0.0\n\n[vehicles]" + text.split("[vehicles]", 1)[1])
    path = _file(tmp_path, circle, "circle.toml")
    assert_one_line_error(capsys, ["run", "--scenario", path, "--h", "0.5", "--T", "1",
                                   "--quiet", "--out", str(out)],
                          "circle of radius 1 m", "turns at 1 rad/s, 0.5 rad per step h = 0.5 s",
                          "the radius must be at least 1.59 m")
    assert not out.exists()


# --------------------------------------------------------------- envelope
@pytest.mark.parametrize("flag, value, fragment", [
    ("--speeds", "1,1e300", f"speed = 1e+300 m/s must be in [0, {MAX_LEADER_SPEED:g}] m/s"),
    ("--currents", "1e6", f"current = 1e+06 m/s must be in [0, {MAX_CURRENT_SPEED:g}] m/s"),
])
def test_envelope_flags_are_bounded_before_anything_runs(capsys, tmp_path, flag, value,
                                                         fragment):
    for extra in (["--out", str(tmp_path / "e")], ["--write-spec", str(tmp_path / "s.toml")]):
        with pytest.raises(SystemExit) as exc:
            main(["envelope", "--scenario", "formation-4", "--deployment", "per-vehicle",
                  flag, value, *extra])
        assert exc.value.code == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert f"argument {flag}: '{value}': {fragment}" in err[-1], err
    assert not any(tmp_path.iterdir())


@pytest.mark.slow
def test_a_bad_grid_point_fails_alone_and_the_others_reach_the_summary(capsys, tmp_path):
    """Was: the radius 0.001 m stopped the grid with an error naming an eigenvalue, and the
    finished straight-line point reached no summary."""
    out = tmp_path / "env"
    assert main(["envelope", "--scenario", "formation-4", "--deployment", "per-vehicle",
                 "--T", "1", "--speeds", "1", "--radii", "inf,0.001,30", "--currents", "0.1",
                 "--out", str(out)]) == POINTS_FAILED
    printed = capsys.readouterr().out
    env = json.loads((out / "summary.json").read_text())["envelope"]
    straight, tiny, circle = env["points"]
    assert env["failed"] == 1 and straight["failed"] is None and circle["failed"] is None
    for p in (straight, circle):
        assert p["max_error"] > 0 and (out / p["folder"] / "summary.json").exists()
    assert tiny["radius"] == 0.001 and tiny["max_error"] is None and not tiny["holds"]
    assert "circle of radius 0.001 m" in tiny["failed"] and tiny["folder"] is None
    assert "the radius must be at least 0.0318 m" in tiny["failed"]
    assert "2/3 speed 1 m/s, radius 0.001 m, current 0.1 m/s: failed:" in printed
    assert "1 could not run (each one's reason in summary.json)" in printed
    assert sorted(p.name for p in (out / "points").iterdir()) == ["1", "3"]
    assert math.isfinite(straight["max_error"])
