"""``auv-cosim plot`` of a run stopped by a signal says so: one line in the printout, and
the last lines of every figure's title (the matplotlib text, read back from the figures).

The run is a real ``auv-cosim run`` in a subprocess whose standard error is a terminal
(a pseudo-terminal), so that it shows its progress bar: the bar's first appearance means
the loop is stepping, and SIGINT is sent then (not after a guessed delay)."""
from __future__ import annotations

import fcntl
import json
import os
import pty
import select
import signal
import struct
import subprocess
import sys
import termios
import time
from pathlib import Path

import pytest

from orchestrator.cli import main
from orchestrator.plotting import build_figures, deterministic_style, load_run
from orchestrator.plotting.run_folder import interruption_note

ROOT = Path(__file__).resolve().parents[1]


def _interrupted_run(out: Path, *args: str) -> dict:
    """A real ``auv-cosim run`` stopped by SIGINT once its loop steps; its summary."""
    primary, secondary = pty.openpty()
    # a terminal of 30 x 100 characters (tqdm draws nothing on one of zero columns)
    fcntl.ioctl(secondary, termios.TIOCSWINSZ, struct.pack("HHHH", 30, 100, 0, 0))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]))
    proc = subprocess.Popen([sys.executable, "-m", "orchestrator", "run", *args,
                             "--out", str(out)], stdout=subprocess.DEVNULL,
                            stderr=secondary, env=env)
    os.close(secondary)
    seen = b""
    try:
        deadline = time.monotonic() + 240
        while b"step" not in seen:           # the progress bar: the loop runs
            assert proc.poll() is None and time.monotonic() < deadline, seen
            if select.select([primary], [], [], 0.1)[0]:
                try:
                    seen += os.read(primary, 4096)
                except OSError:              # the child closed the terminal
                    break
        proc.send_signal(signal.SIGINT)
        while proc.poll() is None and time.monotonic() < deadline:
            if select.select([primary], [], [], 0.1)[0]:
                try:
                    seen += os.read(primary, 4096)
                except OSError:
                    break
        assert proc.wait(timeout=60) == 130, seen
    finally:
        proc.kill()
        os.close(primary)
    return json.loads((out / "summary.json").read_text())


@pytest.mark.slow
def test_plot_of_an_interrupted_run_says_so(tmp_path, capsys):
    run = tmp_path / "run"
    summary = _interrupted_run(run, "--T", "3000")
    assert summary["interrupted"] is True and summary["interrupted_by"] == "SIGINT"
    reached = summary["time_reached_s"]
    assert 0 < reached < 3000 and summary["rrd"]["recorded_steps"] > 0
    note = interruption_note(summary)
    assert note == (f"interrupted run: stopped by SIGINT at t = {reached:.6g} s of 3000 s; "
                    "the traces end there, the statistics are over the seeds that completed")

    figs = tmp_path / "figs"
    assert main(["plot", str(run), "--format", "png", "--out", str(figs), "--quiet"]) == 0
    printed = capsys.readouterr().out.strip().splitlines()
    assert printed == [f"note: {run}: {note} (each figure's title says so)",
                       f"wrote 6 files into {figs}"]

    data = load_run(run)
    assert data.interruption == note
    with deterministic_style():
        figures = build_figures(data)
    assert [pf.name for pf in figures] == ["error-1", "error-2", "state-1", "state-2",
                                           "control-1", "control-2"]
    for pf in figures:
        title = pf.figure.get_suptitle()
        assert "; ".join(title.splitlines()[-2:]) == note, (pf.name, title)
        assert title.startswith(("Tracking error", "State", "Control input"))
        x_end = max(float(line.get_xdata()[-1]) for line in pf.series.values())
        assert x_end <= reached                     # the traces end where the run stopped


@pytest.mark.slow
def test_a_finished_run_has_no_interruption_line(tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["run", "--T", "2", "--quiet", "--out", str(run)]) == 0
    capsys.readouterr()
    assert main(["plot", str(run), "--format", "svg", "--quiet"]) == 0
    assert capsys.readouterr().out.strip().splitlines() == [
        f"wrote 6 files into {run / 'figures'}"]
    with deterministic_style():
        figures = build_figures(load_run(run))
    assert all("interrupted" not in pf.figure.get_suptitle() for pf in figures)
