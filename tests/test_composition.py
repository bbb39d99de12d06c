"""The composition matrix: formation-4 at a short horizon, every combination of deployment
{stacked, per-vehicle centralized, per-vehicle distributed} x links {none, latency + loss} x
vehicle {remus100, remus100-6dof, remus100-6dof-guided} x FMUs {python, native}, through `auv-cosim run`,
and the bursty link model (a Gilbert-Elliott channel per link, from the scenario's
[network]) per-vehicle centralized and distributed x FMUs {python, native}. Each cell
either runs (finite figures, a .rrd that reads back with the expected entities, native equal
to python where both run) or is refused before anything is written, in one line naming the
combination and why. docs/composition.md holds the table this test checks."""
from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from orchestrator.cli import main
from orchestrator.recording import read_rrd_scalars

ROOT = Path(__file__).resolve().parent.parent
DEPLOYMENTS = {"stacked": ["--deployment", "stacked"],
               "centralized": ["--deployment", "per-vehicle", "--architecture", "centralized"],
               "distributed": ["--deployment", "per-vehicle", "--architecture", "distributed"]}
LINKS = {"none": [], "links": ["--latency", "0.5", "--period", "1.0", "--loss", "0.2"]}
VEHICLES = ("remus100", "remus100-6dof", "remus100-6dof-guided")
FMUS = ("python", "native")
#: cells refused, with what the one line must say
REFUSED = {("stacked", "links"): "[network] needs [simulation] deployment = \"per-vehicle\"",
           ("stacked", "remus100-6dof"): "needs [simulation] deployment = \"per-vehicle\"",
           ("stacked", "remus100-6dof-guided"): "needs [simulation] deployment = \"per-vehicle\""}
#: the REMUS 100 vehicle kinds, native with --fmus native (orchestrator.cosim.native_remus)
REMUS_KINDS = ("remus6dof", "remus6dof_actuated")
T = "2.0"
#: the bursty link model's cells: a Gilbert-Elliott channel per link (link_models)
BURSTY_NETWORK = """
[network]
latency = 0.5
period = 0.5
loss_model = "gilbert-elliott"
p_gb = 0.3
p_bg = 0.4
loss_good = 0.05
loss_bad = 0.9
"""

needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler (cc) for the "
                              "native FMUs")


@pytest.fixture(scope="module")
def scenarios(tmp_path_factory):
    folder = tmp_path_factory.mktemp("composition")
    text = (ROOT / "orchestrator/scenario/builtin/formation-4.toml").read_text()
    paths = {}
    for vehicle in VEHICLES:
        paths[vehicle] = folder / f"formation-4-{vehicle}.toml"
        paths[vehicle].write_text(text.replace('model = "remus100"', f'model = "{vehicle}"'))
    paths["bursty"] = folder / "formation-4-bursty.toml"
    paths["bursty"].write_text(text + BURSTY_NETWORK)
    return paths


@pytest.fixture(scope="module")
def runs(scenarios, tmp_path_factory):
    """Every python cell run once (the native cells compare against them)."""
    return {}


def _run(scenarios, tmp, dep, links, vehicle, fmus, capsys):
    out = tmp / f"{dep}-{links}-{vehicle}-{fmus}"
    code = main(["run", "--scenario", str(scenarios[vehicle]), "--T", T, "--seed", "3",
                 "--quiet", "--out", str(out), "--fmus", fmus,
                 *DEPLOYMENTS[dep], *LINKS[links]])
    return code, out, capsys.readouterr()


def _native_equals_python(runs, cell, fmus, scalars, m):
    """Keep a cell's recorded scalars and method summary in ``runs`` under ``cell`` plus
    its FMU kind; once both kinds of the cell ran, check the native one's every signal
    equals the python one's to 1e-12 of that signal's largest magnitude, and its cost rate
    to 1e-12 relative."""
    runs[(*cell, fmus)] = (scalars, m)
    if fmus == "native" and (*cell, "python") in runs:
        ref, mref = runs[(*cell, "python")]
        assert set(ref) == set(scalars)
        for entity, (_, _, values) in ref.items():
            got = scalars[entity][2]
            scale = max(float(np.nanmax(np.abs(values))), 1e-300)
            assert np.nanmax(np.abs(got - values)) <= 1e-12 * scale, entity
        assert m["cost_rate"]["mean"] == pytest.approx(mref["cost_rate"]["mean"], rel=1e-12)


