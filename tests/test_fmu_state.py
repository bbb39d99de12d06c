"""FMU state on the real FMUs: get/set and serialize/deserialize reproduce runs bit for bit;
states that do not belong to an instance are refused with a named error, never a crash.

What a host sees for a refused state (pythonfmu 0.7 cannot return an error status from
fmi2SetFMUstate without turning it into fmi2Fatal; see fmu_common/fmu_state.py):
fmi2DeSerializeFMUstate and fmi2SetFMUstate return fmi2OK, fmi2SetFMUstate logs a message
with status fmi2Error naming the problem, the instance keeps its state, the next
fmi2DoStep returns fmi2Discard with the problem, and the step after that works.
"""
from __future__ import annotations

import ctypes
from contextlib import ExitStack

import numpy as np
import pytest
from fmpy import read_model_description
from numpy.testing import assert_array_equal

from fmu_common.interface import element_names
from fmu_common.slave_base import STATE_MAGIC, decode_state
from orchestrator.cosim.build import FMU_KINDS, STACKED_KINDS, build_fmu
from orchestrator.cosim.instance import Extracted, FmuInstance
from orchestrator.running import scenario_config
from orchestrator.scenario import load_scenario
from support.loop import fmu_parameters, output_names

OK, DISCARD = 0, 2
BLOCK = 2048          # rows per noise block of the plant (plant_model.plant.NoiseStream)


@pytest.fixture(scope="module")
def cfg(paper):
    return scenario_config(paper)


@pytest.fixture(scope="module")
def fmus(paper_fmus):
    return paper_fmus


@pytest.fixture(scope="module")
def hosts(fmus):
    """Instances made by a test are freed and their files removed at the end of the module."""
    with ExitStack() as stack:
        ex = Extracted(fmus)
        stack.callback(ex.cleanup)
        count = [0]

        def make(key: str, config=None, *, initialize: bool = True) -> FmuInstance:
            count[0] += 1
            inst = FmuInstance(key, fmus[key], ex.dirs[key], f"{key}_{count[0]}")
            stack.callback(inst.close)
            if initialize:
                inst.initialize(fmu_parameters(key, config), T=100.0)
            return inst

        yield make


def _raw(inst: FmuInstance, name: str, argtypes: list):
    f = inst.slave.dll[name]
    f.argtypes = argtypes
    f.restype = ctypes.c_int
    return f


def get_state(inst: FmuInstance) -> ctypes.c_void_p:
    state = ctypes.c_void_p()
    assert _raw(inst, "fmi2GetFMUstate", [ctypes.c_void_p, ctypes.c_void_p])(
        inst.component, ctypes.byref(state)) == OK
    return state


def set_state(inst: FmuInstance, state: ctypes.c_void_p) -> int:
    return _raw(inst, "fmi2SetFMUstate", [ctypes.c_void_p, ctypes.c_void_p])(inst.component, state)


def free_state(inst: FmuInstance, state: ctypes.c_void_p) -> None:
    assert _raw(inst, "fmi2FreeFMUstate", [ctypes.c_void_p, ctypes.c_void_p])(
        inst.component, ctypes.byref(state)) == OK


def serialize(inst: FmuInstance, state: ctypes.c_void_p) -> bytes:
    size = ctypes.c_size_t()
    assert _raw(inst, "fmi2SerializedFMUstateSize",
                [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p])(
        inst.component, state, ctypes.byref(size)) == OK
    buf = ctypes.create_string_buffer(size.value)
    assert _raw(inst, "fmi2SerializeFMUstate",
                [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t])(
        inst.component, state, buf, size.value) == OK
    return buf.raw


def deserialize(inst: FmuInstance, blob: bytes) -> ctypes.c_void_p:
    state = ctypes.c_void_p()
    buf = ctypes.create_string_buffer(blob, len(blob))
    status = _raw(inst, "fmi2DeSerializeFMUstate",
                  [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p])(
        inst.component, buf, len(blob), ctypes.byref(state))
    assert status == OK
    return state


