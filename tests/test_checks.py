"""The wiring check every consumer of a system description uses (master, OSP, SSP,
cross-check): orchestrator/cosim/checks.py and orchestrator/interop/common.py.

Merged from the OSP and SSP exporters' own checks: each case asserts the problem is found
and named (connection, component, variable), and that all problems are listed at once."""
from __future__ import annotations

import pytest

from orchestrator.cosim.checks import Variable, connection_problems, system_variables
from orchestrator.cosim.system import Connection, ScalarConnection
from orchestrator.interop.common import ExportError, check_system
from orchestrator.running import scenario_system
from orchestrator.scenario import load_scenario

SC = ScalarConnection


@pytest.fixture(scope="module")
def paper_system():
    return scenario_system(load_scenario("paper"))


def _problems(system, extra=(), drop=()):
    conns = [c for c in system.scalar_connections() if c.target not in drop] + list(extra)
    return connection_problems(system_variables(system), conns)


def _one(problems, *fragments):
    """Exactly one problem, naming every fragment."""
    assert len(problems) == 1, problems
    for f in fragments:
        assert f in problems[0], problems[0]
    return problems[0]


def test_the_paper_loop_connects(paper_system):
    assert _problems(paper_system) == []
    conns = paper_system.scalar_connections()
    d = {"n": 2, "m": 2, "r": 2, "p": 2, "l": 2}
    assert len(conns) == 2 * d["p"] + 2 * (d["n"] + d["r"] + d["l"]) + 2 * d["m"]
    assert SC(("controller", "u[2]"), ("estimator", "u[2]")) in conns


def test_a_variable_the_fmu_lacks(paper_system):
    assert _problems(paper_system, [SC(("plant", "y[3]"), ("estimator", "y[3]"))]) == [
        "connection plant.y[3] -> estimator.y[3]: plant has no variable 'y[3]'",
        "connection plant.y[3] -> estimator.y[3]: estimator has no variable 'y[3]'"]
    conns = paper_system.scalar_connections()
    conns[0] = SC(("plant", "y[1]"), ("estimator", "yy[1]"))
    probs = connection_problems(system_variables(paper_system), conns)
    assert any("estimator has no variable 'yy[1]'" in p for p in probs), probs
    assert any("input estimator.y[1] is not connected" in p for p in probs), probs


def test_an_unknown_component(paper_system):
    _one(_problems(paper_system, [SC(("plant", "e[1]"), ("logger", "e[1]"))]),
         "there is no component 'logger'", "components: plant, estimator, controller")


def test_two_outputs(paper_system):
    _one(_problems(paper_system, [SC(("plant", "e[1]"), ("controller", "u[1]"))]),
         "connects two outputs", "plant.e[1]", "controller.u[1]")


def test_two_inputs(paper_system):
    _one(_problems(paper_system, [SC(("plant", "u[1]"), ("estimator", "u[1]"))]),
         "connects two inputs", "plant.u[1]", "estimator.u[1]")


def test_unconnected_inputs_are_each_named(paper_system):
    _one(_problems(paper_system, drop=[("controller", "zhat[2]")]),
         "input controller.zhat[2] is not connected")
    # the truth inputs of the estimator must be connected too (read only in 'ideal')
    _one(_problems(paper_system, drop=[("estimator", "w[1]")]),
         "input estimator.w[1] is not connected")
    probs = _problems(paper_system, drop=[("plant", "u[1]"), ("plant", "u[2]")])
    assert probs == ["input plant.u[1] is not connected", "input plant.u[2] is not connected"]


def test_an_input_fed_twice(paper_system):
    _one(_problems(paper_system, [SC(("plant", "e[1]"), ("controller", "xhat[1]"))]),
         "input controller.xhat[1] is fed by 2 outputs (estimator.xhat[1], plant.e[1])")


def _vars():
    R = "Real"
    return {"a": {"out": Variable("output", R), "k": Variable("parameter", R),
                  "n": Variable("output", "Integer")},
            "b": {"in": Variable("input", R), "out": Variable("output", R)}}


@pytest.mark.parametrize("conns, fragment", [
    ([SC(("a", "out"), ("a", "k"))], "target a.k is a parameter, not an input"),
    ([SC(("a", "k"), ("b", "in"))], "source a.k is a parameter, not an output"),
    ([SC(("a", "n"), ("b", "in"))], "connects an Integer output to a Real input"),
    ([SC(("a", "out"), ("b", "out"))], "connects two outputs (a.out and b.out)"),
    ([SC(("a", "out"), ("b", "in")), SC(("b", "out"), ("b", "in"))],
     "input b.in is fed by 2 outputs (a.out, b.out)"),
    ([], "input b.in is not connected"),
    ([SC(("a", "out"), ("c", "in"))], "there is no component 'c'"),
])
def test_each_problem_is_named(conns, fragment):
    probs = connection_problems(_vars(), conns)
    assert any(fragment in p for p in probs), probs
    assert connection_problems(_vars(), [SC(("a", "out"), ("b", "in"))]) == []


def test_fmu_file_names_appear_in_messages():
    probs = connection_problems(_vars(), [SC(("a", "out"), ("b", "in")), SC(("a", "zz"), ("b", "in"))],
                                fmu_names={"a": "A.fmu"})
    assert any("a (A.fmu) has no variable 'zz'" in p for p in probs), probs


def test_check_system_lists_every_problem_in_one_error(paper_system):
    bad = paper_system.__class__(
        name="bad", components=paper_system.components, h=paper_system.h, T=paper_system.T,
        connections=tuple(c for c in paper_system.connections if c.target != "plant")
        + (Connection("plant", "y", "controller", "y"),))
    with pytest.raises(ExportError) as exc:
        check_system(bad)
    msg = str(exc.value)
    assert msg.startswith("export refused: ") and "\n" not in msg
    assert "controller has no variable 'y[1]'" in msg
    assert "input plant.u[1] is not connected" in msg and "input plant.u[2] is not connected" in msg
    assert len(exc.value.problems) == 4


def test_check_system_refuses_a_parameter_the_fmu_lacks(paper_system):
    bad = paper_system.with_parameters("plant", **{"A[3,3]": 1.0})
    with pytest.raises(ExportError, match=r"parameter plant\.A\[3,3\]: the FMU AuvPlant has no "
                                          r"such parameter"):
        check_system(bad)
