"""Figures that say what the data say: the paper figures as the whole run's noise envelope
beside a zoom after the transient, fleet paths framed on the data, fleet errors with the
transient marked and the window zoomed, campaign SVGs with full legends, a y label and
round ticks. Real run folders made with the CLI."""
from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from matplotlib.collections import PolyCollection
from matplotlib.patches import Rectangle

from orchestrator.campaign.aggregate import aggregate_rows
from orchestrator.campaign.plot import Y_LABEL, nice_ticks, write_plots
from orchestrator.plotting.fleet import _PATH_MARGIN
from orchestrator.plotting.window import BINS, ZOOM_S, envelope
from support.plots import figures_of, made_runs

METHODS = ("kalman", "classical", "ideal")


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """A paper compare of 40 s (4000 samples: the whole run is binned) and a formation-4
    run of 30 s."""
    base = tmp_path_factory.mktemp("readable")
    made = {"compare": ["compare", "--T", "40", "--seeds", "0"],
            "fleet": ["run", "--scenario", "formation-4", "--T", "30"]}
    return made_runs(base, made)


def _figures(folder):
    return figures_of(folder)


def test_envelope_holds_every_sample_of_its_bin():
    t = np.arange(1000) * 0.01
    v = np.sin(t) + np.random.default_rng(0).normal(size=1000)
    v[17] = np.nan
    env = envelope(t, v, bins=10)
    for b in range(10):
        seg = v[100 * b:100 * (b + 1)]
        assert env.lo[b] == np.nanmin(seg) and env.hi[b] == np.nanmax(seg)
        assert env.mean[b] == pytest.approx(np.nanmean(seg))


@pytest.mark.slow
def test_paper_figures_have_the_whole_run_envelope_beside_a_zoom(folders):
    folder = folders["compare"]
    summary = json.loads((folder / "summary.json").read_text())
    t0 = summary["stats_window_s"][0]
    zoom = (math.ceil(t0), math.ceil(t0) + ZOOM_S)
    figs = _figures(folder)
    for name in ("error-1", "error-2", "control-1", "control-2"):
        pf = figs[name]
        whole, zoomed = pf.figure.axes
        assert whole.get_title(loc="left").startswith("whole run: min-max per")
        assert zoomed.get_title(loc="left").startswith(
            f"zoom: t in [{zoom[0]:.4g}, {zoom[1]:.4g}] s")
        assert zoomed.get_xlim() == pytest.approx(zoom)
        # the whole run: per method a band (the min and max per bin) and its mean line
        bands = [c for c in whole.collections if isinstance(c, PolyCollection)]
        assert len(bands) == len(METHODS)
        means = [ln for ln in whole.lines if len(ln.get_xdata()) == BINS]
        assert len(means) == len(METHODS)
        lo, hi = whole.get_ylim()
        for line in pf.series.values():                # the full range on the whole run
            assert lo <= np.nanmin(line.get_ydata()) and np.nanmax(line.get_ydata()) <= hi
        # the zoom is scaled to the window, not to the run
        zlo, zhi = zoomed.get_ylim()
        inside = [ln.get_ydata()[(ln.get_xdata() >= zoom[0]) & (ln.get_xdata() <= zoom[1])]
                  for ln in pf.series.values()]
        assert zlo <= min(x.min() for x in inside) and max(x.max() for x in inside) <= zhi
        assert zhi - zlo <= 1.2 * (max(x.max() for x in inside) - min(x.min() for x in inside))
        # the zoomed window is marked on the whole run
        spans = [p for p in whole.patches if isinstance(p, Rectangle)]
        assert any(p.get_x() == pytest.approx(zoom[0]) for p in spans)
    state = figs["state-1"]
    assert len(state.figure.axes) == 2 * len(METHODS)
    assert [ax.get_title(loc="left")[:4] for ax in state.figure.axes] == ["whol", "zoom"] * 3


def test_fleet_paths_are_framed_on_the_data_and_to_scale(folders):
    pf = _figures(folders["fleet"])["fleet-paths"]
    (ax,) = pf.figure.axes
    xs = np.concatenate([ln.get_xdata() for ln in pf.series.values()])
    ys = np.concatenate([ln.get_ydata() for ln in pf.series.values()])
    extent = max(np.ptp(xs), np.ptp(ys))
    slack = _PATH_MARGIN * extent + 1e-9
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    for lim, data in (((x0, x1), xs), ((y0, y1), ys)):
        assert lim[0] <= data.min() and data.max() <= lim[1]            # nothing cut
        assert data.min() - lim[0] <= slack and lim[1] - data.max() <= slack  # none empty
    pf.figure.canvas.draw()
    box = ax.get_window_extent()
    assert box.height / box.width == pytest.approx((y1 - y0) / (x1 - x0), rel=0.02)


