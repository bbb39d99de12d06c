"""A campaign over what a scenario says, through the one run step: formation-4 swept over
the deployment (stacked, per-vehicle) and the acoustic links' loss (0, 0.3). Every point and
seed gives one row; the stacked points with links are refused in one line each; every
per-vehicle row equals a plain `auv-cosim run` of that point; the run keys are distinct; a
campaign stopped by a real SIGINT and rerun neither duplicates nor loses a row."""
from __future__ import annotations

import json
import signal
import subprocess
import sys
import time

import pytest

from orchestrator.cli import main
from support.campaign import rows, without_timing

SPEC = """
base = "formation-4"
seeds = "0-1"
seeds_per_task = 1
[sweep]
"simulation.deployment" = ["stacked", "per-vehicle"]
"simulation.architecture" = ["distributed"]
"network.loss" = [0.0, 0.3]
"network.period" = [1.0]
"simulation.T" = [4.0]
"""


def _campaign(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "orchestrator", "campaign", *map(str, args)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.mark.slow
def test_a_sweep_of_deployment_and_loss_gives_every_row_equal_to_a_plain_run(tmp_path):
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC)
    out = tmp_path / "out"
    proc = _campaign(spec, "--workers", "2", "--out", out)
    deadline = time.monotonic() + 300
    while not ((out / "parts").exists() and list((out / "parts").glob("*.json"))):
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)                 # a real interruption mid-way
    proc.communicate(timeout=120)
    again = _campaign(spec, "--workers", "2", "--out", out)
    stdout, stderr = again.communicate(timeout=600)
    assert again.returncode == 3, stderr           # the 2 stacked points with links failed
    assert "auv-cosim campaign: 2 of 4 points failed (4 of 8 runs" in stderr
    table = rows(out)
    assert len(table) == 4 * 2                      # one row per point and seed, no duplicate
    assert len({r["run_key"] for r in table}) == 8
    assert len({(r["point"], r["seed"]) for r in table}) == 8
    stacked = [r for r in table if r["param:simulation.deployment"] == "stacked"]
    per_vehicle = [r for r in table if r["param:simulation.deployment"] == "per-vehicle"]
    assert len(stacked) == 4 and len(per_vehicle) == 4
    for r in stacked:                               # refused before anything ran, one line
        assert r["status"] == "error" and "[network] needs" in r["error"]
        assert "per-vehicle" in r["error"] and "\n" not in r["error"]
    for r in per_vehicle:
        assert r["status"] == "ok", r["error"]
        assert r["deployment"] == "per-vehicle" and r["architecture"] == "distributed"
        loss = r["param:network.loss"]
        folder = tmp_path / f"run_{loss}_{r['seed']}"
        assert main(["run", "--scenario", "formation-4", "--deployment", "per-vehicle",
                     "--architecture", "distributed", "--loss", str(loss), "--period", "1.0",
                     "--T", "4", "--seed", str(r["seed"]), "--out", str(folder),
                     "--quiet"]) == 0
        (m,) = json.loads((folder / "summary.json").read_text())["methods"].values()
        assert r["cost_rate"] == pytest.approx(m["cost_rate"]["mean"], rel=1e-12)
        assert r["rms_e"] == pytest.approx(m["rms_e"]["mean"], rel=1e-12)
    losses = {r["param:network.loss"]: r["cost_rate"] for r in per_vehicle
              if r["seed"] == 0}
    assert losses[0.0] != losses[0.3]               # the links were simulated
    # a third run of the same command has nothing left to do and changes nothing
    third = _campaign(spec, "--workers", "2", "--out", out)
    stdout, _ = third.communicate(timeout=300)
    assert third.returncode == 3 and "8 already done, 0 to run" in stdout
    assert without_timing(rows(out)) == without_timing(table)


def test_the_numpy_engine_says_which_systems_it_covers():
    from orchestrator.campaign.engine_numpy import numpy_unsupported
    from orchestrator.scenario import load_scenario
    sc = load_scenario("formation-4")
    assert numpy_unsupported("gauss-seidel", {"simulation", "vehicles"}, sc) is None
    pv = sc.with_run(deployment="per-vehicle")
    assert "per-vehicle" in numpy_unsupported("gauss-seidel", {"simulation"}, pv)


def test_two_points_that_differ_only_in_deployment_have_different_keys():
    from orchestrator.campaign.points import resolve_point, run_key
    from orchestrator.campaign.spec import base_mapping
    base, where = base_mapping("formation-4")
    a = resolve_point(0, {"simulation.deployment": "stacked"}, base, where)
    b = resolve_point(1, {"simulation.deployment": "per-vehicle"}, base, where)
    c = resolve_point(2, {"simulation.deployment": "per-vehicle", "simulation.fmus": "native"},
                      base, where)
    keys = {run_key(p, 0, "fmu", {}) for p in (a, b, c)}
    assert len(keys) == 3
    d = resolve_point(3, {"network.loss": 0.3}, base, where)       # links on the stacked loop
    assert d.scenario is None and "[network] needs" in d.error
