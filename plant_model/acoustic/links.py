"""Acoustic links between vehicles: message schedule, latency, loss, and the receiver.

Underwater, vehicles talk through acoustic modems: a message every few seconds, a latency
of a second or more, losses of tens of percent. One directed link (sender -> receiver) at
the co-simulation's fixed step h, all times in seconds:

- the sender transmits at t = offset + m period (m = 0, 1, ...), i.e. at the steps
  k = round((offset + m period) / h); with a TDMA schedule the senders take turns, sender
  number s of S transmitting at offset = s period / S (:func:`tdma_offsets`);
- each message is lost as the link's model draws it (:mod:`.link_models`: independently
  with probability ``loss``, one uniform draw per message, or a Gilbert-Elliott channel)
  from the link's own generator, seeded [seed, 1_000_000 + key] (apart from every
  vehicle's noise stream, [seed, i]);
- a message that is not lost arrives ``latency`` later, at the first step at or after
  t_send + latency and at the earliest the next step (:func:`arrival_step`: the co-simulation
  couples at h, so information sent at t_k is used from t_(k+1) on and no receiver feeds
  through); at most ceil(latency / period) + 1 are in flight at once;
- the receiver keeps the newest message that has arrived, ``rx``, with its send time. It
  either holds that value (M = I), or propagates it with the sender's model, rx <- M rx at
  every step, so that rx(t_k) = M^(k - k_send) rx(t_send) (:func:`propagate`; a message
  [x; u] with M = [[Phi, Gam], [0, I]] carries the sender's estimate and its control). Both
  are fixed-gain receivers. Before the first arrival it holds the value exchanged before
  launch (sent at t = 0).

The age of information is t - t_send of the message the receiver holds.
:func:`~.settings.resolve_links` gives every link of a fleet its timing from a ``[network]``
table (fleet-wide defaults, per-link overrides, TDMA); :mod:`.schedule` switches links on and
off (a schedule of graphs). This module is the mathematics only: the FMU and the predictions
build on it.
"""
from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..linalg_checks import ModelError
from .base import _number, whole_steps
from .link_models import Independent, LinkModel

__all__ = ["LINK_KEY_BASE", "MAX_IN_FLIGHT", "LinkTiming", "LinkChannel", "arrival_step",
           "check_link", "in_range", "link_key", "link_sender", "propagate", "send_steps",
           "tdma_offsets"]

#: added to the seed key of a link's generator (vehicles use 1..N, the leader 0)
LINK_KEY_BASE = 1_000_000
#: the most messages one link may have in flight, latency / period: every one is a state of
#: the networked loop (orchestrator.analysis.acoustic.loop) and a slot of the receiver
MAX_IN_FLIGHT = 1000


@dataclass(frozen=True)
class LinkTiming:
    """When a link transmits, how long a message travels, how often it is lost."""

    latency: float      #: s, >= 0
    period: float       #: s, > 0: one message per period
    loss: float         #: probability in [0, 1): the mean loss of its model
    offset: float = 0.0  #: s, in [0, period): the first transmission (TDMA slot)
    #: how messages are lost (:mod:`.link_models`); None: independently with ``loss``
    bursts: LinkModel | None = None

    @property
    def model(self) -> LinkModel:
        """The link's loss model (a row of :data:`.link_models.LINK_MODELS`)."""
        return self.bursts if self.bursts is not None else Independent(self.loss)

    @property
    def max_in_flight(self) -> int:
        """ceil(latency / period) + 1: the most messages that can travel at once."""
        return math.ceil(self.latency / self.period) + 1


def check_link(name: str, latency: Any, period: Any, loss: Any,
               offset: Any = 0.0, h: float | None = None) -> LinkTiming:
    """A validated :class:`LinkTiming`; every error is one line naming the link.

    Parameters
    ----------
    name : str
        The link, e.g. "link 2 -> 4" or "leader -> 1".
    latency, period, loss, offset : Any
        Seconds (>= 0), seconds (> 0), a probability in [0, 1) or a validated loss model
        (:mod:`.link_models`), seconds in [0, period); at most :data:`MAX_IN_FLIGHT`
        periods of latency.
    h : float, optional
        The step (s): the period is then a whole number of steps, at least one.

    Returns
    -------
    LinkTiming
        The timing.

    Raises
    ------
    ModelError
        Naming the link and the value.
    """
    lat = _number(f"{name}: latency", latency)
    per = _number(f"{name}: period", period)
    model = loss if isinstance(loss, LinkModel) else Independent.parse(name, {"loss": loss})
    p = model.mean_loss
    off = _number(f"{name}: offset", offset)
    if lat < 0.0:
        raise ModelError(f"{name}: latency = {lat:g} s is negative")
    if per <= 0.0:
        raise ModelError(f"{name}: period = {per:g} s must be positive")
    if not p < 1.0:
        raise ModelError(f"{name}: the mean loss of {model} is 1 (a link that loses every "
                         "message carries nothing)")
    if not 0.0 <= off < per:
        raise ModelError(f"{name}: offset = {off:g} s is not within [0, period = {per:g} s)")
    if h is not None:
        whole_steps(f"{name}: period", per, h)
    if lat / per > MAX_IN_FLIGHT:
        raise ModelError(f"{name}: latency = {lat:g} s is {lat / per:.3g} periods of {per:g} s: "
                         f"at most {MAX_IN_FLIGHT} messages may be in flight on a link "
                         f"(latency at most {MAX_IN_FLIGHT * per:g} s at this period)")
    return LinkTiming(latency=lat, period=per, loss=p, offset=off,
                      bursts=None if isinstance(model, Independent) else model)


