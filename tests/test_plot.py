"""``auv-cosim plot``: static figures of real run folders (a run, a compare, a fleet run made
with the CLI on short horizons), checked against the .rrd they were drawn from."""
from __future__ import annotations

import json
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

from orchestrator.cli import main
from orchestrator.plotting import build_figures, deterministic_style, load_run
from orchestrator.plotting.figure import DPI
from orchestrator.recording import (
    read_rrd_points,
    read_rrd_scalars,
    read_rrd_series,
    read_rrd_series_lines,
)

PAPER_FIGURES = ("error-1", "error-2", "state-1", "state-2", "control-1", "control-2")
FLEET_FIGURES = ("fleet-paths", "fleet-errors")
METHODS = ("kalman", "classical", "ideal")


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Three real run folders: a paper run, a paper compare (one seed), a formation-4 run."""
    base = tmp_path_factory.mktemp("plot_runs")
    made = {"run": ["run", "--T", "5"], "compare": ["compare", "--T", "5", "--seeds", "0"],
            "fleet": ["run", "--scenario", "formation-4", "--T", "10"]}
    for name, argv in made.items():
        assert main([*argv, "--out", str(base / name), "--quiet"]) == 0
    return {name: base / name for name in made}


def _svg_text(path: Path) -> str:
    """Every text of an SVG that parses as XML: matplotlib draws text as paths and keeps
    the string in a comment before each, so read the comments."""
    parser = ET.XMLParser(target=ET.TreeBuilder(insert_comments=True))
    root = ET.fromstring(path.read_bytes(), parser=parser)
    assert root.tag.endswith("svg")
    return "\n".join(el.text or "" for el in root.iter() if el.tag is ET.Comment)


def _figures(folder: Path) -> dict:
    with deterministic_style():
        return {pf.name: pf for pf in build_figures(load_run(folder))}


@pytest.mark.slow
def test_compare_writes_every_figure_in_every_format(runs, capsys):
    folder = runs["compare"]
    assert main(["plot", str(folder), "--format", "png,svg,pdf"]) == 0
    printed = capsys.readouterr().out.splitlines()
    figs = _figures(folder)
    assert list(figs) == list(PAPER_FIGURES)
    out = folder / "figures"
    for name in PAPER_FIGURES:
        for fmt in ("png", "svg", "pdf"):
            path = out / f"{name}.{fmt}"
            assert path.is_file() and str(path) in printed
        w, h = figs[name].figure.get_size_inches()
        png = imread(out / f"{name}.png")
        assert png.shape == (round(h * DPI), round(w * DPI), 4)
        assert png[..., :3].std() > 0.05                      # not a blank image
        pdf = (out / f"{name}.pdf").read_bytes()
        assert pdf.startswith(b"%PDF-") and pdf.rstrip().endswith(b"%%EOF")
        text = _svg_text(out / f"{name}.svg")
        symbol = {"error": "e", "state": "x", "control": "u"}[name.split("-")[0]]
        assert "time t (s)" in text
        assert f"${symbol}_{{{name[-1]}}}$ (model units)" in text    # y-axis label
        for m in METHODS:                                            # legend entries
            assert (f"{m} true" if symbol == "x" else m) in text
    assert "classical estimate" in _svg_text(out / "state-1.svg")
    assert not list(out.glob(".*.part"))                  # no temporary file left
    assert (out / "error-1.png").stat().st_mode & 0o044  # readable by others, like any file


def test_the_lines_drawn_are_the_recorded_data_in_the_recording_colours(runs):
    folder = runs["compare"]
    rrd = folder / "paper.rrd"
    scalars = read_rrd_scalars(rrd)
    styles = read_rrd_series_lines(rrd)
    figs = _figures(folder)
    drawn = {}
    for pf in figs.values():
        drawn.update(pf.series)
    expected = {f"{root}/{i}/{m}" for root in ("error", "control") for i in (1, 2)
                for m in METHODS}
    expected |= {f"state/{i}/{m}/{kind}" for i in (1, 2) for m in METHODS
                 for kind in ("true", "estimate")}
    off_scale = {e for pf in figs.values() for e in pf.clipped}    # a note, not a line
    assert off_scale == {"state/1/classical/estimate", "state/2/classical/estimate"}
    assert set(drawn) == expected - off_scale
    for entity, line in drawn.items():
        _, t_ns, values = scalars[entity]
        np.testing.assert_array_equal(line.get_xdata(), t_ns / 1e9)
        np.testing.assert_array_equal(line.get_ydata(), values)
        rgba = styles[entity][1][0]
        np.testing.assert_allclose(line.get_color(), np.array(rgba[:3]) / 255, atol=1 / 255)


def test_state_axes_hold_the_true_state_and_note_the_classical_spikes(runs):
    folder = runs["compare"]
    scalars = read_rrd_scalars(folder / "paper.rrd")
    figs = _figures(folder)
    for i in (1, 2):
        pf = figs[f"state-{i}"]
        axes = pf.figure.axes
        assert len(axes) == 6               # per method a row: the whole run and the zoom
        whole = axes[0::2]
        lo, hi = whole[0].get_ylim()
        assert all(ax.get_ylim() == (lo, hi) for ax in whole)
        for m in METHODS:
            true = scalars[f"state/{i}/{m}/true"][2]
            assert lo < true.min() and true.max() < hi
        spikes = scalars[f"state/{i}/classical/estimate"][2]
        assert spikes.min() < lo or spikes.max() > hi
        assert hi - lo < 0.5 * (spikes.max() - spikes.min())   # not scaled to the spikes
        assert set(pf.clipped) == {f"state/{i}/classical/estimate"}
        assert pf.clipped[f"state/{i}/classical/estimate"] == (spikes.min(), spikes.max())
        assert "classical estimate leaves it" in pf.figure.get_suptitle()
        # the note sits in the classical panel, with the range; nothing drawn off the axis
        notes = [t.get_text() for t in whole[1].texts]
        assert notes == [f"classical estimate off this scale: it spans {spikes.min():.3g} to "
                         f"{spikes.max():.3g} (not drawn)"]
        legend = [t.get_text() for t in axes[3].get_legend().get_texts()]
        assert legend == ["classical true"]
    # the error and control figures show every method's full range on the whole run
    for name in ("error-1", "control-1"):
        whole, zoom = figs[name].figure.axes
        lo, hi = whole.get_ylim()
        for line in figs[name].series.values():
            assert lo <= line.get_ydata().min() and line.get_ydata().max() <= hi
        legend = [t.get_text() for t in zoom.get_legend().get_texts()]
        assert legend == list(METHODS)


@pytest.mark.slow
def test_a_run_plots_its_one_method_in_png_and_svg_by_default(runs, capsys):
    folder = runs["run"]
    assert main(["plot", str(folder)]) == 0
    out = folder / "figures"
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == sorted(
        f"{n}.{f}" for n in PAPER_FIGURES for f in ("png", "svg"))
    text = _svg_text(out / "state-1.svg")
    assert "kalman true" in text and "kalman estimate" in text
    assert "classical" not in text and "ideal" not in text
    assert "clipped" not in text
    figs = _figures(folder)
    assert {e.split("/")[2] for pf in figs.values() for e in pf.series} == {"kalman"}


@pytest.mark.slow
def test_two_plots_of_a_run_are_byte_identical(runs, tmp_path):
    folder = runs["compare"]
    for k in (1, 2):
        assert main(["plot", str(folder), "--format", "svg", "--out",
                     str(tmp_path / str(k))]) == 0
    for name in PAPER_FIGURES:
        for fmt in ("svg",):
            a = (tmp_path / "1" / f"{name}.{fmt}").read_bytes()
            assert a == (tmp_path / "2" / f"{name}.{fmt}").read_bytes(), f"{name}.{fmt}"


@pytest.mark.slow
def test_a_fleet_gets_its_paths_and_error_norms(runs, tmp_path, capsys):
    folder = runs["fleet"]
    rrd = folder / "formation-4.rrd"
    for k in (1, 2):
        assert main(["plot", str(folder), "--format", "png,svg,pdf", "--out",
                     str(tmp_path / str(k))]) == 0
    for name in FLEET_FIGURES:
        for fmt in ("png", "svg", "pdf"):
            a = (tmp_path / "1" / f"{name}.{fmt}").read_bytes()
            assert a == (tmp_path / "2" / f"{name}.{fmt}").read_bytes(), f"{name}.{fmt}"
    paths_text = _svg_text(tmp_path / "1" / "fleet-paths.svg")
    for label in ("east (m)", "north (m)", "leader", "vehicle 1", "vehicle 4", "start", "end",
                  "target at end"):
        assert label in paths_text
    assert r"$\|e_i\|$ (m)" in _svg_text(tmp_path / "1" / "fleet-errors.svg")  # units: m

    figs = _figures(folder)
    assert list(figs) == list(FLEET_FIGURES)
    paths = figs["fleet-paths"].series
    _, _, pos = read_rrd_points(rrd, "world/kalman/vehicles")
    assert pos.shape[1] == 4
    for i in range(4):              # east on x, north on y
        np.testing.assert_array_equal(paths[f"world/kalman/vehicles[{i}]"].get_xdata(),
                                      pos[:, i, 1])
        np.testing.assert_array_equal(paths[f"world/kalman/vehicles[{i}]"].get_ydata(),
                                      pos[:, i, 0])
    _, _, lead = read_rrd_points(rrd, "world/kalman/leader")
    np.testing.assert_array_equal(paths["world/kalman/leader"].get_ydata(), lead[:, 0, 0])
    _, _, targets = read_rrd_points(rrd, "world/kalman/targets")
    np.testing.assert_array_equal(paths["world/kalman/targets[-1]"].get_xdata(),
                                  targets[-1, :, 1])
    errors = figs["fleet-errors"].series
    for i in range(1, 5):
        _, t_ns, e = read_rrd_series(rrd, f"vehicles/{i}/error/kalman")
        line = errors[f"vehicles/{i}/error/kalman:norm"]
        np.testing.assert_array_equal(line.get_xdata(), t_ns / 1e9)
        np.testing.assert_allclose(line.get_ydata(), np.sqrt((e ** 2).sum(axis=1)), rtol=1e-12)


def _one_line_error(capsys, argv, *fragments):
    assert main(argv) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith("auv-cosim plot: error: "), err
    for f in fragments:
        assert f in err, err
    return err


def test_bad_input_is_one_line_and_exit_status_2(runs, tmp_path, capsys):
    good = runs["compare"]
    bad = tmp_path / "bad"
    bad.mkdir()
    _one_line_error(capsys, ["plot", str(tmp_path / "none")], "does not exist")
    _one_line_error(capsys, ["plot", str(bad)], "is not a run folder", "no summary.json")
    (bad / "file").write_text("x")
    _one_line_error(capsys, ["plot", str(bad / "file")], "is not a folder")
    (bad / "summary.json").write_text("{not json")
    _one_line_error(capsys, ["plot", str(bad)], "summary.json is not a run summary",
                    "not valid JSON")
    (bad / "summary.json").write_text(json.dumps({"scenario": "paper"}))
    _one_line_error(capsys, ["plot", str(bad)], "summary.json is not a run summary")
    summary = json.loads((good / "summary.json").read_text())
    (bad / "summary.json").write_text(json.dumps(summary))
    _one_line_error(capsys, ["plot", str(bad)], "paper.rrd is missing")
    rrd = (good / "paper.rrd").read_bytes()
    (bad / "paper.rrd").write_bytes(rrd[: len(rrd) // 2])               # cut short
    _one_line_error(capsys, ["plot", str(bad)], "paper.rrd cannot be read as a recording")
    (bad / "paper.rrd").write_bytes(b"not a recording" * 10)
    _one_line_error(capsys, ["plot", str(bad)], "paper.rrd cannot be read as a recording",
                    "Not an RRD file")
    shutil.copyfile(runs["fleet"] / "formation-4.rrd", bad / "paper.rrd")   # another run's
    _one_line_error(capsys, ["plot", str(bad)], "holds no traces of classical, ideal",
                    "not this run's recording")
    one = {**summary, "methods": {"kalman": summary["methods"]["kalman"]}}
    (bad / "summary.json").write_text(json.dumps(one))
    _one_line_error(capsys, ["plot", str(bad)], "holds 200 samples per series but "
                    "summary.json says 500")
    (bad / "summary.json").write_text(json.dumps({**summary, "rrd": {"path": None}}))
    _one_line_error(capsys, ["plot", str(bad)], "recorded no traces")
    for fmt, fragment in (("png,gif", "gif is not one of png, svg, pdf"),
                          ("", "give one or more of png, svg, pdf")):
        _one_line_error(capsys, ["plot", str(good), "--format", fmt], fragment)
    _one_line_error(capsys, ["plot", str(good), "--out", str(bad / "file" / "figs")],
                    "is under a file")
    assert not (bad / "figures").exists()


def test_the_state_limits_ignore_what_a_diverged_run_leaves():
    from orchestrator.plotting.paper import _limits
    true = np.array([0.0, 1.0, np.inf, np.nan])
    ylim, clipped = _limits([true], {"near": np.array([0.2, 1.1]), "far": np.array([-50.0, 50.0]),
                                     "gone": np.array([np.nan])})
    assert ylim[0] < 0.0 and 1.1 < ylim[1] < 1.5
    assert clipped == {"far": (-50.0, 50.0)}
    assert np.all(np.isfinite(_limits([np.array([np.nan])], {})[0]))
