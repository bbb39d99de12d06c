"""The native AuvNetwork FMU (AuvNetworkNative, fmu_common/native/network_fmu.c) against the
pythonfmu AuvNetwork it replaces: the same variables, the same messages delivered and lost at
the same steps (every count, age and held value bit for bit; a propagated value to 1e-13 of
its scale: rx <- M rx in C sums in order, numpy's BLAS in its own order), the same loss
stream when seed, keys and timing are set per component, a refused parameter or input named
in the log, and its FMU state restored bit for bit."""
from __future__ import annotations

import shutil

import numpy as np
import pytest
from test_network_fmu import BURSTY_CONFIG, CONFIG, SCHED_CONFIG, H, _drive, _names

from orchestrator.cosim.build import build_fmus
from orchestrator.cosim.instance import CosimError, Extracted, FmuInstance
from orchestrator.cosim.native_network import native_network_fmu
from plant_model.acoustic.links import link_key
from support.fmi import assert_state_round_trip

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler (cc)")

#: CONFIG with a modem range of 10 m: the receiver's and the senders' true states (6 values,
#: position first) decide which messages are heard; the leader's position is H z
RANGE_CONFIG = dict(CONFIG, range=10.0, state_size=6, position_index=[0, 1, 2],
                    leader_H=[[1.0, 0.0], [0.0, 1.0], [0.5, 0.5]])
#: a key and a seed of another component, and a longer latency than the start values
OTHER = {"seed": 99, "link[1].key": link_key(4, 3), "link[2].latency": 5.0,
         "leader.loss": 0.5, "link[1].offset": 0.4}
#: a modem range and no leader link (a planned leader)
NO_LEADER = dict(CONFIG, leader_size=0, leader=None, range=8.0, state_size=6,
                 position_index=[0, 1, 2])
CONFIGS = {"plain": CONFIG, "sched": SCHED_CONFIG, "range": RANGE_CONFIG,
           "no_leader": NO_LEADER, "bursty": BURSTY_CONFIG}


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    """Per configuration: the pythonfmu FMU, its native FMU (sized for OTHER too)."""
    out = {}
    for key, cfg in CONFIGS.items():
        folder = tmp_path_factory.mktemp(key)
        py = build_fmus(None, folder, kinds={"network": cfg})["network"]
        out[key] = (py, native_network_fmu(py, folder / "native", [OTHER]))
    paths = {f"{k}-{i}": p for k, ps in out.items() for i, p in enumerate(ps)}
    ex = Extracted(paths)
    yield out, ex
    ex.cleanup()


def _open(pair, key, native, name, **override):
    out, ex = pair
    inst = FmuInstance("network", out[key][native], ex.dirs[f"{key}-{native}"], name)
    inst.initialize(override, T=30.0)
    return inst


def _inputs(inst, steps, seed):
    """Random tx inputs; true states (with a range) spread over about +-5 m."""
    n = len(_names(inst, "input"))
    return 4.0 * np.random.default_rng(seed).standard_normal((steps, n))


def _both(pair, key, steps=300, input_seed=3, **override):
    """The outputs per step of the pythonfmu and the native FMU on the same inputs."""
    rec = []
    for native in (0, 1):
        inst = _open(pair, key, native, f"{key}{native}{len(override)}", **override)
        names = _names(inst, "output")
        rec.append(_drive(inst, _inputs(inst, steps, input_seed), 0))
        inst.close()
    return rec[0], rec[1], names


def _propagated(names, key):
    """The output columns of propagated links (M not I in CONFIG): link[2] and leader rx."""
    return np.array([n.startswith(("link[2].rx.", "leader.rx.")) for n in names])


CASES = [(k, o) for k in CONFIGS for o in ("start", "other") if (k, o) != ("no_leader", "other")]


@pytest.mark.parametrize("key, which", CASES, ids=["-".join(c) for c in CASES])
def test_native_delivers_and_loses_what_the_pythonfmu_network_does(pair, key, which):
    py, nat, names = _both(pair, key, **(OTHER if which == "other" else {}))
    prop = _propagated(names, key)
    assert py.shape == nat.shape == (300, len(names))
    assert np.array_equal(py[:, ~prop], nat[:, ~prop])          # counts, ages, held values
    scale = np.max(np.abs(py[:, prop]), axis=0)
    assert np.all(np.abs(nat[:, prop] - py[:, prop]) <= 1e-13 * scale)
    links = ("link[1]", "link[2]", "leader")[:3 if CONFIGS[key]["leader_size"] else 2]
    lost = [names.index(f"{p}.lost") for p in links]
    delivered = [names.index(f"{p}.delivered") for p in links]
    assert np.all(nat[-1, lost] > 0) and np.all(nat[-1, delivered] > 0)   # both happened


def test_the_range_and_the_schedule_change_what_is_heard(pair):
    plain, _, names = _both(pair, "plain")
    ranged, _, _ = _both(pair, "range")
    sched, _, _ = _both(pair, "sched")
    lost = [names.index(f"{p}.lost") for p in ("link[1]", "link[2]", "leader")]
    assert np.all(ranged[-1, lost] >= plain[-1, lost]) and ranged[-1, lost].sum() > \
        plain[-1, lost].sum()
    assert sched[-1, lost].sum() > plain[-1, lost].sum()


