"""Pacing to the wall clock (orchestrator/cosim/pacing.py and the compiled master's Pace):
a paced run takes its planned wall-clock time, T / FACTOR, never less (every step waits for
its deadline) and more only by its last lateness; overruns are counted and the worst
lateness reported; ``run --realtime`` prints and writes it. Real FMUs, both masters."""
from __future__ import annotations

import json
import subprocess
import sys
import time

import pytest

from orchestrator.cosim.master import run_system
from orchestrator.cosim.pacing import Pacer
from support.masters import on_master, paper_systems


@pytest.fixture(scope="module")
def paper(tmp_path_factory):
    return paper_systems(tmp_path_factory.mktemp("pacing"), 2.0)


@pytest.mark.parametrize("master", ["python", "native"])
@pytest.mark.parametrize("factor", [1.0, 4.0])
def test_a_paced_run_keeps_to_the_wall_clock(paper, master, factor):
    sc = paper[0]
    system, fmus = on_master(paper, master)
    t0 = time.monotonic()
    _, _, info = run_system(system, fmus, sc.steps, master=master, realtime=factor)
    elapsed = time.monotonic() - t0
    rt = info["realtime"]
    planned = sc.T / factor
    assert info["master"] == master and rt["factor"] == factor
    assert rt["planned_s"] == pytest.approx(planned)
    # never ahead of the clock: the last step waited for its deadline, or was late
    assert rt["wall_s"] >= planned - 1e-3
    assert rt["wall_s"] <= planned + rt["worst_lateness_s"] + 0.05
    assert elapsed >= planned
    assert rt["overruns"] >= 0 and (rt["overruns"] > 0) == (rt["worst_lateness_s"] > 0)


def test_an_unpaced_run_is_faster_than_real_time(paper):
    sc, system, fmus, _ = paper
    _, loop_s, info = run_system(system, fmus, sc.steps, master="python")
    assert "realtime" not in info and loop_s < sc.T


def test_overruns_are_counted_when_the_steps_cannot_keep_up():
    pacer = Pacer(1000.0, 0.01)              # 10 us per step of 0.01 s: Python cannot
    pacer.begin(0)
    for k in range(50):
        time.sleep(0.0002)                   # a step that takes 200 us
        pacer.after(k)
    pacer.finish()
    rt = pacer.report(50)
    assert rt["overruns"] >= 45 and rt["worst_lateness_s"] > 0.005
    with pytest.raises(ValueError, match="real-time factor 0"):
        Pacer(0, 0.01)


def test_run_realtime_prints_and_writes_the_overruns(tmp_path):
    out = tmp_path / "rt"
    res = subprocess.run([sys.executable, "-m", "orchestrator", "run", "--T", "2",
                          "--realtime", "2", "--out", str(out)], capture_output=True,
                         text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    rt = json.loads((out / "summary.json").read_text())["realtime"]
    assert rt["factor"] == 2.0 and rt["runs"] == 1 and rt["planned_s"] == pytest.approx(1.0)
    line = next(ln for ln in res.stdout.splitlines() if ln.startswith("real time x2:"))
    assert f"{rt['overruns']} overrun(s)" in line and "s planned" in line
    bad = subprocess.run([sys.executable, "-m", "orchestrator", "run", "--realtime", "0"],
                         capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "give simulated seconds per wall-clock second" in bad.stderr
