"""The AuvNetwork FMU (one vehicle's acoustic inbox) under fmpy, against LinkChannel."""
from __future__ import annotations

import math

import numpy as np
import pytest

from orchestrator.cosim.build import build_fmus
from orchestrator.cosim.instance import CosimError, Extracted, FmuInstance
from plant_model.acoustic.inbox import Inbox, LinkSettings
from plant_model.acoustic.link_models import LINK_MODELS, MODEL_KEY, model_of_code
from plant_model.acoustic.links import LinkChannel, check_link, link_key
from support.fmi import assert_state_round_trip

H, RECEIVER, SEED = 0.1, 3, 11
FIELDS = [["eta", 3], ["eps", 2]]
#: a propagating receiver: eta as a double integrator chain, eps decaying
M_PROP = np.block([[np.array([[1.0, H, 0.0], [0.0, 1.0, H], [0.0, 0.0, 1.0]]), np.zeros((3, 2))],
                   [np.zeros((2, 3)), np.array([[0.9, 0.1], [0.0, 0.95]])]])
M_LEADER = np.array([[1.0, H], [-0.05 * H, 1.0]])


def _link(key, M, rx0, offset=0.0, latency=1.0, period=2.0, loss=0.3):
    return {"latency": latency, "period": period, "loss": loss, "offset": offset, "key": key,
            "M": np.asarray(M).tolist(), "rx0": list(rx0)}


CONFIG = {
    "h": H, "T": 30.0, "seed": SEED, "receiver": RECEIVER, "slots": 2, "fields": FIELDS,
    "leader_size": 2,
    "links": [_link(link_key(1, RECEIVER), np.eye(5), [0.5, -1.0, 2.0, 0.1, 0.2]),
              _link(link_key(2, RECEIVER), M_PROP, [1.0, 0.0, -0.5, 0.3, -0.3], offset=0.5)],
    "leader": _link(link_key("leader", RECEIVER), M_LEADER, [0.4, 0.5]),
}
#: one link, a message every step: many messages for the loss statistics
STATS_CONFIG = {"h": H, "T": 500.0, "seed": 5, "receiver": 1, "slots": 1,
                "fields": [["x", 1]], "leader_size": 0, "leader": None,
                "links": [_link(link_key(2, 1), [[1.0]], [0.0], latency=0.0, period=H,
                                loss=0.2)]}


#: CONFIG with a switching schedule: graphs from 0 s and 3 s, repeating every 7 s
SCHEDULE = {"t": [0.0, 3.0], "period": 7.0}
SCHED_CONFIG = dict(CONFIG, schedule=SCHEDULE,
                    links=[dict(CONFIG["links"][0], up=[1, 0]), dict(CONFIG["links"][1], up=[0, 1])],
                    leader=dict(CONFIG["leader"], up=[1, 1]))
#: CONFIG with bursty links (plant_model.acoustic.link_models): link[1] and the leader's a
#: Gilbert-Elliott channel each, link[2] independent
GE = {MODEL_KEY: 1, "p_gb": 0.15, "p_bg": 0.3, "loss_good": 0.05, "loss_bad": 0.9}
BURSTY_CONFIG = dict(CONFIG, loss_models=True,
                     links=[dict(CONFIG["links"][0], **GE), CONFIG["links"][1]],
                     leader=dict(CONFIG["leader"], **dict(GE, p_gb=0.4)))


def _model(st):
    """A link's loss model from its configuration entry (a row of link_models)."""
    code = st.get(MODEL_KEY, 0)
    row = list(LINK_MODELS.values())[code]
    return model_of_code("ref", code, {k: st[k] for k in row.PARAMETERS})


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    paths = {}
    for key, cfg in (("network", CONFIG), ("stats", STATS_CONFIG), ("sched", SCHED_CONFIG),
                     ("bursty", BURSTY_CONFIG)):
        paths[key] = build_fmus(None, tmp_path_factory.mktemp(key),
                                kinds={"network": cfg})["network"]
    ex = Extracted(paths)
    yield paths, ex
    ex.cleanup()


