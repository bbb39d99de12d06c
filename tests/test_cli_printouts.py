"""What the commands print, read as a user reads it: real runs on short horizons, no "None"
or "n/a" where a value or a word belongs, no standard deviation of one seed, every note one
line with its figure; --quiet and --help the same on every command; the defaults accepted;
the built-in scenarios listed from the package, the one with acoustic links run."""
from __future__ import annotations

import json
import re

import pytest

from orchestrator.cli import main
from orchestrator.cli.parser import build_parser
from orchestrator.numbers import sig
from orchestrator.scenario import load_scenario
from orchestrator.scenario.loader import SCENARIO_DIR

#: a note is one line: at most this many characters
NOTE_WIDTH = 200


def _run(capsys, argv: list[str]) -> str:
    assert main(argv) == 0
    return capsys.readouterr().out


def _check_words(out: str) -> None:
    """No "None" or "n/a" anywhere; every note one line, short enough to read as one."""
    assert "None" not in out, out
    assert "n/a" not in out, out
    for line in out.splitlines():
        if line.startswith("note:"):
            assert len(line) <= NOTE_WIDTH, line
    assert "predicted_window" not in out            # a key of the summary, not a note


def _table(out: str) -> tuple[str, list[str]]:
    """The table's header and its method rows."""
    lines = out.splitlines()
    i = next(k for k, line in enumerate(lines) if line.split()[:1] == ["method"])
    rows = []
    for line in lines[i + 1:]:
        if not line.startswith(" ") or line.strip().startswith("formation"):
            break
        rows.append(line)
    return lines[i], rows


def test_run_prints_values_not_none_and_no_std_for_one_seed(capsys, tmp_path):
    out = _run(capsys, ["run", "--T", "20", "--out", str(tmp_path / "run")])
    _check_words(out)
    head, rows = _table(out)
    assert "(std)" not in head and "predicted" in head
    assert len(rows) == 1 and len(rows[0].split()) == 5       # kalman, cost, pred, 2 rms
    assert re.search(r"seed 0: cost rate [0-9.]+ \(predicted [0-9.]+\)", out)
    notes = [line for line in out.splitlines() if line.startswith("note:")]
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["stationarity_note"]                   # T = 20 s is not stationary
    (note,) = notes
    assert "run T >= 66.7 s" in note and "[10, 20) s" in note     # the figures it means
    expected = summary["methods"]["kalman"]["cost_rate"]["predicted_window"]
    assert f"kalman {sig(expected, 4)}" in note


def test_run_without_prediction_leaves_the_columns_out(capsys, tmp_path):
    out = _run(capsys, ["run", "--T", "20", "--predict", "none", "--out", str(tmp_path)])
    _check_words(out)
    head, (row,) = _table(out)
    assert "predicted" not in head and "pred" not in head
    assert "(predicted" not in out
    assert len(row.split()) == 4                             # kalman, cost, 2 rms e
    assert not [line for line in out.splitlines() if "expected over this window" in line]


@pytest.mark.parametrize("seeds,std", [("0", False), ("0-1", True)])
def test_compare_has_a_std_column_only_for_two_seeds(capsys, tmp_path, seeds, std):
    out = _run(capsys, ["compare", "--T", "20", "--seeds", seeds, "--workers", "1",
                        "--out", str(tmp_path)])
    _check_words(out)
    head, rows = _table(out)
    assert ("(std)" in head) is std
    assert [r.split()[0] for r in rows] == ["kalman", "classical", "ideal"]
    summary = json.loads((tmp_path / "summary.json").read_text())
    for row, m in zip(rows, summary["methods"].values()):
        cells = row.split()
        assert float(cells[1]) == pytest.approx(m["cost_rate"]["mean"], rel=1e-3)
        if std:
            assert float(cells[2]) == pytest.approx(m["cost_rate"]["std"], rel=2e-2)
            assert m["cost_rate"]["std"] > 0
        assert float(cells[3 if std else 2]) == pytest.approx(m["cost_rate"]["predicted"],
                                                               rel=1e-3)


