"""plant_model.acoustic: an acoustic link's schedule, latency, loss and receiver."""
from __future__ import annotations

import math

import numpy as np
import pytest

from plant_model.acoustic.links import (
    LinkChannel,
    arrival_step,
    check_link,
    link_key,
    propagate,
    send_steps,
    tdma_offsets,
)
from plant_model.linalg_checks import ModelError


def _run(ch: LinkChannel, steps: int, size: int = 2):
    """Step a link whose sender sends k at step k; the receiver's value and age per step."""
    ages, rx = [], []
    for k in range(steps):
        ages.append(ch.age(k))
        rx.append(ch.rx[0])
        ch.advance(k, np.full(size, float(k)))
    return ages, rx


def _link(latency, period, loss, h, offset=0.0, key=1, size=2, M=None, seed=0):
    return LinkChannel(check_link("link 1 -> 2", latency, period, loss, offset), h, seed=seed,
                       key=key, rx0=np.full(size, -1.0), M=M)


def test_period_and_latency_set_what_arrives_when():
    """period 2 s, latency 1 s, h = 0.01 s, no loss: messages leave at 0, 2, 4 s and arrive
    at 1, 3, 5 s; before 1 s the receiver holds the launch value; the age saws 1 s .. 3 s."""
    ch = _link(1.0, 2.0, 0.0, 0.01)
    ages, rx = _run(ch, 650)
    assert rx[99] == -1.0 and ages[99] == pytest.approx(0.99)   # launch value, sent at t = 0
    assert rx[100] == 0.0 and ages[100] == pytest.approx(1.0)
    assert rx[299] == 0.0 and ages[299] == pytest.approx(2.99)
    assert rx[300] == 200.0 and ages[300] == pytest.approx(1.0)
    assert rx[500] == 400.0
    assert min(ages[100:]) == pytest.approx(1.0) and max(ages[100:]) == pytest.approx(2.99)
    assert (ch.sent, ch.lost, ch.delivered) == (4, 0, 3)     # sent at 0, 2, 4, 6 s


def test_a_long_latency_keeps_at_most_ceil_latency_over_period_plus_one_in_flight():
    timing = check_link("link 3 -> 4", 5.0, 2.0, 0.0)
    assert timing.max_in_flight == 4
    ch = LinkChannel(timing, 0.05, seed=0, key=2, rx0=np.zeros(1))
    most = 0
    for k in range(2000):
        ch.advance(k, np.array([float(k)]))
        most = max(most, len(ch.in_flight))
    assert most <= timing.max_in_flight and most == 3      # 5 s / 2 s: three on the way
    assert ch.age(2000) >= 5.0


def test_zero_latency_is_heard_at_the_next_step():
    """No receiver feeds through: latency 0 means the message of t_k is used at t_(k+1)."""
    ch = _link(0.0, 0.5, 0.0, 0.1, size=1)
    ages, rx = _run(ch, 12, size=1)
    assert rx[0] == -1.0 and rx[1] == 0.0 and rx[5] == 0.0 and rx[6] == 5.0
    assert ages[1] == pytest.approx(0.1) and ages[5] == pytest.approx(0.5)
    assert arrival_step(7, 0.1, 0.0) == 8 and arrival_step(7, 0.1, 0.25) == 10


def test_losses_are_independent_draws_of_the_links_own_stream():
    p, n = 0.2, 4000
    timing = check_link("link 1 -> 2", 0.0, 0.01, p)

    def lost(seed: int, key: int) -> np.ndarray:
        ch = LinkChannel(timing, 0.01, seed=seed, key=key, rx0=np.zeros(1))
        out = []
        for k in range(n):
            before = ch.lost
            ch.advance(k, np.zeros(1))
            out.append(ch.lost > before)
        return np.array(out)

    a = lost(7, 1)
    assert abs(a.mean() - p) < 4 * math.sqrt(p * (1 - p) / n)
    # independent from message to message: the lag-1 correlation is small
    assert abs(np.corrcoef(a[:-1], a[1:])[0, 1]) < 4 / math.sqrt(n)
    assert np.array_equal(a, lost(7, 1))                     # the seed fixes every draw
    assert not np.array_equal(a, lost(7, 2))                 # another link, another stream
    assert not np.array_equal(a, lost(8, 1))
    assert link_key("leader", 3) == 3 and link_key(2, 3) == 20_003