def test_another_seed_or_key_draws_other_losses(pair):
    a, _, names = _both(pair, "plain")
    b, _, _ = _both(pair, "plain", seed=12)
    assert not np.array_equal(a[:, names.index("link[1].lost")], b[:, names.index("link[1].lost")])


def test_the_native_fmu_validates_with_the_pythonfmu_variables(pair):
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu
    for key in CONFIGS:
        py, nat = pair[0][key]
        assert validate_fmu(str(nat)) == []
        a, b = read_model_description(str(py)), read_model_description(str(nat))
        assert not b.coSimulation.needsExecutionTool
        assert b.coSimulation.modelIdentifier == "AuvNetworkNative"
        fields = ("name", "type", "causality", "variability", "unit", "description", "start")
        assert [[getattr(v, f) for f in fields] for v in a.modelVariables] == \
            [[getattr(v, f) for f in fields] for v in b.modelVariables]
        assert [u.variable.name for u in a.outputs] == [u.variable.name for u in b.outputs]
        assert all(not u.dependencies for u in b.outputs)
        for t in ("Real", "Integer"):               # value references 0.. per type
            vrs = [v.valueReference for v in b.modelVariables if v.type == t]
            assert vrs == list(range(len(vrs)))


def test_native_fmu_state_round_trip_is_bit_identical(pair):
    inst = _open(pair, "sched", 1, "state")
    first = assert_state_round_trip(inst, _drive, _inputs(inst, 300, 4), 120)
    assert first[-1, _names(inst, "output").index("link[2].lost")] > 0
    inst.close()


@pytest.mark.parametrize("name, value, fragment", [
    ("link[1].loss", 1.0, "link[1].loss: link[1] of vehicle 3: loss = 1 is not a probability"),
    ("link[1].period", 2.05, "link[1].period: link[1] of vehicle 3: period = 2.05 s is not a "
     "whole number of steps"),
    ("leader.offset", 2.5, "leader.offset: leader link of vehicle 3: offset = 2.5 s is not"),
    ("link[1].latency", 50.0, "link[1].latency: link[1] of vehicle 3: latency = 50 s at a "
     "period of 2 s puts up to 26 messages in flight; this native FMU was built for at most"),
    ("seed", -1, "parameter seed = -1 must not be negative"),
    ("h", 0.0, "parameter h = 0 s must be a positive number"),
])
def test_a_bad_parameter_fails_initialization_naming_it(pair, name, value, fragment):
    with pytest.raises(CosimError) as exc:
        _open(pair, "plain", 1, f"bad_{name}", **{name: value})
    assert "initialization failed" in str(exc.value) and fragment in str(exc.value)


@pytest.mark.parametrize("name, value, fragment", [
    ("link[1].p_bg", 1.5, "link[1].p_bg: link[1] of vehicle 3: p_bg = 1.5 is not a "
     "probability in (0, 1]"),
    ("leader.loss_bad", 0.01, "leader.loss_bad: leader link of vehicle 3: loss_bad = 0.01 is "
     "below loss_good = 0.05"),
    ("link[2].loss_model", 2, "link[2].loss_model: link[2] of vehicle 3: loss_model = 2 is "
     "not one of 0 (independent), 1 (gilbert-elliott)"),
])
def test_a_bad_bursty_parameter_fails_naming_it(pair, name, value, fragment):
    with pytest.raises(CosimError) as exc:
        _open(pair, "bursty", 1, f"bad_{name}", **{name: value})
    assert fragment in str(exc.value)


@pytest.mark.parametrize("name, value, fragment", [
    ("schedule.t[2]", 3.05, "schedule.t[2] = 3.05 s is not a whole number of steps"),
    ("schedule.period", 2.0, "schedule.period = 2 s must be 0 or after the last switch"),
    ("link[2].up[1]", 2, "link[2].up[1] = 2 must be 0 or 1"),
])
def test_a_bad_schedule_parameter_fails_naming_it(pair, name, value, fragment):
    with pytest.raises(CosimError) as exc:
        _open(pair, "sched", 1, f"bad_{name}", **{name: value})
    assert fragment in str(exc.value)


def test_a_non_finite_input_is_refused_naming_it_and_the_fmu_goes_on(pair):
    inst = _open(pair, "plain", 1, "nan")
    vin = [inst.vr[n] for n in _names(inst, "input")]
    inst.slave.setReal(vin, [0.0] * len(vin))
    inst.slave.setReal([inst.vr["link[2].tx.eps[1]"]], [float("nan")])
    status = inst.do_step(inst.component, 0.0, H, 1)
    assert status == 3 and "input link[2].tx.eps[1] = nan is not finite" in inst.errors()
    inst.slave.setReal([inst.vr["link[2].tx.eps[1]"]], [1.0])
    assert inst.do_step(inst.component, 0.0, H, 1) == 0
    inst.close()


