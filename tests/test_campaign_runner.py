"""auv-cosim campaign end to end, with real Dask clusters and real signals: a local cluster
of 2 workers, a `dask scheduler` and two `dask worker` processes used through --scheduler,
a campaign killed mid-way and resumed (the same table as an uninterrupted one), SIGINT,
a failing point recorded as rows, the numpy engine against the FMUs, a second writer
refused."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from orchestrator.cli import main
from orchestrator.outputs import output_folder
from support.campaign import RESUME
from support.campaign import rows as _rows
from support.campaign import without_timing as _without_timing
from support.dask_cluster import dask_cluster
from support.outputs import staging_folders, working


def _spec(tmp_path: Path, text: str, name: str = "spec.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p




def _campaign(*args: str, **kw) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "orchestrator", "campaign", *map(str, args)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)


SWEEP = """
base = "paper"
seeds = "0-2"
[sweep]
"simulation.estimator" = ["kalman", "classical"]
"simulation.T" = [5.0]
"vehicles.C" = [[[1.0, 2.0], [3.0, 4.0]], [[1.0, 2.0], [2.0, 4.0]]]
"""


@pytest.mark.slow
def test_local_cluster_failing_point_and_numpy_engine(tmp_path, capsys):
    """2 local workers; classical with a singular C fails as rows, the rest goes on; the
    numpy engine gives the FMU engine's statistics on every shared point (1e-9)."""
    spec = _spec(tmp_path, SWEEP)
    assert main(["campaign", str(spec), "--workers", "2", "--out", str(tmp_path / "fmu")]) == 3
    assert "auv-cosim campaign: 1 of 4 points failed (3 of 12 runs" in capsys.readouterr().err
    fmu = _rows(tmp_path / "fmu")
    assert len(fmu) == 4 * 3 and {r["engine"] for r in fmu} == {"fmu"}
    failed = [r for r in fmu if r["status"] != "ok"]
    assert len(failed) == 3                               # classical with singular C
    assert all(r["param:simulation.estimator"] == "classical" and "rank 1 < 2" in r["error"]
               for r in failed)
    assert all(r["cost_rate"] > 0 and len(r["rms_e"]) == 2 for r in fmu if r["status"] == "ok")
    summary = json.loads((tmp_path / "fmu" / "campaign.json").read_text())
    assert summary["cluster"]["workers"] == 2 and summary["failed"] == 3
    agg = _rows(tmp_path / "fmu", "aggregate.parquet")
    assert [a["failed"] for a in agg].count(3) == 1 and len(agg) == 4
    assert all(a["cost_rate_ci_low"] <= a["cost_rate_mean"] <= a["cost_rate_ci_high"]
               for a in agg if a["ok"])
    assert (tmp_path / "fmu" / "cost_simulation.estimator.svg").exists()

    assert main(["campaign", str(spec), "--workers", "2", "--engine", "numpy",
                 "--out", str(tmp_path / "numpy")]) == 3
    num = _rows(tmp_path / "numpy")
    assert {r["engine"] for r in num} == {"numpy"}
    for a, b in zip(fmu, num):
        assert (a["point"], a["seed"], a["status"]) == (b["point"], b["seed"], b["status"])
        if a["status"] == "ok":
            assert b["cost_rate"] == pytest.approx(a["cost_rate"], rel=1e-9, abs=1e-9)
            assert b["rms_e"] == pytest.approx(a["rms_e"], rel=1e-9, abs=1e-9)
            assert b["rms_u"] == pytest.approx(a["rms_u"], rel=1e-9, abs=1e-9)
            assert b["predicted_cost_rate"] == a["predicted_cost_rate"]
        else:
            assert b["error"] == a["error"]
    check = json.loads((tmp_path / "numpy" / "campaign.json").read_text())["numpy_check"]
    assert check["passed"] and check["runs"] == 2 and check["max_rel_diff"] <= 1e-9
    assert len(_rows(tmp_path / "numpy", "check.parquet")) == 2
    out = capsys.readouterr().out
    assert "agree" in out
    # a lost numpy batch is run again whole: the same bits as before
    part = next(p for p in sorted((tmp_path / "numpy" / "parts").glob("*.json"))
                if '"numpy"' in p.read_text())
    part.unlink()
    assert main(["campaign", str(spec), "--workers", "2", "--engine", "numpy",
                 "--out", str(tmp_path / "numpy")]) == 3
    assert "0 already done" not in capsys.readouterr().out
    assert _without_timing(_rows(tmp_path / "numpy")) == _without_timing(num)


@pytest.mark.slow
def test_external_scheduler_and_workers_then_jacobi_goes_to_the_fmus(tmp_path):
    """A `dask scheduler` and two `dask worker` processes on 127.0.0.1, used through
    --scheduler; with --engine numpy the Jacobi points run through the FMUs."""
    with dask_cluster(2) as cluster:
        address = cluster.address
        spec = _spec(tmp_path, """
base = "paper"
seeds = [3, 4]
[sweep]
"simulation.T" = [5.0]
"cosim.coupling" = ["gauss-seidel", "jacobi"]
""")
        proc = _campaign(spec, "--scheduler", address, "--engine", "numpy",
                         "--out", tmp_path / "out")
        stdout, stderr = proc.communicate(timeout=120)
        assert proc.returncode == 0, stderr
        rows = _rows(tmp_path / "out")
        assert [(r["param:cosim.coupling"], r["seed"], r["engine"]) for r in rows] == [
            ("gauss-seidel", 3, "numpy"), ("gauss-seidel", 4, "numpy"),
            ("jacobi", 3, "fmu"), ("jacobi", 4, "fmu")]
        assert all(r["status"] == "ok" for r in rows)
        assert "Gauss-Seidel" in rows[2]["engine_note"]
        summary = json.loads((tmp_path / "out" / "campaign.json").read_text())
        assert summary["cluster"]["scheduler"] == address and summary["cluster"]["workers"] == 2
        assert len({r["pid"] for r in rows}) >= 1
        agg = _rows(tmp_path / "out", "aggregate.parquet")
        assert [a["engines"] for a in agg] == ["numpy", "fmu"]
        # the Jacobi loop costs more, as its own prediction says
        assert agg[1]["predicted_cost_rate"] > agg[0]["predicted_cost_rate"]



