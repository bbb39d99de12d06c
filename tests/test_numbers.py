"""orchestrator.numbers.sig: significant figures without the trailing dot ``#g`` leaves."""
from __future__ import annotations

import math

import pytest

from orchestrator.cli.common import method_table
from orchestrator.numbers import sig


@pytest.mark.parametrize(("value", "digits", "text"), [
    (3789.0, 4, "3789"),            # printed "3789." before
    (3814.2, 4, "3814"),
    (-3789.0, 4, "-3789"),
    (100.0, 3, "100"),
    (10.0, 2, "10"),
    (2e6, 1, "2e+06"),              # "2.e+06"
    (619.3, 4, "619.3"),
    (4.2, 3, "4.20"),               # the significant zero is kept
    (0.0648, 3, "0.0648"),
    (16.55, 4, "16.55"),
    (1.5e6, 2, "1.5e+06"),
    (0.0, 3, "0.00"),
])
def test_sig_keeps_figures_and_drops_the_trailing_dot(value, digits, text):
    assert sig(value, digits) == text
    assert not sig(value, digits).endswith(".")
    assert float(sig(value, digits)) == pytest.approx(value, rel=10.0 ** (1 - digits))


def test_sig_pads_to_a_width_and_prints_non_finite_values():
    assert sig(3789.0, 4, 10) == "      3789"
    assert sig(math.inf, 3) == "inf" and sig(math.nan, 3) == "nan"


def test_the_method_table_prints_no_trailing_dot():
    """The table of a run whose figures fill their significant figures (the nonlinear
    fleet's cost rate, 3814) and a fleet's formation line."""
    summary = {"seeds": [0, 1], "methods": {"kalman": {
        "cost_rate": {"mean": 3814.0, "std": 120.0, "predicted": 3790.0},
        "rms_e": {"mean": [1.0, 2.0, 3.0, 4.0, 100.0], "predicted": None},
        "formation_error_rms": {"1->2": 10.0},
        "min_separation": {"m": 100.0, "vehicles": [1, 3], "time_s": 4.0, "seed": 0}}}}
    lines = method_table(summary)
    text = "\n".join(lines)
    assert "3814 " in text and "3790" in text and " 120" in text and "max 100" in text
    assert "10.0 m" in text and "closest approach 100 m" in text
    for word in text.split():
        assert not word.rstrip(",;/)").endswith("."), word
