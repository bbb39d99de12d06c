"""The generated grid fleets and the built-in formation-20 scenario."""
from __future__ import annotations

import tomllib

import numpy as np
import pytest

from orchestrator.scenario import SCENARIO_DIR, load_scenario, scenario_from_dict
from orchestrator.scenario.generator import grid_fleet, scenario_toml


def test_formation_20_file_matches_the_generator():
    shipped = tomllib.loads((SCENARIO_DIR / "formation-20.toml").read_text())
    assert shipped == tomllib.loads(scenario_toml(grid_fleet(20, name="formation-20")))


@pytest.mark.parametrize("N", [1, 2, 5, 7, 20, 50])
def test_every_generated_vehicle_hears_the_leader_through_the_graph(N):
    sc = scenario_from_dict(grid_fleet(N), f"grid {N}")
    g = sc.fleet.graph
    assert len(g.pinning) == 1
    # L + G of a graph where every vehicle has a path from the leader is nonsingular
    # with eigenvalues in the open right half-plane
    assert np.min(np.linalg.eigvals(g.consensus_matrix()).real) > 0
    assert sc.system.dims == {"n": 6 * N, "m": 3 * N, "r": 3 * N, "p": 3 * N,
                              "l": sc.system.l}


def test_grid_offsets_are_distinct_and_the_front_centre_is_pinned():
    d = grid_fleet(20)
    offsets = np.array(d["vehicles"]["offsets"])
    assert len({tuple(o) for o in offsets.tolist()}) == 20
    (pinned, _), = d["graph"]["pinning"]
    assert offsets[pinned - 1].tolist() == [0.0, 0.0, 0.0]


def test_formation_20_loads_with_20_remus_vehicles():
    sc = load_scenario("formation-20")
    assert sc.fleet.N == 20
    assert set(sc.fleet.model_names) == {"remus100"}
    assert sc.tracking == "regulator"


def test_formation_100_file_matches_the_generator():
    from orchestrator.scenario.generator import survey_grid_fleet
    shipped = tomllib.loads((SCENARIO_DIR / "formation-100.toml").read_text())
    assert shipped == tomllib.loads(scenario_toml(survey_grid_fleet(100, name="formation-100")))


def test_formation_100_hears_at_most_four_nearer_neighbours():
    sc = load_scenario("formation-100")
    assert (sc.deployment, sc.architecture) == ("per-vehicle", "distributed")
    g = sc.fleet.graph
    pinned = {i for i, _ in g.pinning}
    assert pinned == set(range(1, 11))                     # the front row
    heard: dict[int, list[int]] = {}
    for j, i, _ in g.edges:
        heard.setdefault(int(i), []).append(int(j))
    assert max(len(v) for v in heard.values()) == 4
    # every neighbour is in a row nearer the leader (row = (k - 1) // 10)
    assert all((j - 1) // 10 < (i - 1) // 10 for i, js in heard.items() for j in js)
    assert set(heard) | pinned == set(range(1, 101))


def test_the_shipped_circle_20_remus_is_the_generated_remus_fleet():
    """circle-20-remus is formation-20's grid (20 m apart) put on the nonlinear REMUS by
    on_remus: the model, its sensors, the leader at 2 m/s, the [design] weight, no R."""
    from orchestrator.scenario.generator import on_remus
    shipped = tomllib.loads((SCENARIO_DIR / "circle-20-remus.toml").read_text())
    made = on_remus(grid_fleet(20, spacing=20.0, T=300.0), name="circle-20-remus")
    assert shipped == tomllib.loads(scenario_toml(made))
    assert shipped["vehicles"]["model"] == "remus100-6dof" and "R" not in shipped["cost"]
    assert shipped["sensors"] == {"kind": "remus"} and shipped["design"]["bandwidth"] == 0.2
