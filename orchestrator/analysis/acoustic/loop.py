"""The per-vehicle loop over acoustic links: held and in-flight messages as states.

A :class:`~orchestrator.analysis.acoustic.message_form.MessageForm` says what each vehicle computes
alone, what each sender transmits and how a received value enters its receiver; the links'
timing (:mod:`plant_model.acoustic.links`) says when. Augmented state Z = [X; F; R]:

- F: per sender and timing (a *group*: the links from one sender with one latency, period
  and offset share the message in flight), a shift register of q = ceil(D / P) slots, D the
  arrival delay and P the period in steps; a send at step k pushes msg_j(k) into slot 0;
- R: per link, the value the receiver uses (held, or propagated by the sender's model M).

One transition k -> k+1 (the order :class:`plant_model.acoustic.links.LinkChannel` uses):
X+ = Phi X + Gam zeta + sum_l B_l R_l; sends push msg into F; an arrival at k + 1 sets
R_l <- R_l + delta_l (F_slot - R_l) with delta_l = 1 if the message got through; then F and
R are propagated by M. So Z[k+1] = A_k(delta) Z[k] + Gam_k(delta) zeta[k] with
A_k(delta) = A_k0 + sum_l delta_l D_l: affine in each link's independent arrival
indicator, E delta_l = 1 - p_l. The second moment X2 = E[Z Z'] therefore obeys exactly::

    X2+ = Abar X2 Abar' + sum_l p_l (1 - p_l) D_l X2 D_l' + (noise terms)

one term per link arriving at that step (not 2^links modes). Between arrivals the steps are
deterministic and identical: runs of them are composed by doubling, so a message period
of 200 steps costs a few dense products. The expected cost of a run's window is
sum_k tr(Qz X2_k) + tr(R Geta W Geta') from the known start (the leader's motion included:
a holding receiver lags a moving leader), and mean-square stability is the spectral radius
of the period map of X2 on the error coordinates (without the leader's state) below 1.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
import scipy.sparse as sp

from plant_model.acoustic.base import whole_steps
from plant_model.acoustic.links import LINK_KEY_BASE, LinkTiming, arrival_step, in_range, link_key
from plant_model.acoustic.schedule import LinkSchedule
from plant_model.linalg_checks import ModelError

from .message_form import RECEIVERS, MessageForm

__all__ = ["NetworkedLoop", "Group"]


@dataclass(frozen=True)
class Group:
    """The links from one sender with one timing: first send, period and delay in steps."""

    sender: int | str
    first: int          #: step of the first send
    P: int              #: period, steps
    D: int              #: arrival delay, steps (>= 1)
    slots: tuple[slice, ...]

    @property
    def read_slot(self) -> int:
        """The shift-register slot an arriving message is in: floor((D - 1) / P)."""
        return (self.D - 1) // self.P

    def sends(self, k: int) -> bool:
        """Does the group transmit at step k?"""
        return k >= self.first and (k - self.first) % self.P == 0

    def arrives(self, k: int) -> int | None:
        """The message number arriving in the transition k -> k+1 (or None)."""
        s = k + 1 - self.D
        if s >= self.first and (s - self.first) % self.P == 0:
            return (s - self.first) // self.P
        return None


class NetworkedLoop:
    """The augmented loop of a message form and its links' timing (module docstring)."""

    def __init__(self, form: MessageForm, timings: Mapping[tuple[Any, int], LinkTiming],
                 receiver: str = "propagate", schedule: LinkSchedule | None = None):
        if receiver not in RECEIVERS:
            raise ModelError(f"receiver {receiver!r} is not one of {', '.join(RECEIVERS)}")
        missing = sorted(str(k) for k in form.links if k not in timings)
        if missing:
            raise ModelError(f"no timing for link(s) {', '.join(missing)}")
        self.form, self.receiver, self.h = form, receiver, form.h
        h = form.h
        nX = form.Phi.shape[0]
        pos = nX
        groups: dict[tuple[Any, ...], Group] = {}
        self.link_group: dict[tuple[Any, int], tuple[Any, ...]] = {}
        for key in form.links:
            t = timings[key]
            name = f"network link {key[0]} -> {key[1]}"
            P = whole_steps(f"{name}: period", t.period, h)
            first = whole_steps(f"{name}: offset", t.offset, h)
            D = arrival_step(0, h, t.latency)
            gk = (key[0], first, P, D)
            if gk not in groups:
                w = form.senders[key[0]].width
                q = math.ceil(D / P)
                slots = tuple(slice(pos + s * w, pos + (s + 1) * w) for s in range(q))
                pos += q * w
                groups[gk] = Group(key[0], first, P, D, slots)
            self.link_group[key] = gk
        self.groups = groups
        self.R: dict[tuple[Any, int], slice] = {}
        for key in form.links:
            w = form.senders[key[0]].width
            self.R[key] = slice(pos, pos + w)
            pos += w
        self.n = pos
        #: per link its mean loss (a Gilbert-Elliott link's stationary one: the independent
        #: part of its second-moment terms, orchestrator.analysis.acoustic.bursty)
        self.loss = {k: float(timings[k].loss) for k in form.links}
        #: the links whose losses are correlated in time (a Markov channel), by link
        self.bursty = {k: timings[k].bursts for k in form.links
                       if timings[k].bursts is not None}
        self.timings = dict(timings)
        self.period = int(np.lcm.reduce([g.P for g in groups.values()])) if groups else 1
        self.startup = max((g.first + g.D for g in groups.values()), default=0)
        #: links switched on and off by a schedule of graphs: a message sent while its link
        #: is down is lost; the patterns repeat over lcm(message cycle, schedule period), or
        #: with the message cycle once the last graph's messages arrive
        self.schedule = schedule
        if schedule is not None:
            if schedule.period:
                self.period = math.lcm(self.period, schedule.period)
            else:
                D = max((g.D for g in groups.values()), default=0)
                self.startup = max(self.startup, schedule.settled + D)
        self._patterns: dict[int, tuple[frozenset, frozenset]] = {}
        self.modem: tuple[float, dict[Any, np.ndarray]] | None = None
        self._Qz: np.ndarray | None = None
        nZ = form.Gam.shape[1]
        self.nZ = nZ
        # cost: e = Ce X, u = Gx_aug Z + Geta zeta
        Gx = np.zeros((form.Gx.shape[0], self.n))
        Gx[:, :nX] = form.Gx
        for key, lk in form.links.items():
            Gx[:, self.R[key]] += lk.Gu
        Ce = np.zeros((form.Ce.shape[0], self.n))
        Ce[:, :nX] = form.Ce
        self.Gx, self.Ce = Gx, Ce
        self.c0 = float(np.trace(form.Rc @ form.Geta @ form.W @ form.Geta.T))
        det = np.zeros(self.n, dtype=bool)
        det[:nX] = form.deterministic
        self.deterministic = det

    @property
    def Qz(self) -> np.ndarray:
        """The step cost e'Q e + u'R u = Z' Qz Z (+ the noise part c0), n x n: built on
        first use (the simulation and the FMU configurations never need it)."""
        if self._Qz is None:
            f = self.form
            self._Qz = self.Ce.T @ f.Qc @ self.Ce + self.Gx.T @ f.Rc @ self.Gx
        return self._Qz

    # --------------------------------------------------------------- one transition
    def pattern(self, k: int) -> tuple[frozenset, frozenset]:
        """(groups sending, links receiving) in the transition k -> k+1 (periodic with the
        cycle once every link has delivered its first message); a link receives when a
        message sent while it was up (:attr:`schedule`) is due."""
        if k >= self.startup + self.period:
            k = self.startup + (k - self.startup) % self.period
        if k not in self._patterns:
            sends = frozenset(g for g, grp in self.groups.items() if grp.sends(k))
            arr = frozenset(key for key, g in self.link_group.items()
                            if self.groups[g].arrives(k) is not None and self._up(key, k))
            self._patterns[k] = (sends, arr)
        return self._patterns[k]

    def _up(self, key: tuple[Any, int], k: int) -> bool:
        """Was the message arriving in k -> k+1 on ``key`` sent while the link was up?"""
        if self.schedule is None:
            return True
        return self.schedule.is_up(key, k + 1 - self.groups[self.link_group[key]].D)

    @lru_cache(maxsize=64)  # noqa: B019 - a loop lives as long as its predictions
    def matrices(self, pattern: tuple[frozenset, frozenset]
                 ) -> tuple[sp.csr_matrix, dict[tuple[Any, int], sp.csr_matrix]]:
        """(A0, {link: D_l}) of one pattern over [Z; zeta]:
        Z+ = (A0 + sum_l delta_l D_l) [Z; zeta]."""
        sends, arrivals = pattern
        f, n, nX, nZ = self.form, self.n, self.form.Phi.shape[0], self.nZ
        rows, cols, vals = [], [], []

        def put(r0: int, c0: int, M: np.ndarray) -> None:
            M = sp.coo_matrix(M)
            rows.append(M.row + r0)
            cols.append(M.col + c0)
            vals.append(M.data)

        def eye(r: slice, c: slice) -> None:
            put(r.start, c.start, sp.identity(r.stop - r.start))

        put(0, 0, f.Phi)
        put(0, n, f.Gam)
        for key, lk in f.links.items():
            put(0, self.R[key].start, lk.B)
        for g, grp in self.groups.items():
            if g in sends:
                s = f.senders[grp.sender]
                put(grp.slots[0].start, 0, s.Cm)
                put(grp.slots[0].start, n, s.Dm)
                for lkey, Cr in s.Cr.items():
                    put(grp.slots[0].start, self.R[lkey].start, Cr)
                for a, b in zip(grp.slots[1:], grp.slots[:-1]):
                    eye(a, b)
            else:
                for sl in grp.slots:
                    eye(sl, sl)
        for sl in self.R.values():
            eye(sl, sl)
        E1 = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows),
                                                   np.concatenate(cols))), shape=(n, n + nZ))
        blocks = [sp.identity(nX)]
        for grp in self.groups.values():
            M = f.senders[grp.sender].M(self.receiver)
            blocks += [sp.csr_matrix(M)] * len(grp.slots)
        for key in f.links:
            blocks.append(sp.csr_matrix(f.senders[key[0]].M(self.receiver)))
        Prop = sp.block_diag(blocks, format="csr")
        A0 = (Prop @ E1).tocsr()
        D: dict[tuple[Any, int], sp.csr_matrix] = {}
        for key in sorted(arrivals, key=str):
            grp = self.groups[self.link_group[key]]
            w = self.R[key].stop - self.R[key].start
            El = sp.lil_matrix((n, n))
            Rl, Fs = self.R[key], grp.slots[grp.read_slot]
            El[Rl, Fs] = np.eye(w)
            El[Rl, Rl] = -np.eye(w)
            D[key] = (Prop @ El.tocsr() @ E1).tocsr()
        return A0, D

    # --------------------------------------------------------------- simulation
    def initial_state(self, X0: np.ndarray) -> np.ndarray:
        """Z(0): the loop at X0, nothing in flight, every receiver holding the launch value
        (:meth:`launch_messages`)."""
        Z = np.zeros(self.n)
        Z[:X0.size] = X0
        for key, m in self.launch_messages(X0).items():
            Z[self.R[key]] = m
        return Z

    def launch_messages(self, X0: np.ndarray) -> dict[tuple[Any, int], np.ndarray]:
        """Per link the value exchanged before launch: msg_j = Cm_j X0 (no noise; a message's
        part that depends on received values, a centralized u, is 0)."""
        return {key: self.form.senders[key[0]].Cm @ X0 for key in self.form.links}

    def deliveries(self, seed: int, steps: int) -> dict[tuple[Any, int], np.ndarray]:
        """Per link, whether each message gets through: the draws the network FMU makes,
        the link's loss model (:mod:`plant_model.acoustic.link_models`) on its stream
        [seed, LINK_KEY_BASE + link_key(j, i)], and never
        while the schedule has the link down at its send step."""
        out = {}
        for key, g in self.link_group.items():
            grp = self.groups[g]
            count = max(0, math.ceil((steps - grp.first) / grp.P))
            rng = np.random.default_rng([int(seed), LINK_KEY_BASE + link_key(*key)])
            model = self.timings[key].model
            out[key] = ~model.draw(rng, count, model.start())[0]
            if self.schedule is not None:
                out[key] &= np.array([self.schedule.is_up(key, grp.first + m * grp.P)
                                      for m in range(count)], dtype=bool)
        return out

    def set_modem_range(self, limit: float, positions: Mapping[Any, np.ndarray]) -> None:
        """Simulation only: a message is lost when its sender and receiver are farther apart
        than ``limit`` (m) at its send time; ``positions`` maps a vehicle number or "leader"
        to the 3 x n matrix of its NED position in Z."""
        self.modem = (float(limit), {k: np.asarray(v, float) for k, v in positions.items()})

    def simulate(self, Z0: np.ndarray, zeta: np.ndarray, seed: int) -> np.ndarray:
        """Z[k] for k = 0..steps-1 with each link's own loss draws (the FMUs' realisation).

        Parameters
        ----------
        Z0 : np.ndarray
            :meth:`initial_state`.
        zeta : np.ndarray
            (steps, nzeta): the vehicles' noise.
        seed : int
            The links' seed.

        Returns
        -------
        np.ndarray
            (steps, n).
        """
        steps = zeta.shape[0]
        ok = self.deliveries(seed, steps)
        out = np.empty((steps, self.n))
        Z = np.asarray(Z0, float)
        for k in range(steps):
            out[k] = Z
            if self.modem is not None:           # out of range at its send time: lost
                limit, pos = self.modem
                for key, g in self.link_group.items():
                    grp = self.groups[g]
                    if grp.sends(k):
                        m = (k - grp.first) // grp.P
                        if not in_range(pos[key[0]] @ Z, pos[key[1]] @ Z, limit):
                            ok[key][m] = False
            A0, D = self.matrices(self.pattern(k))
            ext = np.concatenate([Z, zeta[k]])
            Z = A0 @ ext
            for key, Dl in D.items():
                if ok[key][self.groups[self.link_group[key]].arrives(k)]:
                    Z = Z + Dl @ ext
        return out

    def ages(self, steps: int, seed: int) -> dict[tuple[Any, int], np.ndarray]:
        """Age of the information each receiver holds, t_k - t_send, per link and step, s."""
        ok = self.deliveries(seed, steps)
        out = {}
        for key, g in self.link_group.items():
            grp = self.groups[g]
            sent, age = 0, np.empty(steps)
            for k in range(steps):
                age[k] = (k - sent) * self.h
                m = grp.arrives(k)
                if m is not None and ok[key][m]:
                    sent = grp.first + m * grp.P
            out[key] = age
        return out
