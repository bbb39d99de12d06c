"""Simulated cost rates and RMS values agree with the Lyapunov prediction (paper scenario)."""
from __future__ import annotations

import json
import math

import pytest

from orchestrator.running import simulate
from orchestrator.scenario import load_scenario
from support.fmus import LONG_RUN_FMUS


@pytest.mark.slow
def test_compare_on_ten_seeds_agrees_with_prediction(tmp_path):
    sc = load_scenario("paper").with_run(fmus=LONG_RUN_FMUS)
    summary = simulate(sc, ["kalman", "classical", "ideal"], list(range(10)), tmp_path,
                       progress=False, log=lambda s: None)
    assert json.loads((tmp_path / "summary.json").read_text())["methods"].keys() == summary["methods"].keys()
    for name, m in summary["methods"].items():
        c = m["cost_rate"]
        se = c["std"] / math.sqrt(len(c["per_seed"]))
        assert abs(c["mean"] - c["predicted"]) < 4 * se + 1e-3 * c["predicted"], (name, c)
        for key in ("rms_e", "rms_u"):
            for mean, std, pred in zip(m[key]["mean"], m[key]["std"], m[key]["predicted"]):
                assert abs(mean - pred) < 4 * std / math.sqrt(10) + 1e-3 * pred, (name, key)
    costs = {k: v["cost_rate"]["mean"] for k, v in summary["methods"].items()}
    # the paper's claim, and the ideal bound
    assert costs["ideal"] < costs["kalman"] < costs["classical"]