class Loop:
    """The master's exact Gauss-Seidel loop over three instances, recording every signal."""

    def __init__(self, P: FmuInstance, E: FmuInstance, C: FmuInstance, config):
        d = config["dims"]
        self.P, self.E, self.C, self.h = P, E, C, float(config["h"])
        p_out = output_names("plant", config)
        e_out = output_names("estimator", config)
        u = element_names("u", (d["m"],))
        self.vr = {"p_out": P.vrs(p_out), "p_u": P.vrs(u), "e_in": E.vrs(p_out[:2 * d["p"]]),
                   "e_u": E.vrs(u), "e_out": E.vrs(e_out), "c_in": C.vrs(e_out),
                   "c_out": C.vrs(u)}
        self.n = (len(p_out), len(e_out), d["m"], 2 * d["p"])

    def run(self, k0: int, steps: int) -> np.ndarray:
        """Steps k0 ... k0 + steps - 1; rows [plant outputs, estimates, u]."""
        P, E, C, vr = self.P, self.E, self.C, self.vr
        n_p, n_e, n_u, n_meas = self.n
        rec = np.zeros((steps, n_p + n_e + n_u))
        for j in range(steps):
            k = k0 + j
            row = rec[j]
            yp = row[:n_p].ctypes.data
            ye = row[n_p:n_p + n_e].ctypes.data
            yu = row[n_p + n_e:].ctypes.data
            t = k * self.h
            for status in (P.get_real(P.component, vr["p_out"], n_p, yp),
                           E.set_real(E.component, vr["e_in"], n_meas, yp),
                           E.get_real(E.component, vr["e_out"], n_e, ye),
                           C.set_real(C.component, vr["c_in"], n_e, ye),
                           C.get_real(C.component, vr["c_out"], n_u, yu),
                           P.set_real(P.component, vr["p_u"], n_u, yu),
                           E.set_real(E.component, vr["e_u"], n_u, yu),
                           P.do_step(P.component, t, self.h, 1),
                           E.do_step(E.component, t, self.h, 1),
                           C.do_step(C.component, t, self.h, 1)):
                assert status == OK, (k, P.errors(), E.errors(), C.errors())
        return rec


def _three(hosts, cfg):
    return [hosts(key, cfg) for key in ("plant", "estimator", "controller")]


def test_model_descriptions_declare_fmu_state(fmus):
    for key in STACKED_KINDS:
        cs = read_model_description(str(fmus[key])).coSimulation
        assert cs.canGetAndSetFMUstate and cs.canSerializeFMUstate, key


def test_get_run_set_run_is_bit_identical(hosts, cfg):
    """(1) closed loop: k steps, save all three, m steps, restore, the same m steps."""
    insts = _three(hosts, cfg)
    loop = Loop(*insts, cfg)
    k, m = 300, 200
    loop.run(0, k)
    states = [get_state(i) for i in insts]
    first = loop.run(k, m)
    for inst, st in zip(insts, states):
        assert set_state(inst, st) == OK
    second = loop.run(k, m)
    assert_array_equal(second, first)
    # the same state restores again (it is not consumed), and the loop really moved
    for inst, st in zip(insts, states):
        assert set_state(inst, st) == OK
        free_state(inst, st)
    assert_array_equal(loop.run(k, m), first)
    assert np.std(first[:, 0]) > 0.1
    for inst in insts:
        assert not any(s in ("Error", "Fatal") for s, _ in inst.messages), inst.errors()