def test_fleet_errors_mark_the_transient_and_zoom_on_the_window(folders):
    folder = folders["fleet"]
    summary = json.loads((folder / "summary.json").read_text())
    t0, t_end = summary["stats_window_s"]
    pf = _figures(folder)["fleet-errors"]
    whole, zoom = pf.figure.axes
    (shade,) = [p for p in whole.patches if isinstance(p, Rectangle)]
    assert shade.get_x() == pytest.approx(0.0)
    assert shade.get_x() + shade.get_width() == pytest.approx(t0)
    assert zoom.get_xlim()[0] == pytest.approx(t0)
    assert zoom.get_xlim()[1] == pytest.approx(t_end, abs=0.1)     # the last sample
    window_max = max(ln.get_ydata()[ln.get_xdata() >= t0].max() for ln in pf.series.values())
    whole_max = max(ln.get_ydata().max() for ln in pf.series.values())
    assert whole_max > 2 * window_max                   # the transient dwarfs the window ...
    assert zoom.get_ylim()[1] <= 1.1 * window_max       # ... and the zoom is not squashed
    labels = [t.get_text() for t in zoom.get_legend().get_texts()]
    assert labels[:4] == [f"vehicle {i}" for i in range(1, 5)]
    assert "start-up transient" in labels[-1]


def _campaign_rows():
    rows = []
    grid = [(e, T, lat) for e in ("kalman", "classical") for T in (5.0, 10.0)
            for lat in (0.5, 1.0)]
    for point, (est, T, lat) in enumerate(grid):
        for seed in range(3):
            cr = (10.0 if est == "kalman" else 300.0) + 3 * T + 20 * seed + 7 * lat
            rows.append({"point": point, "seed": seed, "engine": "fmu", "status": "ok",
                         "params": json.dumps({"simulation.estimator": est,
                                               "network.latency": lat, "simulation.T": T}),
                         "error": None, "cost_rate": cr, "predicted_cost_rate": cr - 5.0,
                         "rms_e": [1.0, 2.0], "wall_s": 0.5, "predicted_rms_e": [2.0, 2.0],
                         "rms_u": [0.1, 0.2], "predicted_rms_u": [0.1, 0.2]})
    return rows


def test_campaign_svg_has_full_legends_a_y_label_and_round_ticks(tmp_path):
    agg = aggregate_rows(_campaign_rows())
    write_plots(agg, tmp_path)
    svg = ET.parse(tmp_path / "cost_simulation.T.svg").getroot()
    ns = "{http://www.w3.org/2000/svg}"
    series = [f"simulation.estimator={e}, network.latency={lat}"
              for e in ("kalman", "classical") for lat in ("0.5", "1.0")]
    assert all(len(s) > 28 for s in series)          # each longer than the old cut
    entries = [g for g in svg.iter(f"{ns}g") if g.get("class") == "legend-entry"]
    shown = [" ".join(ts.text for ts in g.iter(f"{ns}tspan")) for g in entries]
    assert shown == series
    assert all(len(ts.text) <= 30 or " " not in ts.text       # a long word stays whole
               for g in entries for ts in g.iter(f"{ns}tspan"))
    assert any(len(list(g.iter(f"{ns}tspan"))) > 1 for g in entries)      # wrapped
    (ylabel,) = [t for t in svg.iter(f"{ns}text") if t.get("class") == "ylabel"]
    assert ylabel.text == Y_LABEL and "(" in Y_LABEL     # with its unit
    ticks = [float(t.text) for t in svg.iter(f"{ns}text") if t.get("class") == "ytick"]
    assert len(ticks) >= 3
    steps = np.diff(ticks)
    assert np.allclose(steps, steps[0])
    mantissa = steps[0] / 10 ** math.floor(math.log10(steps[0]))
    assert round(mantissa, 6) in (1.0, 2.0, 2.5, 5.0)
    assert all(abs(v / steps[0] - round(v / steps[0])) < 1e-9 for v in ticks)


def test_nice_ticks_are_round_and_cover_the_range():
    ticks = nice_ticks(-42.91, 682.2)
    assert ticks[0] <= -42.91 and ticks[-1] >= 682.2
    assert ticks == [-200.0, 0.0, 200.0, 400.0, 600.0, 800.0]
    assert nice_ticks(0.013, 0.0171)[:2] == [0.013, 0.014]
