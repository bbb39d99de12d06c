"""The composition slice through `compare` and `plot`: both architectures over acoustic links
in one compare (each architecture's own FMUs), the plants compared and plotted (each figure
names its plant), and formation-100 per vehicle with native FMUs equal to the pythonfmu run."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from orchestrator.cli import main
from orchestrator.recording import read_rrd_scalars

LINKS = ["--latency", "0.5", "--period", "1.0", "--loss", "0.2"]


@pytest.mark.slow
def test_compare_architectures_over_links_runs_both_and_plots_them(tmp_path, capsys):
    out = tmp_path / "arch"
    assert main(["compare", "--scenario", "formation-4", "--deployment", "per-vehicle",
                 "--what", "architectures", *LINKS, "--T", "4", "--seeds", "0", "--quiet",
                 "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert set(s["methods"]) == {"centralized", "distributed"}
    for name, m in s["methods"].items():
        assert m["architecture"] == name and m["seeds_completed"] == 1
        assert m["network"]["loss"] == 0.2 and m["network"]["links"] > 0
        assert "--predict full" in m["network"]["critical_loss_note"]
    # each architecture's network FMU in its own folder, both named in the summary
    nets = {k: e["path"] for k, e in s["fmus"].items() if k.startswith("network")}
    assert len(nets) == 2 and len(set(nets.values())) == 2
    capsys.readouterr()
    assert main(["plot", str(out), "--format", "svg"]) == 0
    svgs = sorted((out / "figures").glob("*.svg"))
    assert svgs
    for svg in svgs:
        text = svg.read_text()
        assert "centralized" in text and "distributed" in text, svg.name


@pytest.mark.slow
def test_compare_plants_is_plotted_per_plant_with_its_name(tmp_path, capsys):
    out = tmp_path / "plants"
    assert main(["compare", "--scenario", "formation-4", "--deployment", "per-vehicle",
                 "--architecture", "distributed", "--what", "plants", "--T", "3",
                 "--seeds", "0", "--quiet", "--out", str(out)]) == 0
    (out / "figures").mkdir()
    (out / "figures" / "stale.svg").write_text("an earlier run's figure")
    capsys.readouterr()
    assert main(["plot", str(out), "--format", "svg"]) == 0
    for plant in ("remus100", "remus100-6dof"):
        svgs = sorted((out / "figures" / plant).glob("*.svg"))
        assert svgs, plant
        assert all(f"plant {plant}" in p.read_text() for p in svgs), plant
    # a new compare into the folder removes the earlier figures with the earlier run
    assert main(["compare", "--scenario", "formation-4", "--deployment", "per-vehicle",
                 "--architecture", "distributed", "--what", "plants", "--T", "2",
                 "--seeds", "0", "--quiet", "--out", str(out)]) == 0
    assert not (out / "figures").exists()


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler (cc) for native FMUs")
def test_formation_100_per_vehicle_native_equals_pythonfmu(tmp_path, capsys):
    """301 FMUs per run: every linear one native (leader, vehicles, estimators, distributed
    controllers) gives the pythonfmu run's traces to 1e-12 of each signal's scale."""
    runs = {}
    for fmus in ("python", "native"):
        out = tmp_path / fmus
        assert main(["run", "--scenario", "formation-100", "--deployment", "per-vehicle",
                     "--architecture", "distributed", "--T", "0.3", "--quiet", "--fmus", fmus,
                     "--predict", "none",
                     "--out", str(out)]) == 0
        s = json.loads((out / "summary.json").read_text())
        runs[fmus] = (s, read_rrd_scalars(out / "formation-100.rrd"))
    (sp, rp), (sn, rn) = runs["python"], runs["native"]
    assert {e["kind"] for e in sn["fmus"].values()} == {"native"}
    assert set(rp) == set(rn) and len(rp) > 400
    for entity, (_, _, values) in rp.items():
        scale = max(float(np.nanmax(np.abs(values))), 1e-300)
        assert np.nanmax(np.abs(rn[entity][2] - values)) <= 1e-12 * scale, entity
    (mp,), (mn,) = sp["methods"].values(), sn["methods"].values()
    assert mn["cost_rate"]["mean"] == pytest.approx(mp["cost_rate"]["mean"], rel=1e-12)


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler (cc) for native FMUs")
def test_compare_native_equals_pythonfmu_on_every_seed_and_method(tmp_path, capsys):
    """compare --fmus native: each method's own native FMUs, every seed's noise (not only
    the scenario's seed) equal to the pythonfmu compare's to 1e-12."""
    per_seed = {}
    for fmus in ("python", "native"):
        out = tmp_path / fmus
        assert main(["compare", "--T", "5", "--seeds", "0-2", "--methods", "kalman,ideal",
                     "--workers", "1", "--quiet", "--fmus", fmus, "--out", str(out)]) == 0
        s = json.loads((out / "summary.json").read_text())
        per_seed[fmus] = {m: s["methods"][m]["cost_rate"]["per_seed"] for m in s["methods"]}
        if fmus == "native":
            assert (out / "fmus" / "native" / "kalman").is_dir()
            assert "FMUs: native" in capsys.readouterr().out
    for m, rates in per_seed["python"].items():
        assert len(set(rates)) == 3                       # three different noise draws
        assert per_seed["native"][m] == pytest.approx(rates, rel=1e-12)