def test_serialize_into_fresh_instances_is_bit_identical(hosts, cfg):
    """(2) serialize -> fresh instances (instantiated, initialized) -> deserialize -> run."""
    insts = _three(hosts, cfg)
    loop = Loop(*insts, cfg)
    k, m = 250, 200
    loop.run(0, k)
    blobs = []
    for inst in insts:
        st = get_state(inst)
        blobs.append(serialize(inst, st))
        free_state(inst, st)
    first = loop.run(k, m)
    fresh = _three(hosts, cfg)
    for inst, blob in zip(fresh, blobs):
        assert blob.startswith(STATE_MAGIC)
        assert set_state(inst, deserialize(inst, blob)) == OK
    assert_array_equal(Loop(*fresh, cfg).run(k, m), first)
    # serializing a deserialized state gives the same bytes
    again = deserialize(fresh[0], blobs[0])
    assert serialize(fresh[0], again) == blobs[0]


def test_restore_rebuilds_the_mathematics_when_parameters_differ(hosts, cfg, paper):
    """A fresh instance initialized with other parameters (seed, Q, noise), or not
    initialized at all, takes the state's parameters and reproduces the run."""
    insts = _three(hosts, cfg)
    loop = Loop(*insts, cfg)
    loop.run(0, 120)
    blobs = [serialize(i, get_state(i)) for i in insts]
    first = loop.run(120, 150)
    other = dict(cfg, seed=cfg["seed"] + 5,
                 system=dict(cfg["system"], Q=[[7.0, 0.0], [0.0, 3.0]],
                             V_y=[[1.0, 0.0], [0.0, 1.0]]))
    plant = hosts("plant", other)
    estimator = hosts("estimator", other)
    controller = hosts("controller", initialize=False)      # instantiated only
    for inst, blob in zip((plant, estimator, controller), blobs):
        assert set_state(inst, deserialize(inst, blob)) == OK
        assert not any(s in ("Error", "Fatal") for s, _ in inst.messages), inst.errors()
    assert_array_equal(Loop(plant, estimator, controller, cfg).run(120, 150), first)
    seed = plant.slave.getInteger([plant.vr["seed"]])[0]
    assert seed == cfg["seed"]


@pytest.mark.parametrize("k", [BLOCK - 60, BLOCK + 5])
def test_plant_state_across_a_noise_block_boundary(hosts, cfg, k):
    """(3) the plant alone, fixed u sequence: a state saved before the block of noise rows
    is refilled (k = 1988) and restored after the run went past the refill, and a state
    saved just after a refill (k = 2053), reproduce exactly, in memory and serialized."""
    P = hosts("plant", cfg)
    h = float(cfg["h"])
    vr_u = P.vrs(element_names("u", (2,)))
    names = output_names("plant", cfg)
    vr_y = P.vrs(names)
    m = 200
    u_seq = np.column_stack([np.sin(0.01 * np.arange(k + m)), np.cos(0.013 * np.arange(k + m))])

    def run(inst, k0, steps):
        out = np.zeros((steps, len(names)))
        for j in range(steps):
            kk = k0 + j
            u = np.ascontiguousarray(u_seq[kk])
            assert inst.set_real(inst.component, vr_u, 2, u.ctypes.data) == OK
            assert inst.do_step(inst.component, kk * h, h, 1) == OK, inst.errors()
            assert inst.get_real(inst.component, vr_y, len(names), out[j].ctypes.data) == OK
        return out

    run(P, 0, k)
    st = get_state(P)
    blob = serialize(P, st)
    _, tree = decode_state(blob)
    pending = tree["model"]["noise"]["pending"].shape[0]
    assert tree["model"]["k"] == k
    if k < BLOCK:
        assert pending == BLOCK - k - 1 < m       # the block runs out during the m steps
    else:
        assert pending == 2 * BLOCK - k - 1 > BLOCK - 10      # refilled just before
    first = run(P, k, m)            # crosses (or follows) a refill of the 2048-row block
    assert set_state(P, st) == OK
    assert_array_equal(run(P, k, m), first)
    fresh = hosts("plant", cfg)
    assert set_state(fresh, deserialize(fresh, blob)) == OK
    assert_array_equal(run(fresh, k, m), first)


