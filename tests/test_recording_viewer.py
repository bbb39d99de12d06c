"""What the Rerun viewer draws, read back from the blueprint and styles of .rrd files written by
real runs (short horizons): the paper example, formation-4 per vehicle over acoustic links, and
formation-4 with the nonlinear remus100-6dof vehicles.

Every noisy series aggregates MinMax (the viewer's default average draws noise 2-4 times
smaller); every time-series view names its unit and fixes a y range that covers everything it
draws with at least three ticks; the links have their own legend line and colours apart from
the components'; the actuators are grouped per kind with their limits as constant series."""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from rerun.chunk import RrdReader

from orchestrator.recording import (
    read_rrd_points,
    read_rrd_scalars,
    read_rrd_series,
    read_rrd_series_lines,
    write_rrd,
)
from support.rrd_readback import (
    read_rrd_blueprint_tree,
    read_rrd_blueprint_views,
    read_rrd_view_properties,
)

SCENARIO_DIR = Path(__file__).resolve().parents[1] / "orchestrator" / "scenario" / "builtin"
MIN_MAX = 5          # rerun.components.AggregationPolicy.MinMax
COMPONENT_RGB = {(214, 39, 40), (44, 160, 44), (31, 119, 180)}     # n red, e green, d blue


def _run(tmp: Path, name: str, *args: str) -> Path:
    from orchestrator.cli import main
    out = tmp / name
    assert main(["run", "--T", "20", "--quiet", "--predict", "none", "--out", str(out),
                 *args]) == 0
    (rrd,) = out.glob("*.rrd")
    return rrd


@pytest.fixture(scope="module")
def paper_rrd(tmp_path_factory) -> Path:
    return _run(tmp_path_factory.mktemp("viewer"), "paper")


@pytest.fixture(scope="module")
def links_rrd(tmp_path_factory) -> Path:
    return _run(tmp_path_factory.mktemp("viewer"), "links", "--scenario", "formation-4",
                "--deployment", "per-vehicle", "--latency", "0.5", "--period", "1",
                "--loss", "0.2")