def _instance(built, name, key="network", **override):
    fmus, ex = built
    inst = FmuInstance("network", fmus[key], ex.dirs[key], name)
    inst.initialize(override, T=30.0)
    return inst


def _names(inst, causality):
    return [v.name for v in inst.md.modelVariables if v.causality == causality]


def _drive(inst, inputs, k0):
    """Set the tx inputs of each row, read every output, step; the outputs per step."""
    s = inst.slave
    vin = [inst.vr[n] for n in _names(inst, "input")]
    vout = [inst.vr[n] for n in _names(inst, "output")]
    rec = []
    for j, row in enumerate(inputs):
        s.setReal(vin, list(row))
        rec.append(s.getReal(vout))
        s.doStep((k0 + j) * H, H)
    return np.array(rec)


def _reference(config, inputs):
    """The same links as bare LinkChannels (M = I held without M): outputs per step; with a
    schedule a link loses what it sends while it is down."""
    from plant_model.acoustic.schedule import LinkSchedule
    sch = config.get("schedule")
    layout = [(st, [n for _, n in config["fields"]]) for st in config["links"]]
    if config["leader_size"]:
        layout.append((config["leader"], [config["leader_size"]]))
    chans = []
    for st, _ in layout:
        M = np.array(st["M"])
        chans.append(LinkChannel(check_link("ref", st["latency"], st["period"], _model(st),
                                            st["offset"]), config["h"], config["seed"],
                                 st["key"], np.array(st["rx0"]),
                                 None if np.array_equal(M, np.eye(len(M))) else M))
    widths = [sum(sizes) for _, sizes in layout]
    up = (LinkSchedule(tuple(round(t / config["h"]) for t in sch["t"]),
                       round(sch["period"] / config["h"]),
                       {j: tuple(map(bool, st["up"])) for j, (st, _) in enumerate(layout)})
          if sch else None)
    rec = []
    for k, row in enumerate(inputs):
        out, pos = [], 0
        for j, (ch, w) in enumerate(zip(chans, widths)):
            out += [*ch.rx, ch.age(k), ch.delivered, ch.lost, len(ch.in_flight)]
            ch.advance(k, row[pos:pos + w], up is None or up.is_up(j, k))
            pos += w
        rec.append(out)
    return np.array(rec), chans


def test_the_interface_names_every_link_field_and_statistic(built):
    inst = _instance(built, "names")
    ins, outs = _names(inst, "input"), _names(inst, "output")
    assert ins[:6] == ["link[1].tx.eta[1]", "link[1].tx.eta[2]", "link[1].tx.eta[3]",
                       "link[1].tx.eps[1]", "link[1].tx.eps[2]", "link[2].tx.eta[1]"]
    assert ins[-2:] == ["leader.tx.z[1]", "leader.tx.z[2]"] and len(ins) == 12
    assert outs[5:9] == ["link[1].age", "link[1].delivered", "link[1].lost", "link[1].in_flight"]
    assert outs[-6:] == ["leader.rx.z[1]", "leader.rx.z[2]", "leader.age", "leader.delivered",
                         "leader.lost", "leader.in_flight"]
    params = set(_names(inst, "parameter"))
    assert {"link[2].latency", "link[2].period", "link[2].loss", "link[2].offset",
            "link[2].key", "link[2].M[5,5]", "link[2].rx0[5]", "leader.M[2,2]",
            "leader.key", "h", "seed"} <= params
    assert inst.types["link[1].key"] == "Integer" and inst.types["seed"] == "Integer"
    inst.close()


def test_every_output_equals_the_link_channels_bit_for_bit(built):
    inst = _instance(built, "bits")
    inputs = np.random.default_rng(3).standard_normal((300, 12))
    got = _drive(inst, inputs, 0)
    want, chans = _reference(CONFIG, inputs)
    assert got.shape == want.shape and np.array_equal(got, want)
    assert all(ch.lost > 0 and ch.delivered > 0 for ch in chans)     # both kinds happened
    assert got[-1, 5] == pytest.approx(chans[0].age(299))
    inst.close()