# ------------------------------------------------- the math modules, without FMI
def test_plant_and_estimator_state_round_trip_without_fmi(paper):
    from estimator_fmu.registry import make_estimator
    from plant_model.discretization import discretize
    from plant_model.plant import Plant

    model = discretize(paper.system, paper.h)
    plant = Plant(model, paper.system.initial_state(), seed=3)
    est = make_estimator(paper.system, model, "kalman")
    u = np.array([0.3, -0.2])

    def run(steps):
        out = []
        for _ in range(steps):
            e = est.estimate(np.concatenate([plant.output[:4], plant.s]))
            est.update(e, u)
            plant.step(u)
            out.append(np.concatenate([plant.output, e]))
        return np.array(out)

    run(BLOCK - 3)
    ps, es = plant.get_state(), est.get_state()
    first = run(10)                       # crosses a block refill
    plant.set_state(ps)
    est.set_state(es)
    assert_array_equal(run(10), first)
    # the saved state is a copy: running on did not change it, it restores again
    plant.set_state(ps)
    est.set_state(es)
    assert_array_equal(run(10), first)
    # invalid states are refused before anything changes
    k, s = plant.k, plant.s.copy()
    for bad, match in ((dict(ps, s=np.zeros(3)), "plant state s"),
                       (dict(ps, seed=99), "seed 99"),
                       (dict(ps, noise=dict(ps["noise"], dim=4)), "rows of 4"),
                       (dict(ps, noise=dict(ps["noise"], bit_generator={"x": 1})),
                        "noise generator state")):
        with pytest.raises(ValueError, match=match):
            plant.set_state(bad)
        assert plant.k == k and np.array_equal(plant.s, s)
    with pytest.raises(ValueError, match="mode 'ideal'"):
        est.set_state(dict(es, mode="ideal"))
    with pytest.raises(ValueError, match="shape"):
        est.set_state(dict(es, q=np.zeros(2)))


# ----------------------------------------------------------------- bad states
def _refused(inst: FmuInstance, state, *fragments: str) -> None:
    """Setting ``state`` is refused as documented and the instance goes on unchanged."""
    vrs = inst.vrs([v.name for v in inst.md.modelVariables if v.causality == "output"])
    before = (ctypes.c_double * len(vrs))()
    after = (ctypes.c_double * len(vrs))()
    assert inst.get_real(inst.component, vrs, len(vrs), before) == OK
    n = len(inst.messages)
    assert set_state(inst, state) == OK                 # pythonfmu 0.7 cannot say more here
    new = inst.messages[n:]
    errors = [m for s, m in new if s == "Error"]
    assert errors and all(f in errors[-1] for f in fragments), new
    assert "rejected the state" in errors[-1]
    assert not any(s == "Fatal" for s, _ in new)
    assert inst.get_real(inst.component, vrs, len(vrs), after) == OK
    assert list(after) == list(before)                  # nothing changed
    h = 0.01
    t0 = getattr(inst, "t_next", 0.0)       # the instance steps forward in time only
    assert inst.do_step(inst.component, t0, h, 1) == DISCARD
    refusal = inst.messages[-1]
    assert refusal[0] == "Error" and "refused" in refusal[1]
    assert all(f in refusal[1] for f in fragments)
    for j in range(3):                                   # and then it steps again
        assert inst.do_step(inst.component, t0 + j * h, h, 1) == OK, inst.errors()
    inst.t_next = t0 + 3 * h


def test_controller_state_into_the_plant_is_refused(hosts, cfg):
    C = hosts("controller", cfg)
    blob = serialize(C, get_state(C))
    P = hosts("plant", cfg)
    _refused(P, deserialize(P, blob), "'AuvController'", "not of 'AuvPlant'")
    # the in-memory state object of another FMU is refused the same way
    _refused(P, get_state(C), "'AuvController'", "not of 'AuvPlant'")


