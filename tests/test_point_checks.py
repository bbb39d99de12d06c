"""One set of rules for every point (issue 35, item 3): ``run``, each ``campaign`` point and
each ``envelope`` point pass the same checks before they start
(:func:`orchestrator.running.systems.check_run`), so a point that would not finish
(``T = 1e9``: 1e11 steps) is an error row at once, in the words ``run`` prints; and the
exit statuses: 0 only when every point ran, 3 (``orchestrator.exit_status.POINTS_FAILED``)
with one stderr line counting the failed points otherwise."""
from __future__ import annotations

import json
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from orchestrator.cli import main
from orchestrator.exit_status import POINTS_FAILED
from support.campaign import rows

#: what run prints for paper at T = 1e9 (up to the memory figure, which varies)
T_1E9 = ("T = 1e+09 s with h = 0.01 s is 1e+11 steps: its recording (20 values per sample, 1 "
         "method(s), 1e+11 samples) needs about 6.4e+04 GB on disk, more than the ")


def _command(*args: str | Path, timeout: float = 300) -> tuple[subprocess.CompletedProcess,
                                                                float]:
    """``python -m orchestrator ARGS``: the finished process and its wall time, s."""
    t0 = time.monotonic()
    done = subprocess.run([sys.executable, "-m", "orchestrator", *map(str, args)],
                          capture_output=True, text=True, timeout=timeout)
    return done, time.monotonic() - t0


def _no_memory_figure(text: str) -> str:
    """``text`` without the memory available or the disk free, which differ between two
    processes."""
    text = re.sub(r"the [0-9.e+]+ GB free", "the ... GB free", text)
    return re.sub(r"the [0-9.e+]+ GB of memory available", "the ... GB of memory available",
                  text)