@pytest.mark.slow
def test_a_fleet_over_links_prints_no_missing_prediction(capsys, tmp_path):
    out = _run(capsys, ["run", "--scenario", "formation-4-links", "--T", "5",
                        "--out", str(tmp_path)])
    _check_words(out)
    head, (row,) = _table(out)
    assert "rms e (sim / pred)" not in head                  # no RMS prediction over links
    assert re.fullmatch(r"\s*kalman\s+\S+\s+\S+\s+max \S+", row)
    assert (tmp_path / "formation-4-links.rrd").is_file()


@pytest.mark.slow
def test_envelope_default_scenario_is_one_it_accepts(capsys, tmp_path):
    parser = build_parser()
    args = parser.parse_args(["envelope"])
    sc = load_scenario(args.scenario)
    assert sc.fleet is not None and sc.deployment == "per-vehicle"
    out = _run(capsys, ["envelope", "--T", "5", "--speeds", "2", "--radii", "inf",
                        "--currents", "0.05", "--out", str(tmp_path)])
    _check_words(out)
    assert re.search(r"1/1 speed 2 m/s, radius straight, current 0.05 m/s: max error "
                     r"[0-9.]+ m -> (holds|does not hold)", out)
    assert out.splitlines()[-1].startswith("1 of 1 points hold" if "-> holds" in out
                                           else "0 of 1 points hold")
    quiet = _run(capsys, ["envelope", "--T", "5", "--speeds", "2", "--radii", "inf",
                          "--currents", "0.05", "--out", str(tmp_path / "q"), "--quiet"])
    assert len(quiet.splitlines()) == 1 and "points hold within" in quiet


def test_every_command_accepts_quiet_and_run_is_quiet(capsys, tmp_path):
    parser = build_parser()
    (sub,) = [a for a in parser._actions if a.dest == "command"]
    helps = set()
    for name, sp in sub.choices.items():
        action = sp._option_string_actions.get("--quiet")
        assert action is not None, name
        helps.add(action.help)
        positional = {"export": ["osp"], "campaign": ["spec.toml"], "plot": ["folder"]}
        assert parser.parse_args([name, *positional.get(name, []), "--quiet"]).quiet
    assert len(helps) == 1                          # it means the same everywhere
    out = _run(capsys, ["run", "--T", "5", "--quiet", "--out", str(tmp_path)])
    assert "seed 0:" not in out and out.startswith("scenario paper:")


def test_export_help_documents_the_positional(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["export", "--help"])
    assert exc.value.code == 0
    text = capsys.readouterr().out
    positional = text.split("positional arguments:")[1].split("options:")[0]
    flat = " ".join(positional.split())
    for fmt, what in (("osp:", "OSP system"), ("ssp:", "SSP archive"), ("native:", "compiled")):
        assert fmt in flat and what in flat


def test_run_help_lists_the_builtin_files_and_the_linked_fleet_runs(capsys, tmp_path):
    parser = build_parser()
    (sub,) = [a for a in parser._actions if a.dest == "command"]
    text = sub.choices["run"]._option_string_actions["--scenario"].help
    listed = re.search(r"built-in name \(([^)]*)\)", text).group(1).split(", ")
    assert listed == sorted(p.stem for p in SCENARIO_DIR.glob("*.toml"))
    assert "formation-4-links" in listed
    sc = load_scenario("formation-4-links")
    assert sc.deployment == "per-vehicle" and sc.architecture == "distributed"
    assert (sc.network.table["latency"], sc.network.table["period"], sc.network.table["loss"]) == (1.0, 2.0, 0.1)
    assert main(["run", "--scenario", "formation-4-links", "--T", "5", "--quiet",
                 "--out", str(tmp_path)]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["scenario"] == "formation-4-links" and summary["T"] == 5.0
    assert summary["deployment"] == "per-vehicle"


def test_the_scenarios_page_lists_every_builtin():
    from pathlib import Path
    page = (Path(__file__).resolve().parents[1] / "docs" / "scenarios.md").read_text()
    rows = re.findall(r"^\| `([^`]+)`", page, flags=re.M)
    assert sorted(rows) == sorted(p.stem for p in SCENARIO_DIR.glob("*.toml"))
