"""One vehicle's acoustic inbox: every link that ends at it, stepped together.

A receiving vehicle hears some neighbours (and perhaps the leader) over acoustic links;
each is a :class:`~plant_model.acoustic.links.LinkChannel` (schedule, latency, loss, held or
propagated message). :class:`Inbox` steps them with the co-simulation's step counter k
(t = k h, s), exposes what the receiver uses now (``rx``, one array per link), each link's
age of information (s) and message counts, and its whole state as one flat float array
(the FMU state of plant_model.acoustic.auv_network_slave). Pure numpy, no FMI.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from .links import LinkChannel, LinkTiming

__all__ = ["Inbox", "LinkSettings"]

#: a LinkChannel's state: 6 counters and the loss model's channel state, rx (size), per
#: message in flight 3 + size, 10 RNG words
_HEAD, _MSG, _RNG = 7, 3, 10


class LinkSettings(NamedTuple):
    """One link ending at the receiver."""

    name: str                   #: names the link in messages, e.g. "link[2] of vehicle 3"
    timing: LinkTiming
    key: int                    #: loss stream [seed, LINK_KEY_BASE + key]
    rx0: np.ndarray             #: the value held before the first arrival (launch)
    M: np.ndarray | None = None  #: propagation matrix (None: hold)


class Inbox:
    """The links ending at one vehicle, stepped from step k0 on (module docstring).

    Parameters
    ----------
    links : Sequence[LinkSettings]
        The links, in output order.
    h : float
        Communication step, s.
    seed : int
        The fleet's seed (each link draws its losses from [seed, LINK_KEY_BASE + key]).
    k0 : int, optional
        The first step (t = k0 h).
    """

    def __init__(self, links: Sequence[LinkSettings], h: float, seed: int, k0: int = 0):
        self.names = [ln.name for ln in links]
        self.links = [LinkChannel(ln.timing, h, seed, ln.key, ln.rx0, ln.M) for ln in links]
        self.h = float(h)
        self.k = int(k0)            #: the step the inbox is at (next to advance)

    @property
    def rx(self) -> list[np.ndarray]:
        """What the receiver uses now, per link (the newest message, held or propagated)."""
        return [ch.rx for ch in self.links]

    @property
    def s(self) -> np.ndarray:
        """All ``rx`` concatenated (the vector a step advances)."""
        return np.concatenate([ch.rx for ch in self.links]) if self.links else np.zeros(0)

    def advance(self, k: int, tx_list: Sequence[np.ndarray],
                heard: Sequence[bool] | None = None) -> None:
        """The transition from step k to k + 1 of every link.

        Parameters
        ----------
        k : int
            The step (t = k h), visited in increasing order.
        tx_list : Sequence[np.ndarray]
            What each link's sender sends at t_k, one array per link.
        heard : Sequence[bool] or None, optional
            Per link whether sender and receiver are within the modem's range at t_k
            (None: all).

        Raises
        ------
        ValueError
            If the number of messages is not the number of links.
        """
        if len(tx_list) != len(self.links):
            raise ValueError(f"inbox: {len(tx_list)} messages for {len(self.links)} links")
        for j, (ch, tx) in enumerate(zip(self.links, tx_list)):
            ch.advance(k, tx, True if heard is None else bool(heard[j]))
        self.k = int(k) + 1

    def age(self, k: int) -> np.ndarray:
        """Per link: t_k - t_send of the message held at step k, s."""
        return np.array([ch.age(k) for ch in self.links], dtype=float)

    @property
    def delivered(self) -> np.ndarray:
        """Per link: messages that arrived so far."""
        return np.array([ch.delivered for ch in self.links], dtype=float)

    @property
    def lost(self) -> np.ndarray:
        """Per link: messages lost so far (counted at their would-be arrival step)."""
        return np.array([ch.lost for ch in self.links], dtype=float)

    @property
    def in_flight(self) -> np.ndarray:
        """Per link: messages sent and not yet arrived (or lost)."""
        return np.array([len(ch.in_flight) for ch in self.links], dtype=float)

    def get_state(self) -> np.ndarray:
        """[k, L, length of each link's state, each link's state]: one flat float array."""
        parts = [ch.get_state() for ch in self.links]
        return np.concatenate([[float(self.k), float(len(parts))],
                               [float(p.size) for p in parts], *parts])

    def set_state(self, state: np.ndarray) -> None:
        """Restore :meth:`get_state`; validated first, the inbox is unchanged on error.

        Raises
        ------
        ValueError
            Naming the link and the problem if the array does not fit this inbox.
        """
        s = np.asarray(state, dtype=float).reshape(-1)
        L = len(self.links)
        if s.size < 2 or not np.all(np.isfinite(s)):
            raise ValueError("inbox state: not a finite array with a header")
        if s[1] != L or s.size < 2 + L:
            raise ValueError(f"inbox state: holds {s[1]:g} links, this inbox has {L}")
        lengths = s[2:2 + L]
        if np.any(lengths != np.round(lengths)) or lengths.sum() != s.size - 2 - L:
            raise ValueError(f"inbox state: {s.size} values do not match the link lengths "
                             f"{lengths.tolist()}")
        chunks, pos = [], 2 + L
        for name, ch, n in zip(self.names, self.links, lengths.astype(int)):
            part = s[pos:pos + n]
            pos += n
            flying = int(part[5]) if n > 5 else -1
            want = _HEAD + ch.size + flying * (_MSG + ch.size) + _RNG
            if flying < 0 or n != want:
                raise ValueError(f"inbox state: {name}: {n} values, expected {want} for a "
                                 f"message of {ch.size} values")
            chunks.append(part)
        saved = [ch.get_state() for ch in self.links]
        try:
            for ch, part in zip(self.links, chunks):
                ch.set_state(part)
        except Exception as exc:                     # e.g. a corrupt RNG state: put back
            for ch, part in zip(self.links, saved):
                ch.set_state(part)
            raise ValueError(f"inbox state: a link's state cannot be restored ({exc})") from None
        self.k = int(s[0])