def test_truncated_garbage_and_corrupt_blobs_are_refused(hosts, cfg):
    P = hosts("plant", cfg)
    blob = serialize(P, get_state(P))
    _refused(P, deserialize(P, blob[:len(blob) // 2]), "truncated", f"announces {len(blob)}")
    _refused(P, deserialize(P, blob[:12]), "truncated", "shorter than")
    _refused(P, deserialize(P, b""), "truncated")
    _refused(P, deserialize(P, b"{\"json\": 1}" + bytes(40)), "not a serialized state")
    corrupt = bytearray(blob)
    corrupt[-100] ^= 0x40
    _refused(P, deserialize(P, bytes(corrupt)), "corrupt", "CRC-32")
    _refused(P, deserialize(P, blob + b"\0"), "1 unexpected bytes")
    other_format = bytearray(blob)
    other_format[8] = 99
    _refused(P, deserialize(P, bytes(other_format)), "format version 99")
    # after all that, a good blob still restores
    assert set_state(P, deserialize(P, blob)) == OK
    assert P.do_step(P.component, 0.0, 0.01, 1) == OK


def test_state_of_an_fmu_built_for_another_scenario_is_refused(hosts, cfg, tmp_path):
    """The formation-4 plant (other variables and sizes) into the paper's plant."""
    f4 = scenario_config(load_scenario("formation-4"))
    path = build_fmu(FMU_KINDS["plant"], f4, tmp_path / "f4")
    ex = Extracted({"plant": path})
    other = FmuInstance("plant", path, ex.dirs["plant"], "f4_plant")
    try:
        other.initialize(fmu_parameters("plant", f4), T=1.0)
        assert other.do_step(other.component, 0.0, 0.01, 1) == OK
        blob = serialize(other, get_state(other))
    finally:
        other.close()
        ex.cleanup()
    P = hosts("plant", cfg)
    _refused(P, deserialize(P, blob), "another interface", "A is missing from the state",
             "interface hash")


def test_state_of_another_build_with_the_same_interface_restores_with_a_warning(
        hosts, cfg, tmp_path):
    """pythonfmu gives every build a new GUID; the same interface restores, with a warning."""
    path = build_fmu(FMU_KINDS["plant"], cfg, tmp_path / "again")
    ex = Extracted({"plant": path})
    other = FmuInstance("plant", path, ex.dirs["plant"], "plant_rebuilt")
    try:
        other.initialize(fmu_parameters("plant", cfg), T=1.0)
        for j in range(7):
            assert other.do_step(other.component, j * 0.01, 0.01, 1) == OK
        blob = serialize(other, get_state(other))
        x = other.slave.getReal([other.vr["x[1]"], other.vr["x[2]"]])
    finally:
        other.close()
        ex.cleanup()
    P = hosts("plant", cfg)
    assert set_state(P, deserialize(P, blob)) == OK
    warnings = [m for s, m in P.messages if s == "Warning"]
    guid = read_model_description(str(path)).guid
    assert any("another build" in m and guid in m for m in warnings), P.messages
    assert P.slave.getReal([P.vr["x[1]"], P.vr["x[2]"]]) == x
    assert P.do_step(P.component, 0.07, 0.01, 1) == OK


def test_blob_sizes_and_header(hosts, cfg):
    """The header names the model, the build (GUID), the interface and the format."""
    import json
    import struct

    for key, model in (("plant", "AuvPlant"), ("estimator", "AuvEstimator"),
                       ("controller", "AuvController")):
        inst = hosts(key, cfg)
        blob = serialize(inst, get_state(inst))
        magic, fmt, _, hlen, plen, _ = struct.unpack_from("<8sHHIQI", blob)
        assert magic == STATE_MAGIC and fmt == 1 and len(blob) == 28 + hlen + plen
        header = json.loads(blob[28:28 + hlen])
        assert header["model"] == model
        assert header["guid"] == inst.md.guid
        assert len(header["interface"]) == 16
        assert header["instance"].startswith(key)
        # the plant carries the pending noise rows of its block (at most 2048 x 10 values)
        limit = 170_000 if key == "plant" else 12_000
        assert len(blob) < limit, (key, len(blob))
