"""model = "fmu": a vehicle the user brings as an FMU (plant_model/vehicle_fmu.py,
plant_model/vehicle_fmu_identification.py), with a C mass-damper FMU the test compiles: its M
and D are the identification's independent reference."""
from __future__ import annotations

import json
import shutil
import zipfile
from pathlib import Path

import pytest

from orchestrator.cli import main
from plant_model import vehicle_fmu_identification as ident
from plant_model.linalg_checks import ModelError
from plant_model.vehicle_models import make_vehicle
from tests.support.vehicle_fmus import mass_damper_fmu

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
M, D = (50.0, 60.0, 70.0), (10.0, 20.0, 30.0)
PORTS = {"inputs": {"force": ["F_n", "F_e", "F_d"]},
         "outputs": {"position": ["n", "e", "d"], "velocity": ["v_n", "v_e", "v_d"]},
         "start": {"position": ["n0", "e0", "d0"], "velocity": ["vn0", "ve0", "vd0"]},
         "horizontal": "separate"}
FLEET = Path(__file__).parent / "data" / "vehicle-fmu-fleet.toml"


@pytest.fixture(scope="module")
def fmu(tmp_path_factory) -> Path:
    return mass_damper_fmu(tmp_path_factory.mktemp("vfmu"), M, D)


def test_mass_damper_is_identified_to_its_own_mass_and_damping(fmu, capsys):
    """Within 0.2 % (measured 0.04 %), the fit printed; a second build reads the cache."""
    ident._memo.clear()
    model = make_vehicle("fmu", dict(PORTS, fmu=str(fmu)), "vehicle 1")
    fit = model.parameters["fit"]
    assert fit["M"] == pytest.approx(M, rel=2e-3) and fit["D"] == pytest.approx(D, rel=2e-3)
    assert fit["max_error"] < 0.01
    printed = capsys.readouterr().out
    assert "MassDamper.fmu: design model identified" in printed and "fit error RMS" in printed
    assert model.A[3, 3] == pytest.approx(-D[0] / M[0], rel=2e-3)
    ident._memo.clear()
    ident._printed.clear()
    again = make_vehicle("fmu", dict(PORTS, fmu=str(fmu)), "vehicle 1")
    assert "from the cache" in capsys.readouterr().out
    assert again.parameters["fit"]["M"] == fit["M"]


@pytest.mark.parametrize("change, words", [
    ({"fmu": "nowhere.fmu"}, ["fmu: no file 'nowhere.fmu'"]),
    ({"outputs": {"position": ["n", "east", "d"], "velocity": ["v_n", "v_e", "v_d"]}},
     ["fmu port outputs.position[2]", "no variable 'east'"]),
    ({"outputs": {"position": ["n", "F_e", "d"], "velocity": ["v_n", "v_e", "v_d"]}},
     ["fmu port outputs.position[2]", "'F_e'", "is input, not output"]),
    ({"inputs": {"force": ["F_n", "F_e", "M_d"]}},
     ["fmu port inputs.force[3]", "'M_d'", "is parameter, not input"]),
])
def test_a_bad_port_map_is_refused_in_one_line_naming_vehicle_port_and_variable(
        fmu, change, words):
    with pytest.raises(ModelError) as exc:
        make_vehicle("fmu", {**PORTS, "fmu": str(fmu), **change}, "vehicle 3")
    msg = str(exc.value)
    assert msg.startswith("vehicle 3: ") and "\n" not in msg
    assert all(w in msg for w in words), msg


def test_a_model_exchange_fmu_is_refused(fmu, tmp_path):
    me = tmp_path / "me.fmu"
    with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(me, "w") as dst:
        for item in src.namelist():
            data = src.read(item)
            if item == "modelDescription.xml":
                data = data.replace(b"<CoSimulation", b"<ModelExchange")
            dst.writestr(item, data)
    with pytest.raises(ModelError, match="vehicle 2: fmu: me.fmu is not a co-simulation FMU"):
        make_vehicle("fmu", {**PORTS, "fmu": str(me)}, "vehicle 2")


def _fleet(tmp_path: Path, fmu: Path) -> Path:
    shutil.copy2(fmu, tmp_path / "MassDamper.fmu")
    path = tmp_path / "fleet.toml"
    path.write_text(FLEET.read_text())
    return path


@pytest.mark.parametrize("args", [
    [], ["--architecture", "centralized"], ["--latency", "0.5", "--period", "1.0",
                                            "--loss", "0.2"], ["--fmus", "native"]],
    ids=["distributed", "centralized", "links", "native"])
def test_a_fleet_of_four_vehicle_fmus_holds_its_formation(fmu, tmp_path, capsys, args):
    """From the TOML file and the FMU alone (its path relative to the file): within 3 m
    max and 1.5 m RMS after the transient, on a straight leader at 1.5 m/s."""
    out = tmp_path / "out"
    code = main(["run", "--scenario", str(_fleet(tmp_path, fmu)), "--quiet", "--out",
                 str(out), *args])
    assert code == 0, capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    m = summary["methods"]["kalman"]
    assert m["max_error"] < 3.0 and max(m["rms_e"]["mean"]) < 1.5
    assert (out / "fmus" / "MassDamper.fmu").exists() or any(
        p.name == "MassDamper.fmu" for p in out.rglob("*.fmu"))
    if "--fmus" in args:               # the C vehicle FMU runs in the compiled master
        assert set(summary["master"].values()) == {"native"}


