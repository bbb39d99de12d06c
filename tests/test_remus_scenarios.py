"""The built-in scenarios on the nonlinear REMUS 100 (survey-4-remus, circle-20-remus):
paths the vehicle can fly, a weight chosen from the vehicle, and (slow) the survey held."""
from __future__ import annotations

import json

import pytest

from orchestrator.scenario import load_scenario
from support.fmus import LONG_RUN_FMUS


@pytest.mark.parametrize("name", ["survey-4-remus", "circle-20-remus"])
def test_the_path_check_and_the_weight_comes_from_the_bandwidth(name):
    """Both paths pass the check: each file says path_check = "refuse" and loads with no
    finding. The bandwidth target sets
    R (the loop at 0.2 rad/s, to 1e-6), and the controllers clip at the vehicle's force:
    the drag of the design model at the simulated top speed (horizontal axes above 20 N)."""
    sc = load_scenario(name)
    d = sc.design
    assert sc.raw["design"]["path_check"] == "refuse"
    assert d.findings == [] and d.checked
    assert d.binding == "bandwidth" and d.bandwidth == pytest.approx(0.2, rel=1e-6)
    assert 0.5 < d.R < 5.0
    assert d.clip and all(u[0] > 20.0 and u[1] > 20.0 for u in d.u_max)
    assert sc.sensors.fix_period == 2.0           # the REMUS navigation sensors


@pytest.mark.slow
def test_the_survey_holds_on_its_straight_legs(tmp_path):
    """survey-4-remus, the whole 600 s on seed 1: after the transient (window from 150 s)
    the largest tracking error on straight legs is at most 3 m and its RMS at most 1.5 m
    (measured over seeds 0-3: at most 0.78 m, RMS at most 0.33 m)."""
    from orchestrator.cli import main
    out = tmp_path / "s4"
    assert main(["run", "--scenario", "survey-4-remus", "--seed", "1", "--out", str(out),
                 "--quiet", "--fmus", LONG_RUN_FMUS]) == 0
    m = json.loads((out / "summary.json").read_text())["methods"]["kalman"]
    assert m["max_error_straight"] <= 3.0 and m["rms_error_straight"] <= 1.5, m
