"""SIGINT and SIGTERM sent to a real `auv-cosim run` in the middle of its loop: the run
stops between steps, keeps a valid .rrd up to the time reached and a summary.json marked
interrupted (replacing an earlier run's), says so in one line and exits 130 / 143."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from orchestrator.recording import read_rrd_scalars
from support.outputs import working


@pytest.mark.slow
@pytest.mark.parametrize("sig, status", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_keeps_what_was_simulated(tmp_path, sig, status):
    out = tmp_path / "run"
    out.mkdir()
    (out / "summary.json").write_text('{"earlier": true}')
    (out / "paper.rrd").write_bytes(b"an earlier run's recording")
    proc = subprocess.Popen([sys.executable, "-m", "orchestrator", "run", "--T", "3000",
                             "--quiet", "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while not (working(out) / "fmus" / "AuvController.fmu").exists():   # FMUs in place
            assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read()
            time.sleep(0.05)
        time.sleep(4.0)          # inside the loop (set-up takes about 1 s, 3 s under load)
        proc.send_signal(sig)
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == status, stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    assert lines[0].startswith(f"auv-cosim: interrupted by {sig.name} at t = ")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"] is True and summary["interrupted_by"] == sig.name
    reached = summary["time_reached_s"]
    assert 0 < reached < 3000
    steps = summary["rrd"]["recorded_steps"]
    # stopped between slices of 200 steps (or at the end of a chunk of the recorder)
    assert steps == round(reached / 0.01) and (steps % 200 == 0 or steps % 2 ** 14 == 0)
    assert summary["methods"]["kalman"]["seeds_completed"] == 0
    series = read_rrd_scalars(out / "paper.rrd")                     # a valid, complete file
    k, t_ns, e1 = series["error/1/kalman"]
    assert np.array_equal(k, np.arange(steps)) and len(series) == 20
    assert np.all(np.isfinite(e1))
    assert not [p for p in out.iterdir() if p.name.endswith(".part")]
    assert f"{reached:.6g}" in lines[0]


def test_an_uninterrupted_run_says_so(tmp_path):
    from orchestrator.cli import main
    assert main(["run", "--T", "1", "--quiet", "--out", str(tmp_path)]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["interrupted"] is False and summary["interrupted_by"] is None
    assert summary["time_reached_s"] == 1.0 and summary["rrd"]["recorded_steps"] == 100
    assert os.path.exists(summary["rrd"]["path"])


@pytest.mark.slow
@pytest.mark.parametrize("sig, status", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_signal_while_the_rrd_is_written(tmp_path, sig, status):
    """The signal arrives while the .rrd is being written (its temporary file exists): the
    recording is finished whole (a complete, valid file with all 20 series), never left
    truncated under its final name, and the run says it was interrupted."""
    out = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, "-m", "orchestrator", "run", "--T", "1000",
                             "--quiet", "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 300
        while not (working(out).is_dir() and [p for p in working(out).iterdir()
                                              if p.name.endswith(".part")
                                              and ".rrd" in p.name]):
            assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read()
            time.sleep(0.002)
        proc.send_signal(sig)
        _, stderr = proc.communicate(timeout=300)
    finally:
        proc.kill()
    assert proc.returncode == status, stderr
    assert len(stderr.strip().splitlines()) == 1 and f"interrupted by {sig.name}" in stderr
    series = read_rrd_scalars(out / "paper.rrd")
    assert len(series) == 20
    k, _, e1 = series["error/1/kalman"]
    assert len(k) == 100_000 and np.all(np.isfinite(e1))
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"] is True and summary["rrd"]["recorded_steps"] == 100_000
    assert not [p for p in out.iterdir() if p.name.endswith(".part")]


@pytest.mark.slow
def test_a_signal_keeps_what_a_per_vehicle_run_simulated(tmp_path):
    """The same for 13 FMUs of the per-vehicle deployment: one line, the traces up to the
    stop in the .rrd (read back), the summary marked."""
    out = tmp_path / "pv"
    proc = subprocess.Popen([sys.executable, "-m", "orchestrator", "run", "--scenario",
                             "formation-4", "--deployment", "per-vehicle", "--architecture",
                             "distributed", "--T", "600", "--quiet", "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while not (working(out) / "fmus" / "AuvVehicleController.fmu").exists():
            assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read()
            time.sleep(0.05)
        time.sleep(10.0)         # past the prediction, inside the loop (60,000 steps: 40 s+)
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == 130, stderr
    assert len(stderr.strip().splitlines()) == 1, stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"] is True and summary["deployment"] == "per-vehicle"
    steps = summary["rrd"]["recorded_steps"]
    assert 0 < steps < 60_000 and steps % 200 == 0
    series = read_rrd_scalars(out / "formation-4.rrd")
    k, _, e = series["vehicles/4/error/kalman"]
    assert len(k) == len(range(0, steps, summary["rrd"]["recorded_every_steps"]))
    assert np.all(np.isfinite(e))
