"""A campaign on a real `dask scheduler` with real `dask worker` processes, when a worker is
killed (SIGKILL) mid-way and when the scheduler itself is killed: nothing is lost, and the
final table equals an uninterrupted campaign's (apart from wall times and hosts)."""
from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from support.campaign import RESUME, rows, without_timing
from support.dask_cluster import dask_cluster
from support.outputs import working

SPEC = RESUME
RUNS = 12


def _campaign(*args) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "orchestrator", "campaign", *map(str, args)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _table(out: Path) -> list[dict]:
    return without_timing(rows(out))


def _wait_for_parts(out: Path, count: int, proc: subprocess.Popen) -> int:
    deadline = time.monotonic() + 180
    while True:
        parts = working(out) / "parts"        # the staging folder beside out, while it runs
        n = len(list(parts.glob("*.json"))) if parts.exists() else 0
        if n >= count:
            return n
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline
        time.sleep(0.05)


@pytest.mark.slow
def test_a_killed_worker_loses_nothing(tmp_path, resume_reference):
    (tmp_path / "spec.toml").write_text(SPEC)
    with dask_cluster(2) as cluster:
        proc = _campaign(tmp_path / "spec.toml", "--scheduler", cluster.address,
                         "--out", tmp_path / "out")
        try:
            done = _wait_for_parts(tmp_path / "out", 2, proc)
            cluster.workers[0].send_signal(signal.SIGKILL)       # a worker dies mid-campaign
            cluster.workers[0].wait(timeout=20)
            _, err = proc.communicate(timeout=300)
        finally:
            proc.kill()
    assert done < RUNS, "the worker was not killed mid-way"
    assert proc.returncode == 0, err
    assert _table(tmp_path / "out") == resume_reference          # its task ran on the other worker


@pytest.mark.slow
def test_a_lost_scheduler_keeps_the_rows_and_a_rerun_finishes(tmp_path, resume_reference):
    (tmp_path / "spec.toml").write_text(SPEC)
    out = tmp_path / "out"
    with dask_cluster(1) as cluster:
        proc = _campaign(tmp_path / "spec.toml", "--scheduler", cluster.address, "--out", out)
        try:
            _wait_for_parts(out, 2, proc)
            cluster.scheduler.send_signal(signal.SIGKILL)         # the scheduler is gone
            t0 = time.monotonic()
            _, err = proc.communicate(timeout=120)
            waited = time.monotonic() - t0
        finally:
            proc.kill()
    kept = len(list((out / "parts").glob("*.json")))
    assert 2 <= kept < RUNS
    assert proc.returncode != 0 and waited < 90, (proc.returncode, waited, err)
    lines = [line for line in err.strip().splitlines() if line.startswith("auv-cosim campaign")]
    assert len(lines) == 1 and "not done" in lines[0], err
    assert len(_table(out)) == kept                      # what finished is in the table
    again = _campaign(tmp_path / "spec.toml", "--workers", "2", "--out", out)
    stdout, err = again.communicate(timeout=300)
    assert again.returncode == 0, err
    assert f"{kept} already done, {RUNS - kept} to run" in stdout
    assert _table(out) == resume_reference
