"""Size-dependent paths before they start: the stacked design's time and memory are
estimated (orchestrator.running.memory, calibrated on this machine) and a design that
would not finish in MAX_DESIGN_S is refused in one line with the estimate and the limit;
a long one is announced in one line; SIGINT / SIGTERM during the design (a real signal to
a real `auv-cosim run`) end it between LAPACK calls with one clean line, keeping the FMUs
built."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from orchestrator.cli import main
from orchestrator.running.memory import (
    ANNOUNCE_S,
    MAX_DESIGN_S,
    design_estimate,
)


def test_a_stacked_fleet_too_large_is_refused_by_its_estimate(tmp_path, capsys):
    """formation-100 stacked: one design of 917 states, estimated past the limit: refused
    before any folder or FMU exists (it used to run for many minutes in silence)."""
    out = tmp_path / "o"
    assert main(["run", "--scenario", "formation-100", "--deployment", "stacked",
                 "--T", "0.1", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith("auv-cosim run: error: the stacked deployment solves one design "
                          "for all 100 vehicles (917 states; tracking design, Kalman "
                          "filter, predictions): about ")
    assert f"(estimated), more than the {MAX_DESIGN_S:g} s allowed" in err
    assert "use --deployment per-vehicle --architecture distributed" in err
    assert not out.exists()


def test_the_estimate_counts_only_the_phases_that_run():
    """The Kalman filter and the predictions are the costly phases: without them (the ideal
    estimator, --predict none) formation-100's stacked design fits the limit."""
    full = design_estimate(917)
    bare = design_estimate(917, kalman=False, predict=False)
    assert full.seconds > MAX_DESIGN_S > bare.seconds > ANNOUNCE_S
    assert full.phases == ("design", "filter", "predictions") and bare.phases == ("design",)
    assert design_estimate(300 * 9 + 6).seconds > 10 * 3600       # the 300-vehicle case
    assert design_estimate(6).seconds < 1e-3                       # the paper's system


def _grid(tmp_path, n: int):
    from orchestrator.scenario.generator import grid_fleet, scenario_toml
    path = tmp_path / f"grid{n}.toml"
    path.write_text(scenario_toml(grid_fleet(n, name=f"grid{n}")))
    return path


@pytest.mark.slow
@pytest.mark.parametrize("sig, status, extra", [
    (signal.SIGTERM, 143, ()),                          # in the predictions
    (signal.SIGINT, 130, ("--predict", "none")),       # in the design the FMUs would solve
], ids=["SIGTERM-predictions", "SIGINT-design"])
def test_a_signal_during_the_stacked_design_stops_it(tmp_path, sig, status, extra):
    """40 vehicles stacked (366 states, about 15-27 s of design here): the design is
    announced with its estimate, a real signal stops it within seconds with one line, and
    nothing is left under --out (it held no earlier result: the staging folder, with the
    FMUs it built, is deleted; they stay in the FMU cache), so no summary pretends to a run."""
    out = tmp_path / "o"
    proc = subprocess.Popen([sys.executable, "-m", "orchestrator", "run", "--scenario",
                             str(_grid(tmp_path, 40)), "--T", "0.1", "--out", str(out),
                             *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=dict(os.environ, PYTHONUNBUFFERED="1"))
    try:
        announced = proc.stdout.readline()
        time.sleep(0.5)                                  # inside the design
        t0 = time.monotonic()
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=120)
        waited = time.monotonic() - t0
    finally:
        proc.kill()
    assert announced.startswith("solving the stacked design (40 vehicles, 366 states)")
    assert "s and " in announced and "GB (estimated) ..." in announced
    assert proc.returncode == status, err
    assert err.strip() == (f"auv-cosim run: interrupted by {sig.name} during the stacked "
                           "design (40 vehicles, 366 states), before the first step: "
                           "nothing was simulated")
    assert waited < 10, f"the design went on for {waited:.1f} s after the signal"
    assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if ".staging-" in p.name]