def tdma_offsets(senders: Sequence[Any], period: float) -> dict[Any, float]:
    """TDMA: S senders take turns in each period, sender number s at s period / S.

    Parameters
    ----------
    senders : Sequence[int]
        The senders in slot order (vehicle numbers).
    period : float
        The cycle, s.

    Returns
    -------
    dict[int, float]
        Sender -> its transmission offset, s.
    """
    S = len(senders)
    return {v: s * float(period) / S for s, v in enumerate(senders)}


def propagate(value: np.ndarray, steps: int, Phi: np.ndarray) -> np.ndarray:
    """Phi^steps value: a received state carried forward with the sender's model.

    Parameters
    ----------
    value : np.ndarray
        The state at its send time.
    steps : int
        Steps since then (>= 0).
    Phi : np.ndarray
        The sender's one-step map.

    Returns
    -------
    np.ndarray
        The state now.
    """
    return np.linalg.matrix_power(np.asarray(Phi, dtype=float), int(steps)) @ value


def link_sender(key: int) -> int | str:
    """The sender of a link from its key (:func:`link_key`): a vehicle, or "leader"."""
    j = int(key) // 10_000
    return "leader" if j == 0 else j


def link_key(sender: int | str, receiver: int) -> int:
    """The key of a link's loss stream [seed, LINK_KEY_BASE + key]: 10000 j + i (leader j = 0).

    Parameters
    ----------
    sender : int or str
        Vehicle number, or "leader".
    receiver : int
        Vehicle number (1..9999).

    Returns
    -------
    int
        The key.
    """
    j = 0 if sender == "leader" else int(sender)
    return 10_000 * j + int(receiver)


def arrival_step(k_send: int, h: float, latency: float) -> int:
    """The step at which a message sent at step k_send is heard: ceil((t_send + latency)/h),
    and at the earliest the next step (information sent at t_k is used from t_(k+1): the
    co-simulation couples at h, and a receiver's output never feeds through)."""
    return max(k_send + 1, math.ceil((k_send * h + latency) / h - 1e-9))


def send_steps(timing: LinkTiming, h: float, k_end: int) -> list[int]:
    """The steps k < k_end at which a link transmits: round((offset + m period) / h)."""
    out, m = [], 0
    while True:
        k = round((timing.offset + m * timing.period) / h)
        if k >= k_end:
            return out
        if not out or k > out[-1]:
            out.append(k)
        m += 1