def test_run_and_a_campaign_point_refuse_t_1e9_in_the_same_words(tmp_path, capsys):
    from orchestrator.campaign.points import resolve_point
    from orchestrator.campaign.spec import base_mapping
    assert main(["run", "--scenario", "paper", "--T", "1e9", "--out",
                 str(tmp_path / "r")]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith("auv-cosim run: error: " + T_1E9)
    assert not (tmp_path / "r").exists()                 # refused before any folder
    base, where = base_mapping("paper")
    point = resolve_point(0, {"simulation.T": 1e9}, base, where)
    assert point.scenario is None and point.error is not None
    assert _no_memory_figure(point.error) == _no_memory_figure(
        line.removeprefix("auv-cosim run: error: "))
    assert resolve_point(1, {"simulation.T": 5.0}, base, where).error is None


def test_a_campaign_whose_every_point_fails_exits_3_and_counts_them_on_stderr(tmp_path):
    spec = tmp_path / "all.toml"
    spec.write_text('base = "paper"\nseeds = "0-2"\n[sweep]\n"simulation.T" = [1e9, 2e9]\n')
    out = tmp_path / "out"
    done, wall = _command("campaign", spec, "--out", out)
    assert done.returncode == POINTS_FAILED == 3, done.stderr
    assert wall < 60
    assert done.stderr.strip().splitlines()[-1].startswith(
        f"auv-cosim campaign: 2 of 2 points failed (6 of 6 runs are error rows in "
        f"{out / 'results.parquet'}); the first: point 0: {T_1E9}")
    table = rows(out)
    assert len(table) == 6 and {r["status"] for r in table} == {"error"}
    assert [r["error"][:len("T = 1e+09 s")] for r in table] == ["T = 1e+09 s"] * 3 + [
        "T = 2e+09 s"] * 3
    summary = json.loads((out / "campaign.json").read_text())
    assert summary["failed_points"] == 2 and summary["failed"] == 6
    assert "failed (3 runs): T = 2e+09 s" in done.stdout       # each point's reason


@pytest.mark.slow
def test_a_point_that_would_not_finish_is_an_error_row_at_once(tmp_path):
    """T = 1e9 beside T = 5 on a real local cluster: the 1e9 point is refused before
    anything runs (it used to loop over 1e11 steps), the other runs; exit status 3."""
    spec = tmp_path / "mixed.toml"
    spec.write_text('base = "paper"\nseeds = "0-1"\n[sweep]\n"simulation.T" = [5.0, 1e9]\n')
    out = tmp_path / "out"
    done, wall = _command("campaign", spec, "--workers", "1", "--out", out)
    assert wall < 60, wall                               # the 1e9 run alone: years
    assert done.returncode == POINTS_FAILED, done.stderr
    table = rows(out)
    assert [(r["point"], r["status"]) for r in table] == [(0, "ok"), (0, "ok"),
                                                          (1, "error"), (1, "error")]
    run, _ = _command("run", "--scenario", "paper", "--T", "1e9", "--out", tmp_path / "r")
    said = run.stderr.strip().removeprefix("auv-cosim run: error: ")
    assert run.returncode == 2 and said.startswith(T_1E9)
    for r in table[2:]:
        assert _no_memory_figure(r["error"]) == _no_memory_figure(said)
    assert (f"auv-cosim campaign: 1 of 2 points failed (2 of 4 runs are error rows in "
            f"{out / 'results.parquet'}); the first: point 1: {T_1E9}") in done.stderr


ENVELOPE = ["envelope", "--scenario", "formation-4", "--deployment", "per-vehicle",
            "--architecture", "distributed", "--speeds", "1.5", "--currents", "0.1"]


def test_envelope_points_that_would_not_finish_fail_at_once_and_exit_3(tmp_path):
    out = tmp_path / "env"
    done, wall = _command(*ENVELOPE, "--T", "1e9", "--radii", "inf,30", "--out", out)
    assert done.returncode == POINTS_FAILED, done.stderr
    assert wall < 60
    points = json.loads((out / "summary.json").read_text())["envelope"]["points"]
    assert len(points) == 2
    for p in points:
        assert p["failed"].startswith("T = 1e+09 s with h = 0.01 s is 1e+11 steps: its "
                                      "recording (")
        assert p["folder"] is None                      # refused before its folder
    (line,) = [t for t in done.stderr.splitlines() if t.startswith("auv-cosim envelope:")]
    assert line.startswith(f"auv-cosim envelope: 2 of 2 points failed (each reason in "
                           f"{out / 'summary.json'}); the first: T = 1e+09 s")


@pytest.mark.slow
def test_an_envelope_with_a_failed_point_exits_3_with_the_count(tmp_path):
    """A 0.01 m circle the step cannot sample fails; the straight line runs."""
    out = tmp_path / "env"
    done, _ = _command(*ENVELOPE, "--T", "2", "--radii", "inf,0.01", "--out", out)
    assert done.returncode == POINTS_FAILED, done.stderr
    env = json.loads((out / "summary.json").read_text())["envelope"]
    assert env["failed"] == 1 and env["points"][0]["failed"] is None
    assert env["points"][0]["max_error"] > 0
    assert "the radius must be at least" in env["points"][1]["failed"]
    assert (f"auv-cosim envelope: 1 of 2 points failed (each reason in "
            f"{out / 'summary.json'}); the first: ") in done.stderr


def test_the_path_check_is_sampled_as_step_by_step_and_refused_when_too_long():
    """path_states (doubling blocks) equals z(k dt) = Phi^k z0 step by step; a horizon
    whose samples would not fit is refused before any is taken."""
    from scipy.linalg import expm

    from orchestrator.analysis.weight_search import check_path_horizon
    from plant_model.linalg_checks import ModelError
    from plant_model.path_feasibility import path_states
    w = 0.05                                            # a circle: rotation at w rad/s
    F = np.zeros((4, 4))
    F[0, 2] = F[1, 3] = 1.0
    F[2, 3], F[3, 2] = -w, w
    z0 = np.array([0.0, 0.0, 1.5, 0.0])
    Z = path_states(F, z0, 300.0, 0.1)
    Phi, z = expm(F * 0.1), z0.copy()
    assert Z.shape == (3001, 4)
    for k in range(Z.shape[0]):
        assert Z[k] == pytest.approx(z, rel=1e-11, abs=1e-11)
        z = Phi @ z
    assert check_path_horizon(4, 300.0, available=10**12) == 8 * 3001 * (4 + 16)
    with pytest.raises(ModelError, match=r"^\[design\] path check: T = 1e\+09 s sampled "
                                         r"every 0.1 s is 1e\+10 samples"):
        check_path_horizon(4, 1e9, available=10**10)