def test_a_schedule_switches_the_links_in_the_fmu_as_in_link_channels(built):
    """link[1] up only in the first graph (0-3 s of every 7 s), link[2] only in the second:
    the outputs equal LinkChannels that lose what a down link sends, and a message sent
    in a link's off time is counted lost."""
    inst = _instance(built, "sched", key="sched")
    inputs = np.random.default_rng(6).standard_normal((300, 12))
    got = _drive(inst, inputs, 0)
    want, chans = _reference(SCHED_CONFIG, inputs)
    assert np.array_equal(got, want)
    plain, _ = _reference(CONFIG, inputs)
    assert not np.array_equal(got, plain)
    # link[1] sends at 0, 2, 4, ... s: up at 0 and 2 s of each 7 s, 2 of 3.5 sent per 7 s
    assert chans[0].lost > chans[0].delivered
    names = _names(inst, "parameter")
    assert {"schedule.t[2]", "schedule.period", "link[1].up[2]", "leader.up[1]"} <= set(names)
    assert inst.types["link[2].up[1]"] == "Integer"
    inst.close()


def test_bursty_links_in_the_fmu_equal_the_link_channels_bit_for_bit(built):
    """Gilbert-Elliott links (link[1], leader) beside an independent one (link[2]): every
    output equals LinkChannels drawing through the registry, and the draws differ from the
    independent model's at the same mean loss."""
    inst = _instance(built, "bursty", key="bursty")
    inputs = np.random.default_rng(7).standard_normal((300, 12))
    got = _drive(inst, inputs, 0)
    want, chans = _reference(BURSTY_CONFIG, inputs)
    assert got.shape == want.shape and np.array_equal(got, want)
    assert all(ch.lost > 0 and ch.delivered > 0 for ch in chans)
    assert chans[0].channel in (0, 1) and chans[1].channel == 0       # GE state, none
    plain, _ = _reference(CONFIG, inputs)
    assert np.array_equal(got[:, 9:18], plain[:, 9:18])          # link[2] untouched
    assert not np.array_equal(got[:, :9], plain[:, :9])
    assert inst.types["link[1].loss_model"] == "Integer"
    state = inst.slave.getFMUState()                          # the channel state restored
    first = _drive(inst, inputs[:100], 300)
    inst.slave.setFMUState(state)
    assert np.array_equal(_drive(inst, inputs[:100], 300), first)
    inst.slave.freeFMUState(state)
    inst.close()


@pytest.mark.parametrize("name, value, fragment", [
    ("link[1].p_gb", 0.0, "link[1] of vehicle 3: p_gb = 0 is not a probability in (0, 1]"),
    ("leader.loss_bad", 0.01, "leader link of vehicle 3: loss_bad = 0.01 is below "
     "loss_good = 0.05"),
    ("link[2].loss_model", 1, "link[2] of vehicle 3: p_gb"),        # neutral: 0.5 each
])
def test_a_bad_bursty_parameter_fails_initialization_naming_it(built, name, value, fragment):
    if name == "link[2].loss_model":            # neutral parameters are valid: it runs
        inst = _instance(built, "ge_ok", key="bursty", **{name: value})
        inst.close()
        return
    with pytest.raises(CosimError) as exc:
        _instance(built, f"bad_{name}", key="bursty", **{name: value})
    assert "initialization failed" in str(exc.value) and fragment in str(exc.value)


@pytest.mark.parametrize("name, value, fragment", [
    ("schedule.t[2]", -1.0, "schedule.t = [0.0, -1.0] must start at 0 s and increase"),
    ("schedule.period", 2.0, "schedule.period = 2.0 s must be 0 or after the last switch"),
    ("schedule.t[2]", 3.05, "schedule.t[2] = 3.05 s is not a whole number of steps"),
    ("link[2].up[1]", 2, "link[2].up[1] = 2 is outside its range [0, 1]"),
])
def test_a_bad_schedule_parameter_fails_initialization_naming_it(built, name, value, fragment):
    with pytest.raises(CosimError) as exc:
        _instance(built, f"bad_{name}", key="sched", **{name: value})
    assert "initialization failed" in str(exc.value) and fragment in str(exc.value)


