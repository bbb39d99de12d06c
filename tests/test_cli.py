"""The auv-cosim command line, end to end on short horizons, and its error messages."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from orchestrator.analysis.reference import run_monolithic
from orchestrator.cli import main, parse_seeds
from orchestrator.recording import read_rrd_scalars
from orchestrator.scenario import SCENARIO_DIR, load_scenario

ROOT = Path(__file__).resolve().parent.parent


def test_run_writes_summary_and_rrd_matching_the_reference(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", "--T", "2", "--seed", "3", "--out", str(out), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["scenario"] == "paper" and summary["steps"] == 200 and summary["seeds"] == [3]
    assert summary["noise_convention"] == "intensity"
    assert list(summary["methods"]) == ["kalman"]
    m = summary["methods"]["kalman"]
    assert len(m["rms_e"]["mean"]) == 2 and len(m["rms_u"]["predicted"]) == 2
    assert m["cost_rate"]["per_seed"][0] == m["cost_rate"]["mean"] > 0
    assert {"numpy", "scipy", "fmpy", "pythonfmu", "rerun-sdk"} <= set(summary["versions"])
    # the traces in the .rrd are those of the closed loop (independent reference loop)
    ref = run_monolithic(load_scenario("paper").system, 0.01, "kalman", 3, 200)
    series = read_rrd_scalars(out / "paper.rrd")
    steps, t_ns, e1 = series["error/1/kalman"]
    assert np.array_equal(steps, np.arange(200)) and np.array_equal(t_ns, np.arange(200) * 10_000_000)
    np.testing.assert_allclose(e1, ref["e"][:, 0], atol=1e-9)
    np.testing.assert_allclose(series["control/2/kalman"][2], ref["u"][:, 1], atol=1e-9)
    np.testing.assert_allclose(series["state/1/kalman/estimate"][2], ref["xhat"][:, 0], atol=1e-9)
    assert "paper.rrd" in capsys.readouterr().out


@pytest.mark.slow
def test_compare_runs_three_methods_on_the_same_noise(tmp_path):
    out = tmp_path / "cmp"
    assert main(["compare", "--T", "3", "--seeds", "0-1", "--out", str(out), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["seeds"] == [0, 1]
    methods = summary["methods"]
    assert set(methods) == {"kalman", "classical", "ideal"}
    for m in methods.values():
        assert len(m["cost_rate"]["per_seed"]) == 2
        assert m["cost_rate"]["predicted"] > 0
    # same seed -> same reference trajectory, whatever the estimator (z is not controlled)
    series = read_rrd_scalars(out / "paper.rrd")
    z = [series[f"reference/1/{m}/true"][2] for m in ("kalman", "classical", "ideal")]
    assert np.array_equal(z[0], z[1]) and np.array_equal(z[0], z[2])
    # the estimators differ: the control signals are not the same
    assert not np.allclose(series["control/1/kalman"][2], series["control/1/classical"][2])


def _bad_scenario(tmp_path, old, new):
    text = (SCENARIO_DIR / "paper.toml").read_text()
    assert old in text
    p = tmp_path / "bad.toml"
    p.write_text(text.replace(old, new))
    return str(p)


@pytest.mark.parametrize("args, expected", [
    (["run", "--scenario", "nonexistent"], "unknown scenario 'nonexistent'"),
    (["run", "--T", "0.001"], "T = 0.001 must be at least one step"),
    (["validate", "missing.fmu"], "FMU file(s) not found: missing.fmu"),
])
def test_cli_errors_are_one_clear_line(args, expected, capsys):
    assert main(args) == 2
    err = capsys.readouterr().err
    assert expected in err and "Traceback" not in err


def test_cli_reports_a_bad_matrix_in_a_scenario_file(tmp_path, capsys):
    path = _bad_scenario(tmp_path, "B1 = [[3.0, 2.0], [4.0, 5.0]]", "B1 = [[3.0, 2.0, 1.0], [4.0, 5.0]]")
    assert main(["run", "--scenario", path, "--T", "1"]) == 2
    assert "B1" in capsys.readouterr().err


def test_cli_reports_an_impossible_design(tmp_path, capsys):
    path = _bad_scenario(tmp_path, "A  = [[-1.0, 0.0], [0.0, -1.0]]", "A  = [[1.0, 0.0], [0.0, -1.0]]")
    path2 = _bad_scenario(Path(path).parent, "B1 = [[3.0, 2.0], [4.0, 5.0]]", "B1 = [[0.0, 0.0], [4.0, 5.0]]")
    # write both changes into one file
    text = Path(path2).read_text().replace("A  = [[-1.0, 0.0], [0.0, -1.0]]", "A  = [[1.0, 0.0], [0.0, -1.0]]")
    Path(path2).write_text(text)
    assert main(["run", "--scenario", path2, "--T", "1", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "not stabilizable" in err and "Traceback" not in err


@pytest.mark.parametrize("args", [["run", "--h", "-1"], ["run", "--estimator", "magic"],
                                  ["compare", "--seeds", "5-1"], ["run", "--seed", "-3"]])
def test_argument_errors_exit_with_usage(args, capsys):
    with pytest.raises(SystemExit) as exc:
        main(args)
    assert exc.value.code == 2
    assert "error" in capsys.readouterr().err


def test_parse_seeds():
    assert parse_seeds("0-3") == [0, 1, 2, 3]
    assert parse_seeds("1,4,7") == [1, 4, 7]
    assert parse_seeds("5") == [5]


def test_console_entry_points_validate(tmp_path):
    exe = Path(sys.executable).with_name("auv-cosim")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "orchestrator"]
    done = subprocess.run(cmd + ["validate"], capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.count("no problem") == 3
    done = subprocess.run([sys.executable, "-m", "orchestrator", "--help"], capture_output=True,
                          text=True, cwd=tmp_path, timeout=60)
    assert done.returncode == 0 and "compare" in done.stdout


def test_build_writes_fmus_and_variable_tables(tmp_path, capsys):
    assert main(["build", "--out", str(tmp_path)]) == 0
    names = sorted(p.name for p in tmp_path.glob("*.fmu"))
    assert names == ["AuvController.fmu", "AuvEstimator.fmu", "AuvPlant.fmu"]


def test_committed_fmu_readme_matches_the_generator():
    from orchestrator.cosim.build import variables_markdown
    from orchestrator.running.fmus import FMU_README_HEAD, fmu_readme, scenario_config
    sc = load_scenario("paper")
    text = (ROOT / "fmus" / "README.md").read_text()
    assert text == fmu_readme(sc)
    assert text.startswith(FMU_README_HEAD.format(scenario=sc.name)
                           + variables_markdown(scenario_config(sc)))
    assert "### AuvGuidance.fmu (guidance)" in text and "`M[i]` (i=1..3)" in text


@pytest.mark.parametrize("fmt", ["osp", "ssp"])
def test_a_refused_export_is_one_line(fmt, tmp_path, capsys, monkeypatch):
    """Both exporters refuse a wiring their FMUs cannot run with one line naming every
    problem (a system that lost its u -> plant connection), exit status 2, nothing written."""
    from dataclasses import replace

    import orchestrator.running.systems as wf
    good = wf.scenario_system
    monkeypatch.setattr(wf, "scenario_system", lambda sc: replace(
        good(sc), connections=tuple(c for c in good(sc).connections if c.target != "plant")))
    out = tmp_path / "x"
    assert main(["export", fmt, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("auv-cosim export: error: export refused: input plant.u[1] is not connected; "
                   "input plant.u[2] is not connected")
    assert not out.exists() or not any(out.rglob("*.xml")) and not any(out.rglob("*.ssp"))
