"""Formation figures: per-edge formation error RMS over the window and the closest approach
of two vehicles over the whole run, against plain loops and constructed cases."""
from __future__ import annotations

import itertools

import numpy as np
import pytest

from orchestrator.analysis.formation import formation_stats, formation_summary
from orchestrator.analysis.summary import run_stats
from orchestrator.running import fleet_layout
from support.loop import run_cosimulation


def test_a_constructed_formation():
    """Three vehicles in a line, offsets 10 m apart; vehicle 3 lags 3 m north during the
    window; vehicles 1 and 2 pass 0.5 m apart at step 300 (past the first block)."""
    steps, k0 = 600, 200
    offsets = np.array([[0.0, 0.0, 0.0], [0.0, 10.0, 0.0], [0.0, 20.0, 0.0]])
    x = np.zeros((steps, 9))
    idx = np.arange(9).reshape(3, 3)
    for i in range(3):
        x[:, idx[i]] = offsets[i]
    x[k0:, idx[2][0]] -= 3.0                                   # 3 m behind in the window
    x[300, idx[1]] = [0.0, 0.5, 0.0]                           # a close pass
    st = formation_stats(x, idx, offsets, [(1, 2), (2, 3)], k0, 0.01)
    # 2->3: 3 m at every window step, and (-3, 9.5) at the close pass of vehicle 2
    rms23 = np.sqrt((399 * 9.0 + 9.0 + 9.5 ** 2) / 400)
    assert st["formation_error_rms"]["2->3"] == pytest.approx(rms23, rel=1e-12)
    assert st["formation_error_rms"]["1->2"] == pytest.approx(np.sqrt(9.5 ** 2 / 400), rel=1e-12)
    assert st["formation_error_rms_max"] == pytest.approx(rms23)
    assert st["min_separation"] == pytest.approx(0.5)
    assert st["min_separation_vehicles"] == [1, 2] and st["min_separation_time_s"] == 3.0


def test_a_fleet_run_against_plain_loops(built_scenario):
    from orchestrator.scenario import load_scenario
    sc = load_scenario("formation-4")
    fmus, cfg = built_scenario("formation-4")
    layout = fleet_layout(sc)
    res = run_cosimulation(fmus, cfg, mode="kalman", seed=2, steps=700)
    k0 = 350
    st = run_stats(res.traces, sc.system.Q, sc.system.R, k0,
                   (layout.position_index, layout.offsets, layout.edges, sc.h))["formation"]
    x, pos, off = res.traces["x"], layout.position_index, layout.offsets
    for j, i in layout.edges:
        errs = [np.linalg.norm((x[k, pos[i - 1]] - x[k, pos[j - 1]]) - (off[i - 1] - off[j - 1]))
                for k in range(k0, 700)]
        assert st["formation_error_rms"][f"{j}->{i}"] == pytest.approx(
            np.sqrt(np.mean(np.square(errs))), rel=1e-12)
    best = min((np.linalg.norm(x[k, pos[a]] - x[k, pos[b]]), a, b, k)
               for k in range(700) for a, b in itertools.combinations(range(4), 2))
    assert st["min_separation"] == pytest.approx(best[0], rel=1e-12)
    assert st["min_separation_vehicles"] == [best[1] + 1, best[2] + 1]
    assert st["min_separation_time_s"] == pytest.approx(best[3] * sc.h)
    both = formation_summary([st, dict(st, min_separation=st["min_separation"] / 2)], [2, 9])
    assert both["min_separation"]["seed"] == 9
    assert both["formation_error_rms"] == st["formation_error_rms"]


def test_the_pruned_closest_approach_equals_every_pair_at_every_sample():
    """The block bound drops pairs; the value, pair and sample are those of the brute force
    (random walks of 12 vehicles, several near misses, a tie at two samples)."""
    rng = np.random.default_rng(5)
    steps, N = 1500, 12
    pos = np.cumsum(rng.normal(scale=0.3, size=(steps, N, 3)), axis=0)
    pos += rng.uniform(-40, 40, size=(1, N, 3))
    pos[700, 3] = pos[700, 8] + [0.05, 0.0, 0.0]         # near misses in different blocks
    pos[1200, 1] = pos[1200, 10] + [0.0, 0.03, 0.0]
    pos[1300, 2] = pos[1300, 5] + [0.0, 0.03, 0.0]       # the same distance later: not taken
    x = pos.reshape(steps, N * 3)
    index = np.arange(N * 3).reshape(N, 3)
    st = formation_stats(x, index, np.zeros((N, 3)), [], 0, 0.1)
    d = np.linalg.norm(pos[:, :, None] - pos[:, None, :], axis=3)
    d[:, np.tril(np.ones((N, N), bool))] = np.inf
    k, i, j = np.unravel_index(np.argmin(d), d.shape)
    assert st["min_separation"] == pytest.approx(d[k, i, j], rel=1e-12)
    assert st["min_separation_vehicles"] == [i + 1, j + 1] == [2, 11]
    assert st["min_separation_time_s"] == pytest.approx(k * 0.1) == pytest.approx(120.0)
