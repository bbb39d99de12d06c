"""Short runs and impossible methods: the summary says when its figures are not stationary,
predicts the expected statistics over the actual window (start-up transient included), and
a compare skips a mode the scenario cannot run, saying why, instead of losing the others."""
from __future__ import annotations

import json

import numpy as np
import pytest

from orchestrator.cli import main


def _summary(out):
    return json.loads((out / "summary.json").read_text())


@pytest.mark.slow
def test_short_runs_match_the_window_prediction_not_the_stationary_one(tmp_path, capsys):
    """40 seeds of 5 s (window [2.5, 5) s, inside the 33 s transient): the mean cost rate
    agrees with the transient-inclusive prediction within 3 standard errors and is far
    from the stationary one."""
    out = tmp_path / "short"
    assert main(["compare", "--T", "5", "--methods", "kalman", "--seeds", "0-39", "--quiet",
                 "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    s = _summary(out)
    c_window = s["methods"]["kalman"]["cost_rate"]["predicted_window"]
    assert s["stationary"] is False and "inside the start-up transient" in s["stationarity_note"]
    note = [ln for ln in printed.splitlines() if "is not stationary" in ln]
    assert len(note) == 1 and note[0].startswith("note: the window [2.5, 5) s is not stationary")
    assert f"kalman {c_window:.4g}" in note[0]
    c = s["methods"]["kalman"]["cost_rate"]
    se = np.std(c["per_seed"], ddof=1) / np.sqrt(len(c["per_seed"]))
    assert abs(c["mean"] - c["predicted_window"]) < 3 * se, (c["mean"], c["predicted_window"], se)
    assert abs(c["mean"] - c["predicted"]) > 3 * se
    assert c["predicted_window"] < c["predicted"]


@pytest.mark.slow
def test_a_long_run_is_stationary(tmp_path, capsys):
    out = tmp_path / "long"
    assert main(["run", "--T", "120", "--quiet", "--out", str(out)]) == 0
    s = _summary(out)
    assert s["stationary"] is True and s["stationarity_note"] is None
    c = s["methods"]["kalman"]["cost_rate"]
    assert c["predicted_window"] == pytest.approx(c["predicted"], rel=0.02)
    assert "note:" not in capsys.readouterr().out


@pytest.mark.slow
def test_compare_skips_an_impossible_mode_and_runs_the_others(tmp_path, capsys):
    out = tmp_path / "fleet"
    assert main(["compare", "--scenario", "formation-4", "--what", "estimators", "--T", "4",
                 "--seeds", "0", "--quiet", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    s = _summary(out)
    assert "needs C with full column rank" in s["methods"]["classical"]["skipped"]
    assert s["methods"]["classical"]["seeds_completed"] == 0
    for mode in ("kalman", "ideal"):
        assert s["methods"][mode]["seeds_completed"] == 1
        assert np.isfinite(s["methods"][mode]["cost_rate"]["mean"])
    assert "classical   skipped: the classical estimator needs C" in printed


def test_compare_with_only_impossible_modes_is_one_line(tmp_path, capsys):
    assert main(["compare", "--scenario", "formation-4", "--what", "estimators",
                 "--methods", "classical", "--T", "4", "--seeds", "0", "--quiet",
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "classical estimator needs C" in err


@pytest.mark.parametrize("methods, fragment", [
    ("kalman,bogus", "bogus is not one of the estimators (kalman, kalman-tv, classical, ideal)"),
    ("kalman,kalman", "give each method once"),
])
def test_bad_methods(tmp_path, capsys, methods, fragment):
    assert main(["compare", "--methods", methods, "--T", "1", "--seeds", "0", "--quiet",
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and fragment in err
    assert not (tmp_path / "o").exists()