def test_the_fmu_validates_and_has_no_direct_feedthrough(built):
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu
    for path in built[0].values():
        assert validate_fmu(str(path)) == []
        md = read_model_description(str(path))
        assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate
        assert not md.coSimulation.canHandleVariableCommunicationStepSize
        assert all(v.description for v in md.modelVariables)
        assert md.outputs and all(not u.dependencies for u in md.outputs)
    md = read_model_description(str(built[0]["network"]))
    units = {v.name: v.unit for v in md.modelVariables}
    assert units["link[1].age"] == units["link[2].latency"] == units["h"] == "s"


def test_fmu_state_round_trip_is_bit_identical(built):
    inst = _instance(built, "state")
    inputs = np.random.default_rng(4).standard_normal((300, 12))
    first = assert_state_round_trip(inst, _drive, inputs, 120)
    assert np.std(first[:, 0]) > 0 and first[-1, 7] > 0               # rx moved, losses
    inst.close()


@pytest.mark.parametrize("name, value, fragment", [
    ("link[2].loss", 1.5, "link[2].loss"),
    ("link[1].M[2,3]", float("nan"), "link[1].M[2,3] = nan is not finite"),
    ("leader.rx0[2]", float("inf"), "leader.rx0[2] = inf is not finite"),
    ("link[1].period", 0.0, "link[1] of vehicle 3: period = 0 s must be positive"),
    ("leader.offset", 2.5, "leader link of vehicle 3: offset = 2.5 s is not within"),
])
def test_a_bad_parameter_fails_initialization_naming_it(built, name, value, fragment):
    with pytest.raises(CosimError) as exc:
        _instance(built, f"bad_{name}", **{name: value})
    msg = str(exc.value)
    assert "initialization failed" in msg and fragment in msg


def test_the_lost_fraction_matches_the_loss_probability(built):
    """4000 messages at loss 0.2: the fraction lost within 4 standard errors."""
    inst = _instance(built, "stats", key="stats")
    n, p = 4000, 0.2
    out = _drive(inst, np.zeros((n + 1, 1)), 0)[-1]        # outputs at step n
    names = _names(inst, "output")
    lost, delivered = out[names.index("link[1].lost")], out[names.index("link[1].delivered")]
    assert lost + delivered == n
    assert abs(lost / n - p) < 4 * math.sqrt(p * (1 - p) / n)
    inst.close()


# ---------------------------------------------------------------- the Inbox alone
def _inbox(seed=SEED):
    links = [LinkSettings(f"link[{j}]", check_link("x", 0.3, 0.5, 0.3), j, np.zeros(2),
                          None if j == 1 else np.array([[1.0, H], [0.0, 1.0]]))
             for j in (1, 2)]
    return Inbox(links, H, seed)


def test_inbox_state_round_trip_and_mismatches_are_named():
    ib = _inbox()
    for k in range(37):
        ib.advance(k, [np.array([k, 1.0]), np.array([-k, 2.0])])
    saved = ib.get_state()
    twin = _inbox(seed=99)
    twin.set_state(saved)
    assert twin.k == 37 and np.array_equal(twin.s, ib.s)
    for k in range(37, 90):
        for b in (ib, twin):
            b.advance(k, [np.array([k, 1.0]), np.array([-k, 2.0])])
    assert np.array_equal(twin.s, ib.s) and np.array_equal(twin.lost, ib.lost)
    assert np.array_equal(twin.age(90), ib.age(90)) and ib.lost.sum() > 0
    before = twin.get_state()
    one = Inbox([LinkSettings("a", check_link("x", 0, 1, 0), 1, np.zeros(2))], H, 0)
    with pytest.raises(ValueError, match="holds 2 links, this inbox has 1"):
        one.set_state(saved)
    with pytest.raises(ValueError, match="do not match the link lengths"):
        twin.set_state(saved[:-1])
    bad = saved.copy()
    bad[2], bad[3] = bad[2] + 1, bad[3] - 1            # lengths shifted between the links
    with pytest.raises(ValueError, match="inbox state: link\\[1\\]"):
        twin.set_state(bad)
    assert np.array_equal(twin.get_state(), before)     # unchanged after a refusal
    with pytest.raises(ValueError, match="2 messages for 1 links"):
        one.advance(0, [np.zeros(2)] * 2)
