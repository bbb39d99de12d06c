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
    err = capsys.readouterr().err
    assert "MassDamper.fmu: design model identified" in err and "fit error RMS" in err
    assert model.A[3, 3] == pytest.approx(-D[0] / M[0], rel=2e-3)
    ident._memo.clear()
    ident._printed.clear()
    again = make_vehicle("fmu", dict(PORTS, fmu=str(fmu)), "vehicle 1")
    assert "from the cache" in capsys.readouterr().err
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
