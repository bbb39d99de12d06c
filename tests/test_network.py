"""plant_model.network: an acoustic link's schedule, latency, loss and receiver."""
from __future__ import annotations

import math

import numpy as np
import pytest

from plant_model.linalg_checks import ModelError
from plant_model.network import LinkChannel, check_link, propagate, tdma_offsets


def _run(ch: LinkChannel, steps: int, size: int = 2):
    ages, held = [], []
    for k in range(steps):
        ch.step(k, np.full(size, float(k)))
        ages.append(ch.age(k))
        held.append(None if ch.held is None else ch.held[0])
    return ages, held


def test_period_and_latency_set_what_arrives_when():
    """period 2 s, latency 1 s, h = 0.01 s, no loss: messages leave at 0, 2, 4 s and arrive
    at 1, 3, 5 s; the age of information saws between 1 s and 3 s."""
    ch = LinkChannel(check_link("link 1 -> 2", 1.0, 2.0, 0.0), 0.01, seed=0, key=1, size=2)
    ages, held = _run(ch, 650)
    assert math.isinf(ages[99]) and held[99] is None          # nothing arrived before 1 s
    assert held[100] == 0.0 and ages[100] == pytest.approx(1.0)
    assert held[299] == 0.0 and ages[299] == pytest.approx(2.99)
    assert held[300] == 200.0 and ages[300] == pytest.approx(1.0)
    assert held[500] == 400.0
    finite = [a for a in ages if math.isfinite(a)]
    assert min(finite) == pytest.approx(1.0) and max(finite) == pytest.approx(2.99)
    assert (ch.sent, ch.lost, ch.delivered) == (4, 0, 3)     # sent at 0, 2, 4, 6 s


def test_a_long_latency_keeps_at_most_ceil_latency_over_period_plus_one_in_flight():
    timing = check_link("link 3 -> 4", 5.0, 2.0, 0.0)
    assert timing.max_in_flight == 4
    ch = LinkChannel(timing, 0.05, seed=0, key=2, size=1)
    most = 0
    for k in range(2000):
        ch.step(k, np.array([float(k)]))
        most = max(most, len(ch.in_flight))
    assert most <= timing.max_in_flight and most == 3      # 5 s / 2 s: three on the way
    assert ch.age(1999) >= 5.0


def test_zero_latency_delivers_in_the_same_step():
    ch = LinkChannel(check_link("leader -> 1", 0.0, 0.5, 0.0), 0.1, seed=0, key=0, size=1)
    ages, held = _run(ch, 12, size=1)
    assert held[0] == 0.0 and ages[0] == 0.0 and held[5] == 5.0 and ages[4] == pytest.approx(0.4)


def test_losses_are_independent_draws_of_the_links_own_stream():
    p, n = 0.2, 4000
    timing = check_link("link 1 -> 2", 0.0, 0.01, p)

    def lost(seed: int, key: int) -> np.ndarray:
        ch = LinkChannel(timing, 0.01, seed=seed, key=key, size=1)
        out = []
        for k in range(n):
            before = ch.lost
            ch.step(k, np.zeros(1))
            out.append(ch.lost > before)
        return np.array(out)

    a = lost(7, 1)
    assert abs(a.mean() - p) < 4 * math.sqrt(p * (1 - p) / n)
    # independent from message to message: the lag-1 correlation is small
    assert abs(np.corrcoef(a[:-1], a[1:])[0, 1]) < 4 / math.sqrt(n)
    assert np.array_equal(a, lost(7, 1))                     # the seed fixes every draw
    assert not np.array_equal(a, lost(7, 2))                 # another link, another stream
    assert not np.array_equal(a, lost(8, 1))


def test_tdma_gives_each_sender_its_slot():
    offsets = tdma_offsets([1, 2, 3, 4], 2.0)
    assert offsets == {1: 0.0, 2: 0.5, 3: 1.0, 4: 1.5}
    ch = LinkChannel(check_link("link 3 -> 4", 0.0, 2.0, 0.0, offsets[3]), 0.01, 0, 3, 1)
    _, held = _run(ch, 400, size=1)
    assert held[99] is None and held[100] == 100.0 and held[300] == 300.0


def test_the_propagating_receiver_carries_the_message_forward():
    Phi = np.array([[1.0, 0.1], [0.0, 1.0]])                 # position and velocity, h = 0.1
    ch = LinkChannel(check_link("link 1 -> 2", 0.3, 1.0, 0.0), 0.1, seed=0, key=1, size=2)
    truth = np.array([0.0, 2.0])
    for k in range(8):
        ch.step(k, truth)
        if k >= 3:
            # held: the state at its send time (the message of t = 0, the next leaves at 1 s)
            assert np.allclose(ch.received(k), [0.0, 2.0])
            assert np.allclose(ch.received(k, Phi), propagate(ch.held, k - ch.held_sent, Phi))
        truth = Phi @ truth
    assert np.allclose(ch.received(7, Phi), np.linalg.matrix_power(Phi, 7) @ [0.0, 2.0])


