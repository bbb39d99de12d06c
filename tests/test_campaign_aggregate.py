"""The aggregate (means, Student-t intervals against the prediction) and the plots."""
from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from scipy import stats

from orchestrator.campaign.aggregate import aggregate_rows, confidence_interval, write_aggregate
from orchestrator.campaign.plot import write_plots


def test_confidence_interval_against_scipy():
    x = [3.0, 4.5, 2.5, 5.0, 4.0]
    mean, lo, hi = confidence_interval(x)
    ref = stats.t.interval(0.95, len(x) - 1, loc=np.mean(x), scale=stats.sem(x))
    assert mean == pytest.approx(np.mean(x)) and (lo, hi) == pytest.approx(ref)
    assert confidence_interval([2.0]) == (2.0, 2.0, 2.0)


def _rows():
    rows = []
    for point, (est, T) in enumerate([("kalman", 5.0), ("kalman", 10.0), ("classical", 5.0),
                                      ("classical", 10.0)]):
        for seed in range(4):
            ok = not (est == "classical" and T == 10.0)
            rows.append({"point": point, "seed": seed, "engine": "numpy" if point else "fmu",
                         "params": json.dumps({"simulation.estimator": est, "simulation.T": T}),
                         "status": "ok" if ok else "error", "error": None if ok else "boom",
                         "cost_rate": (10.0 if est == "kalman" else 50.0) + T + seed if ok
                         else None, "predicted_cost_rate": 13.0 if est == "kalman" else 60.0,
                         "rms_e": [1.0 + seed, 2.0] if ok else None, "wall_s": 0.5,
                         "predicted_rms_e": [2.0, 2.0], "rms_u": [0.1, 0.2] if ok else None,
                         "predicted_rms_u": [0.1, 0.2]})
    return rows


def test_aggregate_per_point(tmp_path):
    agg = aggregate_rows(_rows())
    assert [a["ok"] for a in agg] == [4, 4, 4, 0] and agg[3]["error"] == "boom"
    a = agg[0]
    assert a["cost_rate_mean"] == pytest.approx(16.5) and a["rms_e_mean"] == [2.5, 2.0]
    assert a["predicted_in_ci"] is (a["cost_rate_ci_low"] <= 13.0 <= a["cost_rate_ci_high"])
    assert a["rel_error"] == pytest.approx((16.5 - 13.0) / 13.0)
    assert [x["engines"] for x in agg] == ["fmu", "numpy", "numpy", "numpy"]
    written = write_aggregate(_rows(), tmp_path)
    assert len(written) == 4 and (tmp_path / "aggregate.parquet").exists()
    csv = (tmp_path / "aggregate.csv").read_text().splitlines()
    assert csv[0].startswith("point,param:simulation.estimator,param:simulation.T,ok,failed")
    assert len(csv) == 5


def test_plots_are_svg_with_a_band_per_series(tmp_path):
    agg = aggregate_rows(_rows())
    paths = write_plots(agg, tmp_path)
    assert sorted(p.name for p in paths) == ["cost_simulation.T.svg",
                                             "cost_simulation.estimator.svg"]
    svg = ET.parse(tmp_path / "cost_simulation.T.svg").getroot()
    ns = "{http://www.w3.org/2000/svg}"
    bands = svg.findall(f"{ns}polygon")
    assert len(bands) == 1                  # kalman over T (classical has one valid point)
    dots = [c for c in svg.findall(f"{ns}circle") if c.get("fill") != "none"]
    assert len(dots) == 3                   # the three points with finished runs
    assert "simulation.estimator=kalman" in ET.tostring(svg, encoding="unicode")