class LinkChannel:
    """One directed link stepped with the co-simulation (module docstring).

    State: the message the receiver holds, ``rx`` (its value now: held, or propagated by M
    every step) with its send step, and the messages in flight (value, send step, arrival
    step, lost). A message lost on the way is counted as lost at its arrival step (when the
    receiver would have heard it). Before the first arrival the receiver holds ``rx0``, the
    value exchanged before launch, sent at t = 0.
    """

    def __init__(self, timing: LinkTiming, h: float, seed: int, key: int,
                 rx0: np.ndarray, M: np.ndarray | None = None):
        self.timing, self.h = timing, float(h)
        self.rx = np.array(rx0, dtype=float).reshape(-1)
        self.size = self.rx.size
        self.M = None if M is None else np.asarray(M, dtype=float)
        if self.M is not None and self.M.shape != (self.size, self.size):
            raise ModelError(f"propagation matrix of shape {self.M.shape} for a message of "
                             f"{self.size} values")
        self.rng = np.random.default_rng([int(seed), LINK_KEY_BASE + int(key)])
        self.model = timing.model
        self.channel = self.model.start()            #: the loss model's channel state
        self._first = round(timing.offset / self.h)
        self._every = timing.period / self.h
        self._m = 0                                  # next message number
        #: (arrival step, send step, lost, value in the representation of the current step)
        self.in_flight: deque[tuple[int, int, bool, np.ndarray]] = deque()
        self.rx_sent = 0
        self.sent = self.lost = self.delivered = 0

    def _next_send(self) -> int:
        return self._first + round(self._m * self._every)

    def advance(self, k: int, value: np.ndarray, in_range: bool = True) -> None:
        """The transition from step k to k + 1.

        1. if k is a send step: ``value`` (the sender's message at t_k) leaves, lost with
           as the link's model draws it (:meth:`.link_models.Independent.draw`: one uniform
           of the link's stream per message; a Gilbert-Elliott channel: two), and
           lost whatever the draw when the receiver is out of the modem's range
           (``in_range`` False; the draw is made all the same, so a range never shifts the
           other messages' draws);
        2. a message due at k + 1 (:func:`arrival_step`) replaces ``rx`` unless lost;
        3. with M: ``rx`` and the messages in flight are propagated one step (M x).

        Parameters
        ----------
        k : int
            The step (t = k h), visited in increasing order.
        value : np.ndarray
            What the sender sends at t_k, shape (size,).
        in_range : bool, optional
            Whether sender and receiver are within the modem's range at t_k.
        """
        while self._next_send() < k:                 # steps skipped: their messages never left
            self._m += 1
        if self._next_send() == k:
            self._m += 1
            self.sent += 1
            drawn, self.channel = self.model.draw(self.rng, 1, self.channel)
            lost = bool(drawn[0]) or not in_range
            self.in_flight.append((arrival_step(k, self.h, self.timing.latency), k, lost,
                                   np.array(value, dtype=float).reshape(self.size)))
        while self.in_flight and self.in_flight[0][0] <= k + 1:
            _, k_sent, lost, v = self.in_flight.popleft()
            if lost:
                self.lost += 1
            else:
                self.rx, self.rx_sent = v.copy(), k_sent
                self.delivered += 1
        if self.M is not None:                       # in place: no new queue per step
            self.rx = self.M @ self.rx
            for _, _, _, v in self.in_flight:
                v[:] = self.M @ v

    def age(self, k: int) -> float:
        """t_k - t_send of the message the receiver holds at step k, s."""
        return (k - self.rx_sent) * self.h

    def get_state(self) -> np.ndarray:
        """Everything that evolves, as one flat array (FMU state)."""
        head = [self._m, self.rx_sent, self.sent, self.lost, self.delivered,
                len(self.in_flight), self.channel]
        body = [np.r_[a, s, float(lo), v] for a, s, lo, v in self.in_flight]
        return np.concatenate([np.asarray(head, float), self.rx, *body, _rng_state(self.rng)])

    def set_state(self, state: np.ndarray) -> None:
        """Restore :meth:`get_state`."""
        s = np.asarray(state, dtype=float)
        self._m, self.rx_sent, self.sent, self.lost, self.delivered, n, self.channel = (
            int(x) for x in s[:7])
        pos = 7
        self.rx = s[pos:pos + self.size].copy()
        pos += self.size
        self.in_flight = deque()
        for _ in range(n):
            a, k_s, lo = s[pos:pos + 3]
            self.in_flight.append((int(a), int(k_s), bool(lo), s[pos + 3:pos + 3 + self.size]
                                   .copy()))
            pos += 3 + self.size
        _set_rng_state(self.rng, s[pos:])


def _rng_state(rng: np.random.Generator) -> np.ndarray:
    """The PCG64 state as floats (4 x 32-bit halves of state and inc, has_uint32, uinteger)."""
    st = rng.bit_generator.state
    words = []
    for key in ("state", "inc"):
        v = int(st["state"][key])
        words += [(v >> (32 * i)) & 0xFFFFFFFF for i in range(4)]
    return np.asarray(words + [st["has_uint32"], st["uinteger"]], dtype=float)


def _set_rng_state(rng: np.random.Generator, words: np.ndarray) -> None:
    w = [int(x) for x in words]
    st = rng.bit_generator.state
    st["state"] = {"state": sum(w[i] << (32 * i) for i in range(4)),
                   "inc": sum(w[4 + i] << (32 * i) for i in range(4))}
    st["has_uint32"], st["uinteger"] = w[8], w[9]
    rng.bit_generator.state = st


def in_range(a: np.ndarray, b: np.ndarray, limit: float | None) -> bool:
    """Are two NED positions (m) within the modem range ``limit`` (None: no limit)?"""
    return limit is None or float(np.linalg.norm(np.asarray(a) - np.asarray(b))) <= limit