def test_tdma_gives_each_sender_its_slot():
    offsets = tdma_offsets([1, 2, 3, 4], 2.0)
    assert offsets == {1: 0.0, 2: 0.5, 3: 1.0, 4: 1.5}
    ch = _link(0.0, 2.0, 0.0, 0.01, offset=offsets[3], size=1)
    _, rx = _run(ch, 400, size=1)
    assert rx[100] == -1.0 and rx[101] == 100.0 and rx[301] == 300.0
    assert send_steps(ch.timing, 0.01, 401) == [100, 300]


def test_the_propagating_receiver_carries_the_message_forward():
    Phi = np.array([[1.0, 0.1], [0.0, 1.0]])                 # position and velocity, h = 0.1
    ch = LinkChannel(check_link("link 1 -> 2", 0.3, 1.0, 0.0), 0.1, seed=0, key=1,
                     rx0=np.array([0.0, 2.0]), M=Phi)
    truth = np.array([0.0, 2.0])
    for k in range(25):
        # the sender's model is exact here: the propagated message is the truth, always
        assert np.allclose(ch.rx, truth, atol=1e-12)
        if k >= 3:
            assert np.allclose(ch.rx, propagate(truth_at(ch.rx_sent, Phi), k - ch.rx_sent, Phi))
        ch.advance(k, truth)
        truth = Phi @ truth
    assert ch.rx_sent == 20 and ch.age(25) == pytest.approx(0.5)  # sent at 2.0 s, heard at 2.3 s


def truth_at(k: int, Phi: np.ndarray) -> np.ndarray:
    return np.linalg.matrix_power(Phi, k) @ np.array([0.0, 2.0])


def test_state_round_trip_replays_the_same_future():
    ch = _link(1.0, 0.5, 0.3, 0.1, size=2, M=np.array([[1.0, 0.1], [0.0, 1.0]]))
    for k in range(17):
        ch.advance(k, np.array([k, -k], float))
    saved = ch.get_state()
    twin = _link(1.0, 0.5, 0.3, 0.1, size=2, M=np.array([[1.0, 0.1], [0.0, 1.0]]), seed=5)
    twin.set_state(saved)
    for k in range(17, 80):
        ch.advance(k, np.array([k, -k], float))
        twin.advance(k, np.array([k, -k], float))
        assert np.array_equal(ch.rx, twin.rx) and ch.rx_sent == twin.rx_sent
    assert (ch.sent, ch.lost, ch.delivered) == (twin.sent, twin.lost, twin.delivered)
    assert ch.lost > 0


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
    from plant_model.acoustic.settings import resolve_links
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
    # the leader first, then the vehicles that send (1, 2, 3; 4 sends to nobody): four
    # slots of 0.5 s in the 2 s cycle
    assert tdma[("leader", 1)].offset == 0.0 and tdma[(1, 2)].offset == pytest.approx(0.5)
    assert tdma[(3, 4)].offset == pytest.approx(1.5) and tdma[(2, 4)].offset == pytest.approx(1.0)
    with pytest.raises(ModelError, match=r"tdma = true: 4 senders need a period of at least "
                                         r"4 steps \(0.04 s\), not 0.03 s"):
        resolve_links(4, EDGES, PINS, dict(net, tdma=True, period=0.03), 0.01)


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
    from plant_model.acoustic.settings import resolve_links
    with pytest.raises(ModelError) as exc:
        resolve_links(4, EDGES, PINS, net, 0.01)
    assert fragment in str(exc.value) and "\n" not in str(exc.value)


LINKS = [(1, 2), (1, 3), (2, 3), ("leader", 1)]


def test_a_switching_schedule_in_order():
    from plant_model.acoustic.schedule import check_schedule
    sched = check_schedule([{"t": 0.0, "edges": [[1, 2], ["leader", 1]]},
                            {"t": 60.0, "down": [[2, 3]]}], 3)
    assert sched == [(0.0, "edges", [(1, 2), ("leader", 1)]), (60.0, "down", [(2, 3)])]