def _wait_for_parts(out: Path, count: int, proc: subprocess.Popen) -> None:
    deadline = time.monotonic() + 120
    # the campaign writes into its staging folder beside out (swapped in at the end)
    while len(list((working(out) / "parts").glob("*.json"))) < count \
            if (working(out) / "parts").exists() else True:
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline
        time.sleep(0.05)


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGINT])
def test_killed_campaign_resumes_to_the_uninterrupted_table(tmp_path, sig, resume_reference):
    """A real signal to the client mid-way keeps every finished row; the same command then
    runs only the rest, and the table equals an uninterrupted campaign's."""
    spec = _spec(tmp_path, RESUME)
    out = tmp_path / "out"
    proc = _campaign(spec, "--workers", "2", "--out", out)
    try:
        _wait_for_parts(out, 2, proc)
        proc.send_signal(sig)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        proc.kill()
    # SIGKILL: the rows are in the staging folder the client left (the next run resumes
    # it); SIGINT: the partial campaign was swapped in (no earlier result in out)
    kept = len(list((working(out) / "parts").glob("*.json")))
    assert 2 <= kept < 12, "the campaign was not stopped mid-way"
    assert (working(out) == out) == (sig == signal.SIGINT)
    if sig == signal.SIGINT:
        assert proc.returncode == 130
        line = [s for s in stderr.splitlines() if "interrupted" in s]
        assert len(line) == 1 and "rerun the same command" in line[0]
        assert len(_rows(out)) == kept                      # every finished row is in the table
        assert not list(out.rglob("*.part"))
    again = _campaign(spec, "--workers", "2", "--out", out)
    stdout, stderr = again.communicate(timeout=120)
    assert again.returncode == 0, stderr
    assert f"{kept} already done, {12 - kept} to run" in stdout
    resumed = _rows(out)
    assert len(resumed) == 12 and not list(out.rglob("*.part"))
    assert staging_folders(out) == []                   # the killed client's was resumed
    assert _without_timing(resumed) == resume_reference


def test_a_second_campaign_into_the_same_folder_is_refused(tmp_path):
    spec = _spec(tmp_path, 'base = "paper"\nseeds = "0"\n[sweep]\n"simulation.T" = [1.0]\n')
    out = tmp_path / "out"
    with output_folder(out, "campaign"):         # another campaign holds the folder
        proc = _campaign(spec, "--out", out)
        stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 2
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and "is in use by auv-cosim campaign" in lines[0]
    assert f"pid {os.getpid()}" in lines[0]
    assert not (out / "results.parquet").exists()


@pytest.mark.slow
def test_a_plain_run_does_not_import_dask(tmp_path):
    code = ("import sys; from orchestrator.cli import main; "
            f"rc = main(['run', '--T', '0.5', '--quiet', '--out', {str(tmp_path)!r}]); "
            "print('LOADED', rc, sorted(m for m in sys.modules if m.split('.')[0] in "
            "('dask', 'distributed')))")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    last = res.stdout.strip().splitlines()[-1]
    assert last == "LOADED 0 []", res.stdout + res.stderr
    code = "import sys, orchestrator.campaign.runner; print('dask' in sys.modules)"
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert res.stdout.strip() == "False", res.stderr


@pytest.mark.slow
def test_workers_started_after_a_pythonfmu_fmu_ran_here_import_the_project(tmp_path):
    """A pythonfmu FMU instantiated in this process leaves its resources folder (with the
    FMU's copy of the project's packages) in front of sys.path: pythonfmu never takes it
    out. Local Dask workers started afterwards must not inherit it (the spawn start method
    hands them the parent's sys.path: they imported the FMU's copy and failed every run,
    "Cannot find shared library ... AuvPlant.so"). Every run is ok; sys.path is left as it
    was (Dask appends its scratch folder)."""
    from fmpy import extract

    from orchestrator.cosim.build import build_fmus
    from orchestrator.cosim.instance import FmuInstance
    from orchestrator.running.fmus import scenario_config
    from orchestrator.scenario import load_scenario
    sc = load_scenario("paper")
    fmu = build_fmus(scenario_config(sc), tmp_path / "fmus")["plant"]
    folder = tmp_path / "unzipped"
    inst = FmuInstance("probe", fmu, extract(str(fmu), unzipdir=str(folder)), "probe")
    assert str(folder / "resources") in sys.path
    before = list(sys.path)
    spec = _spec(tmp_path, 'name = "after-fmu"\nbase = "paper"\nseeds = "0-1"\n'
                 '[[points]]\n"simulation.T" = 2.0\n')
    assert main(["campaign", str(spec), "--workers", "2", "--out", str(tmp_path / "c")]) == 0
    assert [r["status"] for r in _rows(tmp_path / "c")] == ["ok", "ok"]
    assert sys.path[:len(before)] == before
    del inst