@pytest.fixture(scope="module")
def remus_rrd(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("viewer")
    text = (SCENARIO_DIR / "formation-4.toml").read_text()
    assert 'model = "remus100"' in text
    toml = tmp / "formation-4-6dof.toml"
    toml.write_text(text.replace('model = "remus100"', 'model = "remus100-6dof"'))
    return _run(tmp, "remus", "--scenario", str(toml), "--deployment", "per-vehicle")


def _static(path: Path, column: str) -> dict[str, list]:
    """entity -> the last static value of ``column``."""
    out = {}
    for chunk in RrdReader(path).stream():
        if chunk.is_static:
            batch = chunk.to_record_batch()
            if column in batch.schema.names:
                out[chunk.entity_path.strip("/")] = batch.column(column).to_pylist()[-1]
    return out


def _drawn(query: list[str], origin: str, entities: list[str]) -> list[str]:
    """The entities a view's contents query selects (inclusions only: exact or "/**")."""
    picked = []
    for line in query:
        pattern = line[2:] if line.startswith("+ ") else line
        assert not pattern.startswith("-"), line
        pattern = pattern.replace("$origin", origin.rstrip("/") or "").strip("/")
        if pattern.endswith("/**"):
            base = pattern[:-3]
            picked += [e for e in entities if e == base or e.startswith(base + "/")]
        else:
            picked += [e for e in entities if e == pattern]
    return picked


def _ticks(lo: float, hi: float) -> int:
    """Multiples of the viewer's labelled step (the largest power of ten within the span, or
    the next one when the span holds more than 4.5 of those) inside [lo, hi]."""
    step = 10.0 ** math.floor(math.log10(hi - lo))
    count = math.floor(hi / step) - math.ceil(lo / step) + 1
    wide = math.floor(hi / (10 * step)) - math.ceil(lo / (10 * step)) + 1
    return max(count, wide) if (hi - lo) / step > 4.5 else count


def _check_series_views(path: Path, unit: re.Pattern[str]) -> dict[str, dict]:
    """Every time-series view: unit in the name, a y range covering all it draws, 3 ticks."""
    data = read_rrd_scalars(path)
    views = read_rrd_blueprint_views(path)
    props = read_rrd_view_properties(path)
    series = {n: p for n, p in props.items() if views[n][0] == "TimeSeries"}
    assert series
    for name, p in series.items():
        assert unit.search(name), name
        lo, hi = p["ScalarAxis:range"][0]
        drawn = _drawn(p["ViewContents:query"], views[name][1], sorted(data))
        assert drawn, name
        values = np.concatenate([np.ravel(data[e][2]) for e in drawn])
        assert lo <= values.min() and values.max() <= hi, (name, lo, hi, values.min(),
                                                             values.max())
        assert _ticks(lo, hi) >= 3, (name, lo, hi)
    return series


@pytest.mark.slow
def test_paper_views_have_units_ranges_and_min_max(paper_rrd):
    """Every series MinMax; every view "(dimensionless)", its range over its data, 3 ticks."""
    policies = _static(paper_rrd, "SeriesLines:aggregation_policy")
    assert set(policies) == set(read_rrd_scalars(paper_rrd))
    assert all(p == [MIN_MAX] for p in policies.values())
    series = _check_series_views(paper_rrd, re.compile(r"\(dimensionless\)"))
    assert len(series) == 16             # 10 figure views and 6 full-scale ones


def test_the_ideal_line_is_wide_under_a_see_through_kalman_line(tmp_path):
    """The ideal method (nearly the Kalman curve) is drawn wider and opaque; the Kalman
    line, which the viewer draws over it (entity-path order), is see-through: the ideal
    noise band shows through the Kalman band."""
    rng = np.random.default_rng(3)
    runs = {m: {k: rng.standard_normal((50, 2)) for k in
                ("e", "u", "x", "xhat", "w", "what", "z", "zhat", "y", "ybar")}
            for m in ("kalman", "ideal")}
    path = tmp_path / "ideal.rrd"
    write_rrd(path, runs, 0.01, recording_name="ideal")
    widths = _static(path, "SeriesLines:widths")
    lines = read_rrd_series_lines(path)
    assert widths["error/1/ideal"][0] >= 2 * widths["error/1/kalman"][0]
    assert lines["error/1/ideal"][1][0][3] == 255 and lines["error/1/kalman"][1][0][3] < 200
    assert "error/1/ideal" < "error/1/kalman"          # the viewer's drawing order


def _path_to(tree: dict, name: str, trail: tuple = ()) -> tuple | None:
    if tree["kind"] == "view":
        return trail if tree["name"] == name else None
    for child in tree["contents"]:
        found = _path_to(child, name, (*trail, tree))
        if found is not None:
            return found
    return None


@pytest.mark.slow
def test_links_have_their_own_legend_and_colours_on_the_main_tab(links_rrd):
    """The link view sits on the main layout (no tab to find) under its own legend line,
    whose colour words match the series (grey, orange, purple: none a component colour);
    errors in m, controls in N, ages in s; every series MinMax."""
    series = _check_series_views(links_rrd, re.compile(r"\((m|N|s|messages)\)"))
    assert {n for n in series if "age of information (s)" in n} == {
        f"vehicle {i} age of information (s)" for i in range(1, 5)}
    tree = read_rrd_blueprint_tree(links_rrd)
    name = "links: delivered, lost, in flight (messages)"
    parents = _path_to(tree, name)
    assert parents is not None and all(c["kind"] != "Tabs" for c in parents)
    legend_view = parents[-1]["contents"][0]
    assert (legend_view["class"], legend_view["origin"]) == ("TextDocument", "/legend_links")
    (text,) = _static(links_rrd, "TextDocument:text")["legend_links"]
    for words in ("delivered grey", "lost orange", "in flight purple"):
        assert words in text
    assert not re.search(r"\b(red|green|blue)\b", text)
    lines = read_rrd_series_lines(links_rrd)
    links = {e: v for e, v in lines.items() if e.startswith("network/links/")}
    assert links
    for names, colors in links.values():
        assert [n.rsplit(" ", 1)[-1] for n in names[:2]] == ["delivered", "lost"]
        assert [c[:3] for c in colors] == [(150, 150, 150), (255, 140, 0), (170, 90, 230)]
        assert not {c[:3] for c in colors} & COMPONENT_RGB
    policies = _static(links_rrd, "SeriesLines:aggregation_policy")
    assert policies and all(p == [MIN_MAX] for p in policies.values())


def test_fleet_camera_holds_the_whole_run_and_labels_sit_off_the_trails(links_rrd):
    """Every vehicle position of the run is within 30 degrees of the camera's axis (in frame
    for the viewer's field of view); each number is 4 m beside its vehicle."""
    props = read_rrd_view_properties(links_rrd)
    (view,) = [n for n in props if n.startswith("fleet ")]
    m = view.split()[1]
    eye = props[view]
    position = np.array(eye["EyeControls3D:position"][0])
    target = np.array(eye["EyeControls3D:look_target"][0])
    _, _, vehicles = read_rrd_points(links_rrd, f"world/{m}/vehicles")
    _, _, labels = read_rrd_points(links_rrd, f"world/{m}/labels")
    pts = vehicles.reshape(-1, 3)
    axis = (target - position) / np.linalg.norm(target - position)
    rays = pts - position
    angle = np.degrees(np.arccos(rays @ axis / np.linalg.norm(rays, axis=1)))
    assert angle.max() < 30.0
    gap = np.linalg.norm(labels - vehicles, axis=-1)
    np.testing.assert_allclose(gap, 4.0, rtol=1e-4)
    assert _static(links_rrd, "Points3D:labels")[f"world/{m}/labels"] == ["1", "2", "3", "4"]


@pytest.mark.slow
def test_actuators_grouped_per_kind_with_limits(remus_rrd):
    """Four actuator views (rpm, rudder, stern planes, saturated), not one per vehicle, each
    holding every vehicle; the limits are constant series n_max and +-delta_max in them."""
    series = _check_series_views(remus_rrd, re.compile(r"\((m|N|rpm|rad|0/1)\)"))
    kinds = {"propeller speed (rpm)": ("propeller", "limits/propeller"),
             "rudder (rad)": ("rudder", "limits/fins"),
             "stern planes (rad)": ("stern", "limits/fins"),
             "saturated (0/1)": ("saturated", None)}
    assert set(kinds) <= set(series)
    assert not [n for n in series if re.match(r"vehicle \d+ (propeller|fins)", n)]
    entities = sorted(read_rrd_scalars(remus_rrd))
    views = read_rrd_blueprint_views(remus_rrd)
    for name, (group, limit) in kinds.items():
        drawn = _drawn(series[name]["ViewContents:query"], views[name][1], entities)
        assert {e.split("/")[1] for e in drawn if e.startswith("vehicles/")} == {"1", "2", "3",
                                                                                 "4"}
        assert all(e.split("/")[2] == group for e in drawn if e.startswith("vehicles/"))
        assert (limit in drawn) if limit else not any(e.startswith("limits/") for e in drawn)
    _, _, n_max = read_rrd_series(remus_rrd, "limits/propeller")
    _, _, fins = read_rrd_series(remus_rrd, "limits/fins")
    np.testing.assert_array_equal(n_max, [[1525.0], [1525.0]])
    d = np.radians(15.0)
    np.testing.assert_allclose(fins, [[d, -d], [d, -d]])
    (rpm_entity,) = [e for e in entities if e.startswith("vehicles/2/propeller/")]
    _, _, rpm = read_rrd_series(remus_rrd, rpm_entity)
    assert 0 < rpm.max() <= 1525.0
    policies = _static(remus_rrd, "SeriesLines:aggregation_policy")
    assert all(p == [MIN_MAX] for p in policies.values())
