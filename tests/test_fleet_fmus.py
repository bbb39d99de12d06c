"""FMUs built for a fleet: a small, meaningful parameter interface that the host can set."""
from __future__ import annotations

import copy
import re
from dataclasses import replace

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from orchestrator.analysis.reference import run_monolithic
from orchestrator.running import build, scenario_config
from orchestrator.scenario import scenario_from_dict
from orchestrator.scenario.generator import grid_fleet
from plant_model.fleet import fleet_system
from plant_model.fleet_model import Fleet
from support.loop import run_cosimulation


@pytest.fixture(scope="module")
def f4(formation4):
    return formation4


@pytest.fixture(scope="module")
def fmus(formation4_fmus):
    return formation4_fmus


def _params(fmu) -> set[str]:
    md = read_model_description(str(fmu))
    return {v.name for v in md.modelVariables if v.causality == "parameter"}


@pytest.mark.parametrize("kind", ["plant", "estimator", "controller"])
def test_fmpy_validate_reports_no_problem(fmus, kind):
    assert validate_fmu(str(fmus[kind])) == []


def test_parameters_are_per_vehicle_graph_and_leader_quantities(fmus):
    plant, est, ctrl = (_params(fmus[k]) for k in ("plant", "estimator", "controller"))
    for names in (plant, est, ctrl):
        assert {"vehicle[1].mass", "vehicle[4].added_mass[3]", "vehicle[2].time_constant[1]",
                "vehicle[3].offset[2]", "a[2,1]", "a[4,3]", "a0[1]", "coupling[4,1]",
                "leader.F[5,6]", "vehicle[2].current.time_constant"} <= names
        # edges that do not exist are not parameters; vehicles 2..4 are not pinned
        assert "a[1,2]" not in names and "a0[2]" not in names
        # no stacked matrix entries
        assert not any(re.fullmatch(r"(A|B1|B2|Bz|C|F|H|K)\[\d+,\d+\]", n) for n in names)
    # each FMU exposes what its mathematics reads
    assert "vehicle[1].x0[1]" in plant and "vehicle[1].x0[1]" not in ctrl
    assert "vehicle[1].V_y" in est and "vehicle[1].V_y" not in ctrl
    assert "vehicle[1].R" in ctrl and "vehicle[1].R" not in plant
    assert "vehicle[1].current.sigma" in plant and "vehicle[1].current.sigma" not in ctrl


@pytest.mark.slow
def test_parameter_count_grows_linearly_with_the_fleet(tmp_path):
    counts = {}
    for N in (2, 6, 10):
        sc = scenario_from_dict(grid_fleet(N, T=1.0), f"grid {N}")
        fm = build(sc, tmp_path / f"n{N}")
        counts[N] = len(_params(fm["controller"]))
    per_vehicle_a = (counts[6] - counts[2]) / 4
    per_vehicle_b = (counts[10] - counts[6]) / 4
    # a constant number of parameters per vehicle (model, offset, current, Q, R, about
    # two edges); the stacked matrices would add (6 N)^2 entries
    assert per_vehicle_a == pytest.approx(per_vehicle_b, abs=1.0)
    assert per_vehicle_a < 40


def test_parameters_set_by_the_host_are_used(f4, fmus):
    """FMUs built for formation-4; the host changes a graph weight, a mass, an offset and
    the tracking law: the co-simulation equals the monolithic loop of the changed fleet."""
    spec = copy.deepcopy(dict(f4.fleet.spec))
    spec["graph"]["edges"][0][2] = 2.0                      # a[2,1]
    spec["vehicles"][2]["params"]["mass"] = 40.0
    spec["vehicles"][0]["offset"][1] = 5.0
    changed = replace(f4, fleet=Fleet.of(spec), system=fleet_system(spec), tracking="lq")
    cfg = scenario_config(changed)
    assert cfg["fleet"]["graph"]["edges"][0][2] == 2.0
    steps = 500
    res = run_cosimulation(fmus, cfg, mode="kalman", seed=3, steps=steps, tracking="lq")
    ref = run_monolithic(changed.system, f4.h, "kalman", 3, steps, "lq")
    for key in ("x", "u", "xhat", "e"):
        np.testing.assert_allclose(res.traces[key], ref[key], rtol=0, atol=1e-9, err_msg=key)
    base = run_monolithic(f4.system, f4.h, "kalman", 3, steps, "lq")
    assert not np.allclose(base["u"], ref["u"])
