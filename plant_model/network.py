"""Acoustic links between vehicles: message schedule, latency, loss, and the receiver.

Underwater, vehicles talk through acoustic modems: a message every few seconds, a latency
of a second or more, losses of tens of percent. One directed link (sender -> receiver) at
the co-simulation's fixed step h, all times in seconds:

- the sender transmits at t = offset + m period (m = 0, 1, ...), i.e. at the steps
  k = round((offset + m period) / h); with a TDMA schedule the senders take turns, sender
  number s of S transmitting at offset = s period / S (:func:`tdma_offsets`);
- each message is lost independently with probability ``loss``, one uniform draw per
  message from the link's own generator, seeded [seed, 1_000_000 + key] (apart from every
  vehicle's noise stream, [seed, i]);
- a message that is not lost arrives ``latency`` later, at the first step at or after
  t_send + latency (ceil((t_send + latency) / h)); at most ceil(latency / period) + 1 are
  in flight at once;
- the receiver keeps the newest message that has arrived (its value and send time). It
  either holds that value, or propagates it to the current time with the sender's model,
  x(t) = Phi^(k - k_send) x(t_send) (:func:`propagate`). Both are fixed-gain receivers.

The age of information is t - t_send of the newest arrived message (infinite before the
first). This module is the mathematics only: the FMU and the predictions build on it.
"""
from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .linalg_checks import ModelError

__all__ = ["LinkTiming", "LinkChannel", "check_link", "propagate", "tdma_offsets"]

#: added to the seed key of a link's generator (vehicles use 1..N, the leader 0)
LINK_KEY_BASE = 1_000_000


@dataclass(frozen=True)
class LinkTiming:
    """When a link transmits, how long a message travels, how often it is lost."""

    latency: float      #: s, >= 0
    period: float       #: s, > 0: one message per period
    loss: float         #: probability in [0, 1)
    offset: float = 0.0  #: s, in [0, period): the first transmission (TDMA slot)

    @property
    def max_in_flight(self) -> int:
        """ceil(latency / period) + 1: the most messages that can travel at once."""
        return math.ceil(self.latency / self.period) + 1


def _number(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ModelError(f"{name} = {value!r} is not a number")
    v = float(value)
    if not math.isfinite(v):
        raise ModelError(f"{name} = {v} is not finite")
    return v


def check_link(name: str, latency: Any, period: Any, loss: Any,
               offset: Any = 0.0) -> LinkTiming:
    """A validated :class:`LinkTiming`; every error is one line naming the link.

    Parameters
    ----------
    name : str
        The link, e.g. "link 2 -> 4" or "leader -> 1".
    latency, period, loss, offset : Any
        Seconds (>= 0), seconds (> 0), a probability in [0, 1), seconds in [0, period).

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
    p = _number(f"{name}: loss", loss)
    off = _number(f"{name}: offset", offset)
    if lat < 0.0:
        raise ModelError(f"{name}: latency = {lat:g} s is negative")
    if per <= 0.0:
        raise ModelError(f"{name}: period = {per:g} s must be positive")
    if not 0.0 <= p < 1.0:
        raise ModelError(f"{name}: loss = {p:g} is not a probability in [0, 1) (a link "
                         "that loses every message carries nothing)")
    if not 0.0 <= off < per:
        raise ModelError(f"{name}: offset = {off:g} s is not within [0, period = {per:g} s)")
    return LinkTiming(latency=lat, period=per, loss=p, offset=off)


def tdma_offsets(senders: Sequence[int], period: float) -> dict[int, float]:
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
    return {int(v): s * float(period) / S for s, v in enumerate(senders)}


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


class LinkChannel:
    """One directed link, stepped with the co-simulation (module docstring)."""

    def __init__(self, timing: LinkTiming, h: float, seed: int, key: int, size: int):
        self.timing, self.h, self.size = timing, float(h), int(size)
        self.rng = np.random.default_rng([int(seed), LINK_KEY_BASE + int(key)])
        self._first = round(timing.offset / self.h)
        self._every = timing.period / self.h
        self._m = 0                                  # next message number
        self.in_flight: deque[tuple[int, int, np.ndarray]] = deque()
        self.held: np.ndarray | None = None
        self.held_sent: int | None = None
        self.sent = self.lost = self.delivered = 0

    def _next_send(self) -> int:
        return self._first + round(self._m * self._every)

    def step(self, k: int, value: np.ndarray) -> None:
        """At step k: transmit ``value`` if k is a send step (unless lost), then deliver
        every message due by k.

        Parameters
        ----------
        k : int
            The step (t = k h), visited in increasing order.
        value : np.ndarray
            What the sender would send now, shape (size,).
        """
        while self._next_send() < k:                 # steps skipped: their messages never left
            self._m += 1
        if self._next_send() == k:
            self._m += 1
            self.sent += 1
            if self.rng.random() < self.timing.loss:
                self.lost += 1
            else:
                t_send = k * self.h
                arrive = math.ceil((t_send + self.timing.latency) / self.h - 1e-9)
                self.in_flight.append((arrive, k, np.array(value, dtype=float)))
        while self.in_flight and self.in_flight[0][0] <= k:
            _, k_sent, v = self.in_flight.popleft()
            self.held, self.held_sent = v, k_sent
            self.delivered += 1

    def age(self, k: int) -> float:
        """t - t_send of the newest message arrived by step k, s (inf before the first)."""
        return math.inf if self.held_sent is None else (k - self.held_sent) * self.h

    def received(self, k: int, Phi: np.ndarray | None = None) -> np.ndarray | None:
        """What the receiver uses at step k: the held value, or with ``Phi`` the held value
        propagated to k (None before the first message).

        Parameters
        ----------
        k : int
            The step.
        Phi : np.ndarray or None, optional
            The sender's one-step map (propagating receiver).

        Returns
        -------
        np.ndarray or None
            The value.
        """
        if self.held is None:
            return None
        if Phi is None:
            return self.held
        return propagate(self.held, k - self.held_sent, Phi)
