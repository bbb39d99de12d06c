"""Campaign specs: the accepted form, and every bad key refused in one line naming it."""
from __future__ import annotations

import pytest

from orchestrator.campaign.spec import SpecError, load_spec, parse_seed_text
from orchestrator.cli import main


def _write(tmp_path, text):
    p = tmp_path / "spec.toml"
    p.write_text(text)
    return p


def test_the_documented_form(tmp_path):
    spec, seeds, base, where = load_spec(_write(tmp_path, """
base = "paper"
seeds = "0-3"
[sweep]
"simulation.estimator" = ["kalman", "classical"]
"simulation.T" = [20.0]
"""))
    assert seeds == [0, 1, 2, 3] and spec.engine == "fmu"
    assert spec.sweep == {"simulation.estimator": ["kalman", "classical"],
                          "simulation.T": [20.0]}
    assert base["name"] == "paper" and where == "built-in scenario 'paper'"


def test_bases_grid_and_relative_path(tmp_path):
    (tmp_path / "mine.toml").write_text(
        (__import__("orchestrator.scenario.loader", fromlist=["x"]).SCENARIO_DIR
         / "paper.toml").read_text().replace('name = "paper"', 'name = "mine"'))
    _, _, base, where = load_spec(_write(tmp_path, 'base = "mine.toml"\n'))
    assert base["name"] == "mine" and where.endswith("mine.toml")
    _, _, base, _ = load_spec(_write(tmp_path, 'base = "grid-7"\n[sweep]\n'
                                               '"vehicles.count" = [3, 7]\n'))
    assert base["vehicles"]["count"] == 7 and "leader" in base


@pytest.mark.parametrize("text, words", [
    ('base = "paper"\nsweeps = 1\n', ["sweeps", "unknown"]),
    ('seeds = "0-3"\n', ["base", "missing"]),
    ('base = "paper"\n[sweep]\n"simulation.estimater" = ["kalman"]\n',
     ["[sweep] key 'simulation.estimater'", "no key 'estimater'", "estimator"]),
    ('base = "paper"\n[sweep]\n"plant.A" = [1.0]\n', ["'plant.A'", "plant is not a table"]),
    ('base = "paper"\n[sweep]\nT = [1.0]\n', ["'T'", "dotted key"]),
    ('base = "paper"\n[sweep]\n"simulation.seed" = [1]\n', ["'simulation.seed'", "seeds"]),
    ('base = "paper"\n[sweep]\n"vehicles.count" = [2]\n', ["'vehicles.count'", "no key 'count'"]),
    ('base = "paper"\n[sweep]\n"simulation.T" = []\n', ["'simulation.T'", "no values"]),
    ('base = "paper"\n[sweep]\n"simulation.T" = 5.0\n', ["sweep", "simulation.T"]),
    ('base = "paper"\n[sweep]\n"cosim.coupling" = ["jacoby"]\n', ["'cosim.coupling'", "jacoby"]),
    ('base = "paper"\n[sweep]\n"cosim.order" = ["x"]\n', ["'cosim.order'", "coupling"]),
    ('base = "paper"\n[[points]]\n"noise.W_q" = 1.0\n', ["[points[1]] key 'noise.W_q'"]),
    ('base = "paper"\nseeds = "3-1"\n', ["seeds", "empty"]),
    ('base = "paper"\nseeds = [1, 1]\n', ["seeds", "more than once"]),
    ('base = "paper"\nseeds = "x"\n', ["seeds", "range"]),
    ('base = "paper"\nengine = "gpu"\n', ["engine"]),
    ('base = "nowhere"\n', ["base = 'nowhere'", "unknown scenario"]),
    ('base = "paper"\ncheck = -1\n', ["check"]),
])
def test_bad_specs_are_one_line_naming_the_key(tmp_path, capsys, text, words):
    path = _write(tmp_path, text)
    with pytest.raises(SpecError) as err:
        load_spec(path)
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith(str(path))
    for w in words:
        assert w in msg, msg
    assert main(["campaign", str(path), "--out", str(tmp_path / "out")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines == [f"auv-cosim campaign: error: {msg}"]
    assert not (tmp_path / "out").exists()


def test_leader_parameters_and_fleet_keys_are_accepted(tmp_path):
    spec, *_ = load_spec(_write(tmp_path, 'base = "formation-4"\n[sweep]\n'
                                          '"leader.speed" = [1.0, 1.5]\n'
                                          '"vehicles.params.cruise_speed" = [1.5]\n'
                                          '"noise.position" = [0.25]\n'))
    assert len(spec.sweep) == 3


def test_seed_text():
    assert parse_seed_text("0-2,7") == [0, 1, 2, 7]
    assert parse_seed_text(" 5 ") == [5]
    with pytest.raises(ValueError):
        parse_seed_text("1-")


def test_missing_or_unreadable_spec(tmp_path, capsys):
    assert main(["campaign", str(tmp_path / "none.toml")]) == 2
    assert "campaign spec not found" in capsys.readouterr().err
    (tmp_path / "bad.toml").write_text("base = ")
    assert main(["campaign", str(tmp_path / "bad.toml")]) == 2
    assert "not valid TOML" in capsys.readouterr().err
    assert main(["campaign", str(tmp_path)]) == 2
    assert "is a folder" in capsys.readouterr().err
