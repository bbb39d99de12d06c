"""A fleet whose protocol is a force draws its noise per vehicle: vehicle i from the
generator seeded [seed, i], the leader from [seed, 0], each with its own block of the
sampled covariance. A vehicle's noise then does not depend on the rest of the fleet (what a
per-vehicle plant FMU needs to reproduce the stacked run)."""
from __future__ import annotations

import tomllib

import numpy as np
import pytest
from scipy.linalg import block_diag

from orchestrator.scenario import SCENARIO_DIR, load_scenario, scenario_from_dict
from plant_model.discretization import discretize
from plant_model.plant import NoiseStream


@pytest.fixture(scope="module")
def model():
    sc = load_scenario("formation-4")
    return discretize(sc.system, sc.h)


def test_blocks_cover_the_row_per_vehicle(model):
    blocks = model.noise_blocks
    assert len(blocks) == 5                                   # 4 vehicles and the leader
    assert sorted(i for b in blocks for i in b) == list(range(model.noise_dim))
    full = block_diag(model.Qd, model.Rd)
    for b in blocks:
        others = np.setdiff1d(np.arange(model.noise_dim), b)
        assert np.abs(full[np.ix_(b, others)]).max() == 0.0   # exactly independent


def test_a_vehicles_noise_is_its_own(model):
    """Vehicle 1 draws the same rows in a fleet of 4 and in a fleet of 3."""
    data = tomllib.loads((SCENARIO_DIR / "formation-4.toml").read_text())
    data["vehicles"]["count"] = 3
    data["vehicles"]["offsets"] = data["vehicles"]["offsets"][:3]
    data["vehicles"]["positions"] = data["vehicles"]["positions"][:3]
    data["graph"]["edges"] = [e for e in data["graph"]["edges"] if 4 not in e[:2]]
    small = scenario_from_dict(data, "three vehicles")
    m3 = discretize(small.system, small.h)
    rows4 = NoiseStream.all_rows(model, 11, 500)
    rows3 = NoiseStream.all_rows(m3, 11, 500)
    np.testing.assert_array_equal(rows4[:, model.noise_blocks[0]], rows3[:, m3.noise_blocks[0]])
    assert not np.array_equal(rows4[:, model.noise_blocks[1]], rows4[:, model.noise_blocks[0]])


def test_rows_have_the_sampled_covariance(model):
    rows = NoiseStream.all_rows(model, 5, 200_000)
    full = block_diag(model.Qd, model.Rd)
    emp = rows.T @ rows / rows.shape[0]
    d = np.sqrt(np.clip(np.diag(full), 1e-300, None))
    corr_err = np.abs(emp - full) / np.outer(d, d)
    live = np.diag(full) > 0
    assert corr_err[np.ix_(live, live)].max() < 0.02          # 200k samples: ~0.003 s.e.
    assert np.all(rows[:, ~live] == 0.0)


def test_the_stream_state_round_trips(model):
    s = NoiseStream(model, 3, block=64)
    s.next_rows(100)
    state = s.get_state()
    assert isinstance(state["bit_generator"], list) and len(state["bit_generator"]) == 5
    ahead = s.next_rows(200)
    t = NoiseStream(model, 99, block=64)
    t.set_state(state)
    np.testing.assert_array_equal(t.next_rows(200), ahead)
    np.testing.assert_array_equal(NoiseStream.all_rows(model, 3, 300)[100:], ahead)
    with pytest.raises(ValueError, match="holds 1 generator states, this stream has 5"):
        t.set_state(dict(state, bit_generator=state["bit_generator"][:1]))