def _refusal(dep, links, vehicle):
    """What the refusal of a cell may say (either reason where two apply), None if it runs."""
    reasons = [REFUSED[k] for k in ((dep, links), (dep, vehicle)) if k in REFUSED]
    return reasons or None


CELLS = [(d, ln, v, f) for d in DEPLOYMENTS for ln in LINKS for v in VEHICLES for f in FMUS]


@pytest.mark.slow
@pytest.mark.parametrize("dep, links, vehicle, fmus", CELLS,
                         ids=["-".join(c) for c in CELLS])
@pytest.mark.slow
def test_every_cell_runs_or_is_refused_in_one_line(scenarios, runs, tmp_path, capsys,
                                                   dep, links, vehicle, fmus):
    if fmus == "native" and shutil.which("cc") is None:
        pytest.skip("no C compiler (cc) for the native FMUs")
    code, out, io = _run(scenarios, tmp_path, dep, links, vehicle, fmus, capsys)
    want = _refusal(dep, links, vehicle)
    if want is not None:
        assert code == 2
        lines = io.err.strip().splitlines()
        assert len(lines) == 1 and any(w in lines[0] for w in want), io.err
        assert not out.exists() or not any(out.iterdir())      # nothing written
        return
    assert code == 0, io.err
    summary = json.loads((out / "summary.json").read_text())
    (m,) = summary["methods"].values()
    assert math.isfinite(m["cost_rate"]["mean"]) and m["seeds_completed"] == 1
    assert summary["fmu_kind"] == fmus and summary["deployment"] == (
        "stacked" if dep == "stacked" else "per-vehicle")
    kinds = {k: e["kind"] for k, e in summary["fmus"].items()}
    if fmus == "python":
        assert set(kinds.values()) == {"python"}
    else:       # every FMU native: the linear forms, the guidance interface, the 6-DOF
        assert set(kinds.values()) == {"native"}, kinds   # vehicles and the network
        assert any(k in REMUS_KINDS for k in kinds) == (vehicle != "remus100")
        if links == "links":
            assert kinds["network"] == "native"
        if vehicle == "remus100-6dof-guided":
            assert kinds["guidance"] == kinds["autopilot"] == "native"
    scalars = read_rrd_scalars(out / f"{summary['scenario']}.rrd")
    for i in range(1, 5):
        assert any(e.startswith(f"vehicles/{i}/error/") for e in scalars), i
    if links == "links":
        assert "network" in m and m["network"]["loss"] == 0.2
        assert any("link" in e for e in scalars)
    if vehicle != "remus100":
        assert any("/propeller/" in e for e in scalars)
    if vehicle == "remus100-6dof-guided":       # guidance -> autopilot -> actuated vehicle
        assert {"guidance", "autopilot", "remus6dof_actuated"} <= set(kinds)
        assert all(f"vehicles/{i}/setpoint/kalman" in scalars for i in range(1, 5))
    _native_equals_python(runs, (dep, links, vehicle), fmus, scalars, m)


@pytest.mark.slow
@needs_cc
@pytest.mark.parametrize("vehicle", ["remus100-6dof", "remus100-6dof-guided"])
def test_native_remus_cells_are_all_native_and_equal_the_python_cells(scenarios, tmp_path,
                                                                      capsys, vehicle):
    """--fmus native runs no pythonfmu FMU, and every recorded signal equals the python
    cell's to 1e-12 of its largest magnitude (measured: 2e-14; docs/native.md)."""
    rec = {}
    for fmus in FMUS:
        code, out, io = _run(scenarios, tmp_path, "distributed", "none", vehicle, fmus, capsys)
        assert code == 0, io.err
        summary = json.loads((out / "summary.json").read_text())
        kinds = {k: e["kind"] for k, e in summary["fmus"].items()}
        assert set(kinds.values()) == {fmus}, kinds
        rec[fmus] = read_rrd_scalars(out / f"{summary['scenario']}.rrd")
    assert set(rec["python"]) == set(rec["native"])
    for entity, (_, _, want) in rec["python"].items():
        got = rec["native"][entity][2]
        scale = max(float(np.max(np.abs(want))) if want.size else 0.0, 1e-300)
        assert got.shape == want.shape and np.max(np.abs(got - want), initial=0.0) <= (
            1e-12 * scale), entity


