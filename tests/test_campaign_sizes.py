"""A campaign's points that would not fit, and its default folder: a fleet whose stacked
model would not fit in memory is refused before it is built (it ended in a MemoryError
after allocating gigabytes), a stacked design estimated past the limit before it is tried,
each as error rows with the one-line reason; a spec name with path parts stays one folder
under out/ (it used to write outside the working folder)."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from orchestrator.running.memory import MAX_DESIGN_S
from support.campaign import rows


def _campaign(spec, *args, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "orchestrator", "campaign", str(spec),
                           *map(str, args)], capture_output=True, text=True, cwd=cwd,
                          timeout=120)


@pytest.mark.slow
def test_a_base_of_2000_vehicles_is_refused_before_its_model_is_built(tmp_path):
    spec = tmp_path / "big.toml"
    spec.write_text('name = "big"\nbase = "grid-2000"\nseeds = "0"\n'
                    '[sweep]\n"simulation.T" = [0.1]\n')
    # the peak of this campaign's process tree (its waited workers included) through
    # wait4, not RUSAGE_CHILDREN: that holds the largest child this xdist worker ever ran
    with open(tmp_path / "stdout", "w") as out, open(tmp_path / "stderr", "w") as err:
        proc = subprocess.Popen([sys.executable, "-m", "orchestrator", "campaign", str(spec),
                                 "--out", str(tmp_path / "out")], stdout=out, stderr=err)
        _, status, usage = os.wait4(proc.pid, 0)
    done = subprocess.CompletedProcess(proc.args, os.waitstatus_to_exitcode(status),
                                       (tmp_path / "stdout").read_text(),
                                       (tmp_path / "stderr").read_text())
    peak_kib = usage.ru_maxrss
    assert done.returncode == 3, done.stderr           # its one point failed
    assert "Traceback" not in done.stderr and "MemoryError" not in done.stderr
    (row,) = rows(tmp_path / "out")
    assert row["status"] == "error"
    assert row["error"].startswith("generated scenario 'grid-2000' with simulation.T = 0.1: "
                                   "the stacked model of 2000 vehicles (18006 states) needs "
                                   "about 36.3 GB (estimated: 14 dense 18006 x 18006 "
                                   "matrices), more than 80% of the ")
    assert row["error"].endswith("GB of memory available; use fewer vehicles")
    assert "\n" not in row["error"]
    assert peak_kib < 3_000_000           # under 3 GB: nothing of the 36 GB began
    assert "failed (1 runs): generated scenario 'grid-2000'" in done.stdout


@pytest.mark.slow
def test_a_stacked_point_whose_design_would_not_finish_is_an_error_row(tmp_path):
    spec = tmp_path / "stacked.toml"
    spec.write_text('base = "formation-100"\nseeds = "0-1"\n[sweep]\n'
                    '"simulation.deployment" = ["stacked"]\n"simulation.T" = [0.1]\n')
    done = _campaign(spec, "--out", tmp_path / "out")
    assert done.returncode == 3, done.stderr           # every point failed
    assert "auv-cosim campaign: 1 of 1 points failed (2 of 2 runs" in done.stderr
    table = rows(tmp_path / "out")
    assert len(table) == 2 and {r["status"] for r in table} == {"error"}
    msg = table[0]["error"]
    assert ("the stacked deployment solves one design for all 100 vehicles (917 states; "
            "tracking design, Kalman filter, predictions): about ") in msg
    assert f"more than the {MAX_DESIGN_S:g} s allowed; use --deployment per-vehicle" in msg


def test_a_campaign_name_with_path_parts_stays_under_out(tmp_path):
    """The name is cleaned as the other commands clean scenario names: one folder under
    out/ of the working folder, nothing beside or above it."""
    work = tmp_path / "a" / "b" / "work"
    work.mkdir(parents=True)
    spec = work / "spec.toml"
    spec.write_text('name = "x/../../../escaped"\nbase = "paper"\nseeds = "0"\n'
                    '[sweep]\n"simulation.T" = [-1.0]\n')       # an error row: no cluster
    done = _campaign(spec, cwd=work)
    assert done.returncode == 3, done.stderr           # its one point is an error row
    assert sorted(p.name for p in work.iterdir()) == ["out", "spec.toml"]
    assert sorted(p.name for p in (work / "out").iterdir()) == [
        ".campaign_x_.._.._.._escaped.lock", "campaign_x_.._.._.._escaped"]   # its lock beside
    assert (work / "out" / "campaign_x_.._.._.._escaped" / "results.parquet").exists()
    for folder, only in ((tmp_path, "a"), (tmp_path / "a", "b"), (tmp_path / "a" / "b", "work")):
        assert [p.name for p in folder.iterdir()] == [only]      # nothing beside or above