def test_the_stacked_deployment_refuses_a_vehicle_fmu_in_one_line(fmu, tmp_path, capsys):
    code = main(["run", "--scenario", str(_fleet(tmp_path, fmu)), "--quiet", "--out",
                 str(tmp_path / "out"), "--deployment", "stacked"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert "vehicle model fmu needs [simulation] deployment = \"per-vehicle\"" in err[0]


@pytest.mark.slow
def test_the_native_export_with_the_vehicle_fmu_runs_in_the_c_host(fmu, tmp_path):
    """`auv-cosim export native` of the fleet carries the user's FMU beside ours; the C host
    (no Python anywhere) runs the 200 s and every vehicle ends at the leader plus its
    offset (the leader at 1.5 m/s north from (0, 0, 20))."""
    import csv
    import subprocess

    from orchestrator.benchmarks.native import c_host_binary
    from orchestrator.interop.c_host import write_c_host_system_from_osp
    out = tmp_path / "export"
    assert main(["export", "native", "--scenario", str(_fleet(tmp_path, fmu)), "--quiet",
                 "--out", str(out)]) == 0
    assert (out / "MassDamper.fmu").is_file()
    system = write_c_host_system_from_osp(out / "OspSystemStructure.xml", tmp_path / "host")
    exe = c_host_binary(tmp_path / "bin")
    r = subprocess.run([str(exe), str(system), "4000", "0.05", str(tmp_path / "host.csv")],
                       capture_output=True, text=True, env={})
    assert r.returncode == 0, r.stderr
    rows = list(csv.reader((tmp_path / "host.csv").open()))
    head, last = rows[0], [float(x) for x in rows[-1]]
    t = last[0]
    offsets = [(10.0, 0.0, 0.0), (0.0, -10.0, 0.0), (0.0, 10.0, 0.0), (-10.0, 0.0, 0.0)]
    for i, off in enumerate(offsets, start=1):
        # the mass-damper's outputs n, e, d are its value references 3, 4, 5
        pos = [last[head.index(f"vehicle_{i}.{vr}")] for vr in (3, 4, 5)]
        want = (1.5 * t + off[0], off[1], 20.0 + off[2])
        assert max(abs(p - w) for p, w in zip(pos, want)) < 0.1, (i, pos, want)


TORPEDO_INPUTS = 'inputs = { speed = "U_d", heading = "psi_d", depth = "d_d", depth_rate = "dd_d" }'


@pytest.mark.slow
def test_a_fleet_of_four_torpedo_fmus_holds_its_formation(tmp_path, capsys):
    """docs/examples/torpedo.py (Prestero's equations, a PID autopilot with the depth rate fed
    forward) as a pythonfmu set-point FMU: identified through the guidance (fit printed),
    then four of them on a straight leader at 1.5 m/s hold within 3 m max and 1.5 m RMS
    after the transient, through our guidance FMU and the distributed law."""
    from tests.support.vehicle_fmus import torpedo_fmu
    torpedo_fmu(tmp_path)
    text = FLEET.read_text().replace('fmu = "MassDamper.fmu"', 'fmu = "TorpedoSetpoint.fmu"')
    text = text.replace('inputs = { force = ["F_n", "F_e", "F_d"] }', TORPEDO_INPUTS)
    scenario = tmp_path / "torpedoes.toml"
    scenario.write_text(text.replace('horizontal = "separate"\n', ""))
    out = tmp_path / "out"
    code = main(["run", "--scenario", str(scenario), "--out", str(out)])
    io = capsys.readouterr()
    assert code == 0, io.err
    fit = [line for line in (io.out + io.err).splitlines()
           if "TorpedoSetpoint.fmu: design model identified (set-points" in line]
    assert fit and "fit error RMS" in fit[0]
    summary = json.loads((out / "summary.json").read_text())
    m = summary["methods"]["kalman"]
    assert m["max_error"] < 3.0 and max(m["rms_e"]["mean"]) < 1.5
    assert summary["fmus"]["vehicle_fmu"] == {**summary["fmus"]["vehicle_fmu"],
                                              "kind": "python", "user": True}


@pytest.mark.slow
def test_compare_and_a_campaign_run_the_vehicle_fmu_fleet_from_its_files(fmu, tmp_path, capsys):
    """No code: `compare` of the two tracking laws and a campaign over both architectures
    (its base the fleet file, the FMU beside it) run the user's FMU; every row is whole
    and the campaign's rows equal a plain `run` of the same point."""
    fleet = _fleet(tmp_path, fmu)
    out = tmp_path / "compare"
    assert main(["compare", "--scenario", str(fleet), "--T", "10", "--quiet", "--out",
                 str(out)]) == 0, capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["methods"]) == {"lq", "regulator"}
    assert all(m["max_error"] < 3.0 for m in summary["methods"].values())
    spec = tmp_path / "campaign.toml"
    spec.write_text('base = "fleet.toml"\nseeds = "0-1"\nengine = "fmu"\n\n[sweep]\n'
                    '"simulation.architecture" = ["centralized", "distributed"]\n'
                    '"simulation.T" = [10.0]\n')
    assert main(["campaign", str(spec), "--workers", "1", "--quiet", "--out",
                 str(tmp_path / "campaign")]) == 0, capsys.readouterr().err
    import pyarrow.parquet as pq
    rows = pq.read_table(tmp_path / "campaign" / "results.parquet").to_pylist()
    assert len(rows) == 4 and all(r["status"] == "ok" and r["error"] is None for r in rows)
    run_out = tmp_path / "run"
    assert main(["run", "--scenario", str(fleet), "--T", "10", "--seed", "1", "--quiet",
                 "--architecture", "centralized", "--out", str(run_out)]) == 0
    one = json.loads((run_out / "summary.json").read_text())["methods"]["kalman"]
    (row,) = [r for r in rows if r["seed"] == 1
              and r["param:simulation.architecture"] == "centralized"]
    assert row["cost_rate"] == pytest.approx(one["cost_rate"]["mean"], rel=1e-12)