# --- the time-varying Kalman filter (kalman-tv) ----------------------------------------
TV_REFUSED = {"distributed": "the distributed per-vehicle loop needs estimator kalman or ideal, "
                             "not 'kalman-tv'",
              "links": "needs estimator kalman or classical or ideal, not 'kalman-tv'"}
TV_CELLS = [(d, ln, f) for d in DEPLOYMENTS for ln in LINKS for f in FMUS]


@pytest.fixture(scope="module")
def tv_scenario(tmp_path_factory):
    path = tmp_path_factory.mktemp("composition-tv") / "formation-4-tv.toml"
    path.write_text((ROOT / "orchestrator/scenario/builtin/formation-4.toml").read_text()
                    + "\n[estimator]\nP0 = 4.0\n")
    return path


@pytest.mark.slow
@pytest.mark.parametrize("dep, links, fmus", TV_CELLS, ids=["-".join(c) for c in TV_CELLS])
def test_kalman_tv_cells_run_or_are_refused_in_one_line(tv_scenario, runs, tmp_path, capsys,
                                                        dep, links, fmus):
    """kalman-tv on formation-4 (remus100): stacked and per-vehicle centralized run, python
    and native, native equal to python to 1e-12 of each signal's scale; the distributed
    law and acoustic links refuse it in one line (their analyses need a time-invariant
    estimator)."""
    if fmus == "native" and shutil.which("cc") is None:
        pytest.skip("no C compiler (cc) for the native FMUs")
    out = tmp_path / f"tv-{dep}-{links}-{fmus}"
    code = main(["run", "--scenario", str(tv_scenario), "--T", T, "--seed", "3", "--quiet",
                 "--out", str(out), "--fmus", fmus, "--estimator", "kalman-tv",
                 *DEPLOYMENTS[dep], *LINKS[links]])
    io = capsys.readouterr()
    want = ([REFUSED[("stacked", "links")]] if (dep, links) == ("stacked", "links") else
            [TV_REFUSED["distributed"]] if dep == "distributed" else
            [TV_REFUSED["links"]] if links == "links" else None)
    if want is not None:
        assert code == 2
        lines = io.err.strip().splitlines()
        assert len(lines) == 1 and any(w in lines[0] for w in want), io.err
        assert not out.exists() or not any(out.iterdir())
        return
    assert code == 0, io.err
    summary = json.loads((out / "summary.json").read_text())
    (m,) = summary["methods"].values()
    assert math.isfinite(m["cost_rate"]["mean"]) and math.isfinite(m["cost_rate"]["predicted"])
    kinds = {k: e["kind"] for k, e in summary["fmus"].items()}
    assert set(kinds.values()) == {fmus}, kinds
    scalars = read_rrd_scalars(out / f"{summary['scenario']}.rrd")
    _native_equals_python(runs, ("tv", dep, links), fmus, scalars, m)


BURSTY_CELLS = [(d, f) for d in ("centralized", "distributed") for f in FMUS]


@pytest.mark.slow
@pytest.mark.parametrize("dep, fmus", BURSTY_CELLS, ids=["-".join(c) for c in BURSTY_CELLS])
def test_bursty_link_cells_run_and_native_equals_python(scenarios, runs, tmp_path, capsys,
                                                        dep, fmus):
    """A Gilbert-Elliott channel per link (the link-model registry's second row): the
    per-vehicle fleet runs through the network FMUs (python or native), its summary names
    the model and its predictions, and the native cell's every recorded signal equals the
    python cell's to 1e-12 of its scale."""
    if fmus == "native" and shutil.which("cc") is None:
        pytest.skip("no C compiler (cc) for the native FMUs")
    out = tmp_path / f"{dep}-bursty-{fmus}"
    code = main(["run", "--scenario", str(scenarios["bursty"]), "--T", T, "--seed", "3",
                 "--quiet", "--out", str(out), "--fmus", fmus, *DEPLOYMENTS[dep]])
    io = capsys.readouterr()
    assert code == 0, io.err
    summary = json.loads((out / "summary.json").read_text())
    (m,) = summary["methods"].values()
    assert math.isfinite(m["cost_rate"]["mean"]) and math.isfinite(m["cost_rate"]["predicted"])
    net = m["network"]
    assert net["loss_model"] == "gilbert-elliott" and len(net["bursty_links"]) == net["links"]
    assert net["bursty_links"]["leader -> 1"]["mean_burst"] == pytest.approx(2.5)
    kinds = {k: e["kind"] for k, e in summary["fmus"].items()}
    assert kinds["network"] == fmus
    scalars = read_rrd_scalars(out / f"{summary['scenario']}.rrd")
    # network/links/{j}-{i}: delivered, lost, in flight
    lost = [v[-1, 1] for e, (_, _, v) in scalars.items() if e.startswith("network/links/")]
    assert len(lost) == net["links"] and sum(lost) > 0                  # messages were lost
    _native_equals_python(runs, (dep, "bursty"), fmus, scalars, m)