@pytest.mark.parametrize("args, fragment", [
    ((-1.0, 2.0, 0.2), "latency = -1 s is negative"),
    ((1.0, 0.0, 0.2), "period = 0 s must be positive"),
    ((1.0, 2.0, 1.0), "loss = 1 is not a probability in [0, 1)"),
    ((1.0, 2.0, -0.1), "loss = -0.1 is not a probability"),
    ((1.0, 2.0, 0.2, 2.0), "offset = 2 s is not within [0, period = 2 s)"),
    ((float("nan"), 2.0, 0.2), "latency = nan is not finite"),
    ((True, 2.0, 0.2), "latency = True is not a number"),
])
def test_bad_link_settings_are_one_line_naming_the_link(args, fragment):
    with pytest.raises(ModelError) as exc:
        check_link("link 2 -> 4", *args)
    msg = str(exc.value)
    assert msg.startswith("link 2 -> 4: ") and fragment in msg and "\n" not in msg


# ------------------------------------------------------------------ a fleet's links
EDGES = [(1, 2, 1.0), (1, 3, 1.0), (2, 4, 0.5), (3, 4, 0.5)]      # formation-4
PINS = [(1, 1.0)]


def test_defaults_overrides_and_tdma_give_every_link_its_timing():
    from plant_model.network import resolve_links
    perfect = resolve_links(4, EDGES, PINS, None, 0.01)
    assert set(perfect) == {(1, 2), (1, 3), (2, 4), (3, 4), ("leader", 1)}
    assert all((t.latency, t.period, t.loss) == (0.0, 0.01, 0.0) for t in perfect.values())
    net = {"latency": 1.0, "period": 2.0, "loss": 0.2,
           "links": [{"from": 3, "to": 4, "loss": 0.5}, {"from": "leader", "to": 1,
                                                          "latency": 0.2}]}
    links = resolve_links(4, EDGES, PINS, net, 0.01)
    assert (links[(1, 2)].latency, links[(1, 2)].period, links[(1, 2)].loss) == (1.0, 2.0, 0.2)
    assert links[(3, 4)].loss == 0.5 and links[(3, 4)].latency == 1.0
    assert links[("leader", 1)].latency == 0.2 and links[("leader", 1)].loss == 0.2
    assert all(t.offset == 0.0 for t in links.values())
    tdma = resolve_links(4, EDGES, PINS, dict(net, tdma=True), 0.01)
    # the leader first, then vehicles 1..4: five slots of 0.4 s in the 2 s cycle
    assert tdma[("leader", 1)].offset == 0.0 and tdma[(1, 2)].offset == pytest.approx(0.4)
    assert tdma[(3, 4)].offset == pytest.approx(1.2) and tdma[(2, 4)].offset == pytest.approx(0.8)


@pytest.mark.parametrize("net, fragment", [
    ({"latency": -1.0}, "[network]: latency = -1 s is negative"),
    ({"loss": 1.2}, "[network]: loss = 1.2 is not a probability"),
    ({"period": 0.0}, "[network]: period = 0 s must be positive"),
    ({"links": [{"from": 2, "to": 3}]}, "network link 2 -> 3: no such communication edge "
                                        "(vehicle 3 hears 1)"),
    ({"links": [{"from": 7, "to": 2}]}, "[network] links entry 1: vehicle 7 does not exist"),
    ({"links": [{"from": 1, "to": 2, "loss": -0.5}]}, "network link 1 -> 2: loss = -0.5"),
    ({"links": [{"from": 1, "to": 2, "delay": 1}]}, "links entry 1: unknown key(s) delay"),
    ({"tdma": True, "period": 2.0, "links": [{"from": 1, "to": 2, "period": 1.0}]},
     "tdma = true needs one period for every link"),
    ({"latency": 1.0, "speed": 3}, "[network]: unknown key(s) speed"),
])
def test_a_bad_network_table_is_one_line_naming_the_link_or_entry(net, fragment):
    from plant_model.network import resolve_links
    with pytest.raises(ModelError) as exc:
        resolve_links(4, EDGES, PINS, net, 0.01)
    assert fragment in str(exc.value) and "\n" not in str(exc.value)


def test_a_switching_schedule_in_order():
    from plant_model.network import check_schedule
    sched = check_schedule([{"t": 0.0, "edges": [[1, 2, 1.0]]},
                            {"t": 60.0, "edges": [[1, 2, 1.0], [2, 3, 0.5]]}], 3)
    assert sched == [(0.0, [(1, 2, 1.0)]), (60.0, [(1, 2, 1.0), (2, 3, 0.5)])]


@pytest.mark.parametrize("entries, fragment", [
    ([{"t": 5.0, "edges": []}], "entry 1: the first graph must start at t = 0"),
    ([{"t": 0.0, "edges": []}, {"t": 0.0, "edges": []}],
     "entry 2: t = 0 s does not come after the previous switch at 0 s"),
    ([{"t": 0.0, "edges": []}, {"t": 30.0, "edges": []}, {"t": 20.0, "edges": []}],
     "entry 3: t = 20 s does not come after"),
    ([{"t": 0.0, "edges": [[1, 9, 1.0]]}], "entry 1, edge [1, 9, 1.0]: vehicle 9 does not "
                                           "exist (vehicles are 1..3)"),
    ([{"t": 0.0, "edges": [[2, 2, 1.0]]}], "a self-loop"),
    ([{"t": 0.0, "edges": [[1, 2, -1.0]]}], "negative weight -1"),
])
def test_a_bad_schedule_is_one_line_naming_the_entry(entries, fragment):
    from plant_model.network import check_schedule
    with pytest.raises(ModelError) as exc:
        check_schedule(entries, 3)
    assert fragment in str(exc.value) and "\n" not in str(exc.value)
