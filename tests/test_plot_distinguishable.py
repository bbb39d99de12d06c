"""What users see in the static figures (issue 38, item 4): every method can be told apart
in every whole-run panel (its own colour and dash or width, none hidden under another),
and the panels of a comparison share their y scale. The figures are drawn by the real
plotting code from real run folders and read back (lines, styles, pixels, limits)."""
from __future__ import annotations

import numpy as np
import pytest
from matplotlib.colors import to_rgb

from orchestrator.plotting.figure import drawing_order, line_styles
from support.plots import figures_of, made_runs

METHODS = ("kalman", "classical", "ideal")


def test_the_ideal_estimator_lies_under_the_kalman_filter_and_the_noisiest_at_the_back():
    spread = {"kalman": 4.7, "classical": 9.1, "ideal": 3.9}
    assert drawing_order(METHODS, spread, {"ideal"}) == ["classical", "ideal", "kalman"]
    assert drawing_order(("a", "b"), {"a": 1.0, "b": 2.0}, set()) == ["b", "a"]
    assert drawing_order(("w",), {}, {"w"}) == ["w"]


def test_every_pair_of_methods_differs_in_colour_and_in_dash_or_width():
    styles = line_styles((*METHODS, "lq", "regulator", "x1", "x2"))
    keys = list(styles.values())
    for i, a in enumerate(keys):
        for b in keys[i + 1:]:
            assert a.color != b.color
    first4 = [styles[m] for m in ("kalman", "classical", "lq", "regulator")]
    assert len({(s.linestyle, s.linewidth) for s in first4}) == 4
    assert styles["ideal"].linewidth > 2 * styles["kalman"].linewidth
    assert styles["ideal"].alpha < 1.0


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """A paper compare of 40 s (4000 samples: the whole run is binned), one of 4 s (every
    sample drawn) and a formation-4 compare of the two laws over 30 s."""
    base = tmp_path_factory.mktemp("distinguishable")
    made = {"compare": ["compare", "--T", "40", "--seeds", "0"],
            "short": ["compare", "--T", "4", "--seeds", "0"],
            "fleet": ["compare", "--scenario", "formation-4", "--T", "30", "--seeds", "0"]}
    return made_runs(base, made)


def _figures(folder):
    return figures_of(folder)


def _pixels(fig, ax) -> np.ndarray:
    """The RGB pixels of ``ax`` in the figure as drawn."""
    fig.canvas.draw()
    img = np.asarray(fig.canvas.buffer_rgba())[..., :3].astype(int)
    box = ax.get_window_extent()
    h = img.shape[0]
    return img[int(h - box.y1) + 2:int(h - box.y0) - 2, int(box.x0) + 2:int(box.x1) - 2]


@pytest.mark.slow
@pytest.mark.parametrize("folder", ["compare", "short"])
def test_every_method_is_distinguishable_in_every_whole_run_panel(folders, folder):
    figs = _figures(folders[folder])
    for name in ("error-1", "error-2", "control-1", "control-2"):
        pf = figs[name]
        whole = pf.figure.axes[0]
        lines = {m: pf.whole[f"{name.replace('-', '/')}/{m}"] for m in METHODS}
        assert all(ln.axes is whole for ln in lines.values())
        looks = {m: (to_rgb(ln.get_color()), ln.get_linestyle(), ln.get_linewidth())
                 for m, ln in lines.items()}
        for a in METHODS:                 # colour AND (dash or width) differ, pair by pair
            for b in METHODS:
                if a < b:
                    assert looks[a][0] != looks[b][0], (name, a, b)
                    assert looks[a][1:] != looks[b][1:], (name, a, b)
        # the ideal line (nearly the Kalman curve) is wide and under the Kalman line
        assert lines["ideal"].get_zorder() < lines["kalman"].get_zorder()
        assert lines["ideal"].get_linewidth() > 2 * lines["kalman"].get_linewidth()
        # every band under every line
        bands = [c for c in whole.collections]
        assert all(c.get_zorder() < min(ln.get_zorder() for ln in lines.values())
                   for c in bands)
        # none is hidden: taking any one line away changes what the panel shows
        base = _pixels(pf.figure, whole)
        for m, ln in lines.items():
            ln.set_visible(False)
            changed = np.any(_pixels(pf.figure, whole) != base, axis=-1).sum()
            ln.set_visible(True)
            assert changed > 300, (name, m, changed)
        # the legend names every method with the whole-run line's look
        legend = pf.figure.axes[1].get_legend()
        assert [t.get_text() for t in legend.get_texts()] == list(METHODS)
        for handle, m in zip(legend.legend_handles, METHODS):
            assert handle.get_linestyle() == lines[m].get_linestyle()
            assert handle.get_linewidth() == lines[m].get_linewidth()


@pytest.mark.slow
def test_the_two_laws_fleet_error_panels_share_their_y_scale(folders):
    pf = _figures(folders["fleet"])["fleet-errors"]
    axes = np.array(pf.figure.axes).reshape(-1, 2)
    assert len(axes) == 2                                     # lq and regulator
    (w0, z0), (w1, z1) = axes
    assert w0.get_ylim() == w1.get_ylim() and w0.get_ylim()[0] == 0.0
    assert z0.get_ylim() == z1.get_ylim() and z0.get_ylim()[0] == 0.0
    t0 = z0.get_xlim()[0]
    top = {}
    for key, line in pf.series.items():
        method = key.split("/")[-1].split(":")[0]
        x, y = line.get_xdata(), line.get_ydata()
        top[method] = max(top.get(method, 0.0), float(y[x >= t0].max()))
        assert float(y.max()) <= w0.get_ylim()[1]              # nothing cut off
    assert set(top) == {"lq", "regulator"}
    assert max(top.values()) <= z0.get_ylim()[1] <= 1.1 * max(top.values())
