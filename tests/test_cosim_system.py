"""The system description (orchestrator/cosim/system.py) and the master it drives: the
evaluation order from declared feedthrough, algebraic loops, connections that carry data
only in some modes, and a topology the hand-written master could not run (two loops in one
co-simulation, six instances of three FMUs)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from fmu_common.interface import ArraySpec
from orchestrator.cosim.master import CosimError, run_system
from orchestrator.cosim.system import (
    AlgebraicLoopError,
    Component,
    Connection,
    SystemDescription,
    closed_loop_system,
    evaluation_order,
)
from support.loop import run_cosimulation


def _spec(name, causality, depends=()):
    return ArraySpec(name, (2,), causality, name, start=0.0 if causality != "output" else None,
                     depends_on=tuple(depends))


def _feedthrough(name):
    return Component(name, "x", (_spec("i", "input"), _spec("o", "output", ["i"])))


def test_paper_loop_order_follows_feedthrough(built_scenario):
    _, cfg = built_scenario("paper")
    order = evaluation_order(closed_loop_system(dict(cfg, estimator="kalman")))
    assert order == [("plant", s) for s in ("y", "ybar", "x", "w", "z", "e")] + [
        ("estimator", s) for s in ("xhat", "what", "zhat")] + [("controller", "u")]


def test_order_is_derived_not_declared():
    """Components listed against the flow still run in the flow's order."""
    a, b = _feedthrough("a"), _feedthrough("b")
    src = Component("src", "x", (_spec("o", "output"),))
    sys_ = SystemDescription("chain", (b, a, src), (Connection("src", "o", "a", "i"),
                                                    Connection("a", "o", "b", "i")), 0.1, 1.0)
    assert evaluation_order(sys_) == [("src", "o"), ("a", "o"), ("b", "o")]


def test_algebraic_loop_is_refused_naming_the_cycle():
    a, b = _feedthrough("a"), _feedthrough("b")
    loop = SystemDescription("ring", (a, b), (Connection("a", "o", "b", "i"),
                                              Connection("b", "o", "a", "i")), 0.1, 1.0)
    with pytest.raises(AlgebraicLoopError) as exc:
        evaluation_order(loop)
    msg = str(exc.value)
    assert "algebraic loop" in msg and "ring" in msg
    assert "a.o (into b.i) -> b.o (into a.i) -> a.o" in msg or \
        "b.o (into a.i) -> a.o (into b.i) -> b.o" in msg
    # a delay (an output without feedthrough) breaks it
    delayed = replace(loop, components=(a, Component("b", "x", (_spec("i", "input"),
                                                                 _spec("o", "output")))))
    assert evaluation_order(delayed) == [("b", "o"), ("a", "o")]     # b.o first: it feeds a.o


def test_truth_connections_carry_data_only_in_ideal_mode(built_scenario):
    _, cfg = built_scenario("paper")
    truth = {("plant", s, "estimator", s) for s in ("x", "w", "z")}
    for mode in ("kalman", "classical", "ideal"):
        sys_ = closed_loop_system(dict(cfg, estimator=mode))
        active = {(c.source, c.output, c.target, c.input) for c in sys_.active_connections()}
        assert (truth <= active) == (mode == "ideal"), mode
        assert len(sys_.scalar_connections()) == 20          # exports write every connection


@pytest.mark.parametrize("mode, coupling", [("kalman", "gauss-seidel"), ("ideal", "gauss-seidel"),
                                            ("kalman", "jacobi")])
def test_the_plan_is_one_batched_call_per_run_of_signals(built_scenario, mode, coupling):
    """A connection that carries nothing is not in the plan; contiguous signals from one
    component to another travel in one fmi2SetReal."""
    fmus, cfg = built_scenario("paper")
    res = run_cosimulation(fmus, cfg, mode=mode, seed=0, steps=3, coupling=coupling)
    calls = res.info["calls_per_step"]
    meas = "fmi2SetReal (y, ybar, x, w, z from plant)" if mode == "ideal" else \
        "fmi2SetReal (y, ybar from plant)"
    assert calls.count(meas) == 1, calls
    assert not any("x, w, z" in c for c in calls) or mode == "ideal"
    assert calls.count("fmi2GetReal") == 3
    assert calls.count("fmi2SetReal (u from controller)") == 2     # plant and estimator
    assert sum(c.startswith("fmi2DoStep") for c in calls) == 3
    assert len(calls) == 10


def _two_loops(cfg, seeds=(3, 11)) -> SystemDescription:
    """Two independent paper loops in one system (suffixes _a, _b), different seeds."""
    comps, conns = [], []
    for suffix, seed in zip(("_a", "_b"), seeds):
        one = closed_loop_system(dict(cfg, estimator="kalman", seed=seed))
        comps += [replace(c, name=c.name + suffix) for c in one.components]
        conns += [replace(c, source=c.source + suffix, target=c.target + suffix,
                          when=None if c.when is None else (c.when[0] + suffix, *c.when[1:]))
                  for c in one.connections]
    return SystemDescription("two_loops", tuple(comps), tuple(conns), float(cfg["h"]),
                             float(cfg["T"]))


@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
def test_a_new_topology_is_a_new_description(built_scenario, coupling):
    """Six instances of the three FMUs in one co-simulation: each loop's traces are bit
    for bit those of the loop run alone with its seed."""
    fmus, cfg = built_scenario("paper")
    traces, _, info = run_system(_two_loops(cfg), fmus, 400, coupling=coupling)
    assert "plant_a.y" in traces and "controller_b.u" in traces and "y" not in traces
    for suffix, seed in (("_a", 3), ("_b", 11)):
        alone = run_cosimulation(fmus, cfg, mode="kalman", seed=seed, steps=400,
                                 coupling=coupling).traces
        for name, arr in alone.items():
            owner = {"y": "plant", "ybar": "plant", "x": "plant", "w": "plant", "z": "plant",
                     "e": "plant", "xhat": "estimator", "what": "estimator",
                     "zhat": "estimator", "u": "controller"}[name]
            assert np.array_equal(traces[f"{owner}{suffix}.{name}"], arr), (suffix, name)
    assert not np.array_equal(traces["plant_a.y"], traces["plant_b.y"])


def test_a_system_that_does_not_match_its_fmus_is_refused(built_scenario):
    fmus, cfg = built_scenario("paper")
    sys_ = closed_loop_system(dict(cfg, estimator="kalman"))
    bad = replace(sys_, connections=sys_.connections + (Connection("plant", "e", "controller", "y"),))
    with pytest.raises(CosimError, match=r"does not match its FMUs: connection plant\.e\[1\] -> "
                                         r"controller\.y\[1\]: controller \(AuvController\.fmu\) "
                                         r"has no variable 'y\[1\]'"):
        run_system(bad, fmus, 2)
    with pytest.raises(CosimError, match=r"no FMU given for controller"):
        run_system(sys_, {k: v for k, v in fmus.items() if k != "controller"}, 2)


def test_the_recording_places_every_output_of_the_loop(built_scenario):
    """The recording's layout and the loop's description name the same traces."""
    from orchestrator.recording import TRACE_KEYS
    _, cfg = built_scenario("paper")
    assert set(closed_loop_system(cfg).trace_names().values()) == set(TRACE_KEYS)