@pytest.mark.slow
def test_export_native_ships_the_native_network_and_libcosim_runs_it(tmp_path):
    """`auv-cosim export native` of a fleet over links: AuvNetworkNative.fmu beside the
    other native FMUs, no FMU that needs Python, and libcosim runs the OSP system to our
    Jacobi master's traces bit for bit (links' deliveries, losses and ages included)."""
    pytest.importorskip("libcosimpy")
    from fmpy import read_model_description

    from orchestrator.cosim.master import run_system
    from orchestrator.cosim.native import native_system
    from orchestrator.interop import libcosim
    from orchestrator.interop.native import export_native
    from orchestrator.running.systems import build, scenario_system
    from orchestrator.scenario import load_scenario
    libcosim.quiet_libcosim()
    sc = load_scenario("formation-4").with_run(
        T=20.0, deployment="per-vehicle", architecture="distributed",
        network={"latency": 1.0, "period": 2.0, "loss": 0.2})
    paths = export_native(sc, tmp_path / "x")
    fmus = {p.name for p in paths.values() if p.suffix == ".fmu"}
    assert "AuvNetworkNative.fmu" in fmus and "AuvNetwork.fmu" not in fmus
    assert not any(read_model_description(str(p)).coSimulation.needsExecutionTool
                   for p in paths.values() if p.suffix == ".fmu")
    ns = native_system(scenario_system(sc), build(sc, tmp_path / "py"), tmp_path / "n2")
    steps = sc.steps
    lc = libcosim.run_libcosim(paths["system"], ns.system, steps)
    ours, _, _ = run_system(ns.system, ns.fmus, steps, coupling="jacobi")
    assert set(lc["traces"]) == set(ours)
    for key, arr in lc["traces"].items():
        assert np.array_equal(arr, ours[key]), key
    for count in (".lost", ".delivered"):           # both happened
        assert sum(float(ours[k][-1].max()) for k in ours if k.endswith(count)) > 0, count


def test_a_native_run_of_another_seed_gives_its_links_that_seed(tmp_path):
    """--fmus native builds the system for the scenario's seed; a run of another seed (a
    campaign's, compare's) gives every network component that seed, as the pythonfmu run
    does, so its loss streams are that seed's."""
    from orchestrator.running.systems import make_setup
    from orchestrator.scenario import load_scenario
    sc = load_scenario("formation-4").with_run(
        T=2.0, deployment="per-vehicle", architecture="distributed", fmus="native",
        network={"latency": 1.0, "period": 2.0, "loss": 0.2})
    setup = make_setup(sc, tmp_path)
    method = setup.methods[0]
    assert setup.fmu_report(method)["network"]["kind"] == "native"
    other = sc.seed + 4
    native = {c.name: c for c in setup.system(method, other).components}
    python = {c.name: c for c in setup.python_system(method, other).components}
    nets = [n for n, c in native.items() if c.fmu == "network"]
    assert len(nets) == 4
    for n in nets:
        assert native[n].parameters["seed"] == python[n].parameters["seed"] == other
        assert native[n].parameters == python[n].parameters


@pytest.mark.slow
@pytest.mark.parametrize("architecture", ["distributed", "centralized"])
def test_a_fleet_over_links_runs_native_to_the_pythonfmu_traces(tmp_path, architecture):
    """`auv-cosim run` of formation-4 per vehicle with --latency 1 --period 2 --loss 0.2,
    --fmus python and native: the native run has no pythonfmu FMU (the compiled master runs
    it), every link's delivered / lost / in-flight trace equals the pythonfmu run's bit for
    bit, and every other trace to 1e-12 of its scale."""
    import json

    from orchestrator.cli import main
    from orchestrator.recording import read_rrd_scalars
    runs = {}
    for fm in ("python", "native"):
        out = tmp_path / fm
        assert main(["run", "--scenario", "formation-4", "--T", "10", "--seed", "5",
                     "--quiet", "--out", str(out), "--fmus", fm, "--deployment",
                     "per-vehicle", "--architecture", architecture, "--latency", "1",
                     "--period", "2", "--loss", "0.2"]) == 0
        s = json.loads((out / "summary.json").read_text())
        runs[fm] = (s, read_rrd_scalars(out / f"{s['scenario']}.rrd"))
    assert {e["kind"] for e in runs["native"][0]["fmus"].values()} == {"native"}
    assert set(runs["native"][0]["master"].values()) == {"native"}
    ref, got = runs["python"][1], runs["native"][1]
    assert set(ref) == set(got)
    links = [e for e in ref if e.startswith("network/links/")]
    assert links and all(np.array_equal(ref[e][2], got[e][2]) for e in links)
    assert sum(float(np.asarray(ref[e][2])[-1, 1]) for e in links) > 0      # losses
    for entity, (_, _, values) in ref.items():
        scale = max(float(np.nanmax(np.abs(values))), 1e-300)
        assert np.nanmax(np.abs(got[entity][2] - values)) <= 1e-12 * scale, entity
