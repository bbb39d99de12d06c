"""What users see in the viewer (issue 38, item 4): each method's series has its own
colour and name, the ideal estimator wide under a see-through Kalman line, and the views
of a fleet comparison share their y range. Read back from the .rrd a real run wrote (the
series styles and the embedded blueprint)."""
from __future__ import annotations

import pytest
from rerun.chunk import RrdReader

from orchestrator.cli import main
from orchestrator.recording import read_rrd_series_lines, read_rrd_view_ranges
from orchestrator.recording.layout import fleet_method_line, method_styles

METHODS = ("kalman", "classical", "ideal")


def test_the_styles_tell_every_method_apart_and_keep_the_ideal_under_the_kalman_line():
    styles = method_styles(METHODS)
    assert len({s.color for s in styles.values()}) == 3
    assert styles["ideal"].wide and not styles["kalman"].wide
    assert styles["ideal"].layer < styles["kalman"].layer
    # the viewer draws a view's series in entity-path order: ideal before kalman, so the
    # Kalman line over it is see-through and the ideal one opaque
    assert styles["kalman"].viewer_alpha < 255 and styles["ideal"].viewer_alpha == 255
    assert styles["classical"].viewer_alpha == 255          # drawn first, under both
    assert len({s.dash for s in styles.values() if not s.wide}) == 2
    laws = method_styles(("lq", "regulator"))
    assert laws["lq"].color != laws["regulator"].color
    assert laws["lq"].dash != laws["regulator"].dash


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    base = tmp_path_factory.mktemp("viewer_styles")
    made = {"paper": ["compare", "--T", "4", "--seeds", "0"],
            "fleet": ["compare", "--scenario", "formation-4", "--T", "10", "--seeds", "0"]}
    for name, argv in made.items():
        assert main([*argv, "--out", str(base / name), "--quiet"]) == 0
    return {name: base / name for name in made}


@pytest.mark.slow
def test_each_method_has_its_own_colour_and_name_in_the_recording(folders):
    lines = read_rrd_series_lines(folders["paper"] / "paper.rrd")
    styles = method_styles(METHODS)
    for root in ("error/1", "error/2", "control/1", "control/2"):
        seen = {}
        for m in METHODS:
            (name,), (rgba,) = lines[f"{root}/{m}"]
            assert name == m
            assert rgba == (*styles[m].color, styles[m].viewer_alpha)
            seen[m] = rgba[:3]
        assert len(set(seen.values())) == len(METHODS)


@pytest.mark.slow
def test_a_fleet_comparisons_views_share_their_y_ranges(folders):
    ranges = read_rrd_view_ranges(folders["fleet"] / "formation-4.rrd")
    errors = {n: r for n, r in ranges.items() if n.startswith("vehicle ") and " error " in n}
    controls = {n: r for n, r in ranges.items() if n.startswith("vehicle ") and " control " in n}
    assert len(errors) == 4 and len(controls) == 4
    assert len(set(errors.values())) == 1 and len(set(controls.values())) == 1
    (lo, hi), = set(errors.values())
    assert lo < hi


def _widths(path) -> dict[str, list[float]]:
    """entity -> its static series line widths."""
    out = {}
    for chunk in RrdReader(path).stream():
        batch = chunk.to_record_batch()
        if chunk.is_static and "SeriesLines:widths" in batch.schema.names:
            out[chunk.entity_path.strip("/")] = batch.column("SeriesLines:widths").to_pylist()[-1]
    return out


@pytest.mark.slow
def test_a_fleet_comparisons_two_laws_differ_in_shade_and_width(folders):
    rrd = folders["fleet"] / "formation-4.rrd"
    lines, widths = read_rrd_series_lines(rrd), _widths(rrd)
    for i in range(1, 5):
        (names_lq, rgba_lq), (names_reg, rgba_reg) = (
            lines[f"vehicles/{i}/error/{m}"] for m in ("lq", "regulator"))
        assert names_lq == ("lq n", "lq e", "lq d")
        assert names_reg == ("regulator n", "regulator e", "regulator d")
        assert all(a[:3] != b[:3] for a, b in zip(rgba_lq, rgba_reg))
        assert {c[3] for c in rgba_lq} == {fleet_method_line(0, 2)[1]} and all(
            c[3] == 255 for c in rgba_reg)
        assert min(widths[f"vehicles/{i}/error/lq"]) > 2 * max(
            widths[f"vehicles/{i}/error/regulator"])
