"""A scenario nested hundreds of levels deep is refused in one line naming the depth, the
limit and the key (orchestrator/scenario/nesting.py), at the command line (exit status 2, no
traceback, no output folder) and in the loader: never an internal RecursionError."""
from __future__ import annotations

import subprocess
import sys
import tomllib

import pytest

from orchestrator.campaign.spec import SpecError, load_spec
from orchestrator.scenario import SCENARIO_DIR, ScenarioError, load_scenario, scenario_from_dict
from orchestrator.scenario.nesting import MAX_DEPTH, loads_scenario_toml, nesting

PAPER = (SCENARIO_DIR / "paper.toml").read_text()
A_LINE = "A  = [[-1.0, 0.0], [0.0, -1.0]]"

#: name -> (a paper.toml with [vehicles] A replaced, the depth reported, where)
DEEP = {
    # tomllib itself raises RecursionError on these two (checked below)
    "arrays": (PAPER.replace(A_LINE, "A = " + "[" * 1000 + "1.0" + "]" * 1000),
               1001, "[vehicles] A"),
    "inline-tables": (PAPER.replace(A_LINE, "A = " + "{b = " * 400 + "1.0" + "}" * 400),
                      401, "[vehicles] A"),
    # parseable, deep through a table header / a dotted key (found after parsing)
    "header": (PAPER + "[" + ".".join(["deep"] * 500) + "]\nx = 1\n", 500, "[deep] deep"),
    "dotted-key": (PAPER.replace(A_LINE, A_LINE + "\nx" + ".b" * 300 + " = 1"),
                   301, "[vehicles] x"),
}


def test_the_builtin_scenarios_are_far_below_the_limit():
    depths = [nesting(tomllib.loads(p.read_text()))[0] for p in SCENARIO_DIR.glob("*.toml")]
    assert max(depths) == 3 and MAX_DEPTH >= 8 * max(depths)


def test_tomllib_alone_fails_on_the_deepest_cases():
    """Why the loader cannot simply call tomllib: these inputs are its RecursionError."""
    for name in ("arrays", "inline-tables"):
        with pytest.raises(RecursionError):
            tomllib.loads(DEEP[name][0])


@pytest.mark.parametrize("name", sorted(DEEP))
def test_the_cli_refuses_in_one_line(tmp_path, name):
    text, depth, where = DEEP[name]
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "orchestrator", "run", "--scenario",
                           str(path), "--T", "1", "--out", str(out)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert lines == [f"auv-cosim run: error: {path}: nested {depth} levels deep "
                     f"(at most {MAX_DEPTH} allowed) at {where}"], proc.stderr
    assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr
    assert not out.exists()


@pytest.mark.parametrize("name", sorted(DEEP))
def test_the_loader_refuses(tmp_path, name):
    text, depth, where = DEEP[name]
    path = tmp_path / "deep.toml"
    path.write_text(text)
    with pytest.raises(ScenarioError) as exc:
        load_scenario(path)
    assert str(exc.value) == (f"{path}: nested {depth} levels deep (at most {MAX_DEPTH} "
                              f"allowed) at {where}")


def test_just_over_and_at_the_limit(tmp_path):
    """The limit is exact: [vehicles] x nested MAX_DEPTH deep (the section and MAX_DEPTH - 1
    arrays) reaches the schema (an unknown key), one level more is refused for its depth."""
    for extra, refused in ((MAX_DEPTH, False), (MAX_DEPTH + 1, True)):
        value = "[" * (extra - 1) + "1" + "]" * (extra - 1)
        path = tmp_path / f"d{extra}.toml"
        path.write_text(PAPER.replace(A_LINE, A_LINE + f"\nx = {value}"))
        with pytest.raises(ScenarioError) as exc:
            load_scenario(path)
        assert ("levels deep" in str(exc.value)) is refused, str(exc.value)
        if refused:
            assert f"nested {MAX_DEPTH + 1} levels deep" in str(exc.value)
        else:
            assert "unknown key(s) in [vehicles]: x" in str(exc.value)


def test_a_deep_mapping_given_to_scenario_from_dict():
    data = tomllib.loads(PAPER)
    deep: dict = {"leaf": 1.0}
    for _ in range(2000):            # far past Python's recursion limit
        deep = {"b": deep}
    data["vehicles"]["A"] = deep
    with pytest.raises(ScenarioError) as exc:
        scenario_from_dict(data, "mapping")
    assert str(exc.value) == (f"mapping: nested 2002 levels deep (at most {MAX_DEPTH} "
                              "allowed) at [vehicles] A")


def test_tomllib_recursing_below_the_lexical_limit_is_still_one_line():
    """A RecursionError of tomllib the bracket count did not foresee (here: a recursion limit
    lowered so that 30 levels exhaust it) is a ScenarioError, not an internal error."""
    text = "a = " + "[" * 30 + "1" + "]" * 30
    limit = sys.getrecursionlimit()
    depth = len(__import__("inspect").stack(0))
    sys.setrecursionlimit(depth + 40)
    try:
        with pytest.raises(ScenarioError, match=r"^x\.toml: nested too deep to read "
                                                rf"\(at most {MAX_DEPTH} levels allowed\)$"):
            loads_scenario_toml(text, "x.toml")
    finally:
        sys.setrecursionlimit(limit)


def test_brackets_in_strings_and_comments_do_not_count():
    text = ('name = "' + "[" * 100 + '"  # ' + "{" * 100 + "\n"
            "description = '''" + "[" * 100 + "'''\n[simulation]\nT = 1.0\n")
    assert loads_scenario_toml(text, "s.toml")["name"] == "[" * 100


def test_a_campaign_spec_and_its_base(tmp_path):
    deep = tmp_path / "deep.toml"
    deep.write_text(DEEP["arrays"][0])
    spec = tmp_path / "c.toml"
    spec.write_text(f'base = "{deep}"\nseeds = "0"\n')
    with pytest.raises(SpecError, match="nested 1001 levels deep"):
        load_spec(spec)
    spec.write_text('base = "paper"\nseeds = "0"\n[sweep]\n"x" = ' + "[" * 400 + "]" * 400)
    with pytest.raises(SpecError, match=rf"nested 401 levels deep \(at most {MAX_DEPTH} "
                                        r"allowed\) at \[sweep\] x"):
        load_spec(spec)