def test_a_schedule_says_which_links_are_up_at_each_step():
    """edges: only those up; down: all but those; with a period it repeats, without it the
    last graph holds; the switch is at the step of the switch time."""
    from plant_model.acoustic.schedule import resolve_schedule
    table = {"schedule": [{"t": 0.0, "edges": [[1, 2], ["leader", 1]]},
                          {"t": 0.5, "down": [[1, 3]]}]}
    once = resolve_schedule(table, LINKS, 0.1, 3)
    assert [once.is_up((1, 2), k) for k in (0, 4, 5, 1000)] == [True, True, True, True]
    assert [once.is_up((1, 3), k) for k in (0, 4, 5, 1000)] == [False, False, False, False]
    assert [once.is_up((2, 3), k) for k in (0, 4, 5, 1000)] == [False, False, True, True]
    assert once.settled == 5
    rep = resolve_schedule(dict(table, schedule_period=1.0), LINKS, 0.1, 3)
    assert [rep.is_up((2, 3), k) for k in (4, 5, 9, 10, 14, 15)] == [
        False, True, True, False, False, True]
    assert rep.settled == 0 and rep.period == 10
    assert resolve_schedule({"loss": 0.1}, LINKS, 0.1, 3) is None


def test_joint_connectivity_is_the_union_over_a_period():
    """Each graph alone leaves a vehicle unreached; their union over the period reaches all;
    without a period only the last graph counts."""
    from plant_model.acoustic.schedule import connectivity, resolve_schedule
    sched = [{"t": 0.0, "edges": [["leader", 1], [1, 2]]},
             {"t": 1.0, "edges": [["leader", 1], [2, 3]]}]
    rep = resolve_schedule({"schedule": sched, "schedule_period": 2.0}, LINKS, 0.1, 3)
    assert connectivity(rep, LINKS) == {"connected_graphs": [False, False],
                                        "jointly_connected": True}
    once = resolve_schedule({"schedule": sched}, LINKS, 0.1, 3)
    assert connectivity(once, LINKS)["jointly_connected"] is False


@pytest.mark.parametrize("entries, fragment", [
    ([{"t": 5.0, "edges": []}], "entry 1: the first graph must start at t = 0"),
    ([{"t": 0.0, "edges": []}, {"t": 0.0, "edges": []}],
     "entry 2: t = 0 s does not come after the previous switch at 0 s"),
    ([{"t": 0.0, "edges": []}, {"t": 30.0, "edges": []}, {"t": 20.0, "edges": []}],
     "entry 3: t = 20 s does not come after"),
    ([{"t": 0.0, "edges": [[1, 9]]}], "entry 1, link [1, 9]: vehicle 9 does not "
                                      "exist (vehicles are 1..3)"),
    ([{"t": 0.0, "edges": [[2, 2]]}], "a self-loop"),
    ([{"t": 0.0, "edges": [[1, 2, 0.5]]}], "is not a link [j, i]"),
    ([{"t": 0.0, "edges": [], "down": []}], "entry 1: give either edges"),
    ([{"t": 0.0}], "entry 1: give either edges"),
    ([{"t": 0.0, "up": []}], "entry 1: unknown key(s) up"),
])
def test_a_bad_schedule_is_one_line_naming_the_entry(entries, fragment):
    from plant_model.acoustic.schedule import check_schedule
    with pytest.raises(ModelError) as exc:
        check_schedule(entries, 3)
    assert fragment in str(exc.value) and "\n" not in str(exc.value)


@pytest.mark.parametrize("table, fragment", [
    ({"schedule": [{"t": 0.0, "edges": [[3, 1]]}]},
     "entry 1: link 3 -> 1 is not a link of this architecture (vehicle 1 hears leader)"),
    ({"schedule": [{"t": 0.0, "edges": []}, {"t": 0.25, "edges": []}]},
     "schedule entry 2: t = 0.25 s is not a whole number of steps"),
    ({"schedule": [{"t": 0.0, "edges": []}, {"t": 2.0, "edges": []}], "schedule_period": 2.0},
     "schedule_period = 2 s must come after the last switch at 2 s"),
    ({"schedule_period": 5.0}, "schedule_period needs a schedule"),
])
def test_a_schedule_that_does_not_fit_the_links_is_one_line(table, fragment):
    from plant_model.acoustic.schedule import resolve_schedule
    with pytest.raises(ModelError) as exc:
        resolve_schedule(table, LINKS, 0.1, 3)
    assert fragment in str(exc.value) and "\n" not in str(exc.value)