# --- a vehicle brought as an FMU (model = "fmu": the C mass-damper the tests compile) -----
FMU_CELLS = [(d, ln, f) for d in DEPLOYMENTS for ln in LINKS for f in FMUS]


@pytest.fixture(scope="module")
def fmu_fleet(tmp_path_factory):
    from tests.support.vehicle_fmus import mass_damper_fmu
    folder = tmp_path_factory.mktemp("composition-fmu")
    mass_damper_fmu(folder, (50.0, 60.0, 70.0), (10.0, 20.0, 30.0))
    path = folder / "fmu-fleet.toml"
    path.write_text((ROOT / "tests/data/vehicle-fmu-fleet.toml").read_text())
    return path


@pytest.mark.slow
@needs_cc
@pytest.mark.parametrize("dep, links, fmus", FMU_CELLS, ids=["-".join(c) for c in FMU_CELLS])
def test_vehicle_fmu_cells_run_or_are_refused_in_one_line(fmu_fleet, runs, tmp_path, capsys,
                                                          dep, links, fmus):
    """The user's vehicle FMU in every deployment, links or not, with our FMUs python or
    native: the stacked deployment refuses it in one line; the per-vehicle cells run with
    the user's FMU copied beside ours (compiled code: "native" in the summary, and with
    every other FMU native the compiled master runs the whole system), the native cell
    equal to the python one to 1e-12 of each signal's scale."""
    out = tmp_path / f"fmu-{dep}-{links}-{fmus}"
    code = main(["run", "--scenario", str(fmu_fleet), "--T", T, "--seed", "3", "--quiet",
                 "--out", str(out), "--fmus", fmus, *DEPLOYMENTS[dep], *LINKS[links]])
    io = capsys.readouterr()
    if dep == "stacked":
        assert code == 2
        lines = io.err.strip().splitlines()
        assert len(lines) == 1 and ("deployment = \"per-vehicle\"" in lines[0]), io.err
        assert not out.exists() or not any(out.iterdir())
        return
    assert code == 0, io.err
    summary = json.loads((out / "summary.json").read_text())
    (m,) = summary["methods"].values()
    assert math.isfinite(m["cost_rate"]["mean"])
    fmus_run = summary["fmus"]
    assert fmus_run["vehicle_fmu"]["user"] is True and fmus_run["vehicle_fmu"]["kind"] == "native"
    assert {e["kind"] for k, e in fmus_run.items() if k != "vehicle_fmu"} == {fmus}
    if fmus == "native":
        assert set(summary["master"].values()) == {"native"}
    scalars = read_rrd_scalars(out / f"{summary['scenario']}.rrd")
    for i in range(1, 5):
        assert any(e.startswith(f"vehicles/{i}/error/") for e in scalars), i
    runs[("fmu", dep, links, fmus)] = (scalars, m)
    if fmus == "native" and ("fmu", dep, links, "python") in runs:
        ref, mref = runs[("fmu", dep, links, "python")]
        assert set(ref) == set(scalars)
        # 1e-12 of the vehicle's largest signal: with no current in this fleet the current
        # estimates are rounding noise of 1e-7 m/s, whose own scale means nothing
        group: dict[str, float] = {}
        for entity, (_, _, values) in ref.items():
            g = "/".join(entity.split("/")[:2])
            group[g] = max(group.get(g, 0.0), float(np.nanmax(np.abs(values))))
        for entity, (_, _, values) in ref.items():
            got = scalars[entity][2]
            scale = max(group["/".join(entity.split("/")[:2])], 1e-300)
            assert np.nanmax(np.abs(got - values)) <= 1e-12 * scale, entity
