"""A per-vehicle loop cut at its messages: what each vehicle computes alone, and what it hears.

With perfect links every vehicle reads its neighbours' current values; over acoustic links it
reads what its modem last received (:mod:`plant_model.acoustic.links`). To put a network between
them, the stacked loop is written with the received values r_l (one per link l = j -> i) as
inputs::

    X[k+1] = Phi X + Gam zeta + sum_l B_l r_l          (the local loop: nobody hears anybody)
    u[k]   = Gx X + Geta zeta + sum_l Gu_l r_l
    msg_j  = Cm_j X + Dm_j zeta + sum_l Cr_jl r_l      (what sender j transmits)

and perfect links are r_l = msg_j. Messages, as the FMUs send them:

- distributed: vehicle j sends [eta_j; eps_j] (its observer of the leader and its regulation
  error; eps only with cohesion), the leader sends its state v; a propagating receiver carries
  eta and v forward with the leader's sampled exosystem Phi_F and holds eps;
- centralized: vehicle j sends [xhat_j; what_j; u_j] (its estimate and control); a
  propagating receiver carries the estimate forward with the vehicle's own sampled model,
  s <- Ad_j s + Bd_j u (u held); the leader sends z (propagated with Phi_F).

Each message's one-step propagation matrix M_j (identity for a holding receiver) is part of
the form, so the networked loop (:mod:`orchestrator.analysis.acoustic.loop`) needs nothing else.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.linalg import block_diag

from plant_model.acoustic.settings import RECEIVERS

from ..distributed import (
    DistributedLoop,
    SampledAgent,
    _assemble,
    add_vehicle_rows,
    estimate_rows,
    filtered,
)

__all__ = ["MessageForm", "Sender", "Link", "RECEIVERS", "centralized_message_form",
           "distributed_message_form", "perfect_links", "without_leader_links"]



@dataclass(frozen=True, eq=False)
class Sender:
    """msg = Cm X + Dm zeta + sum_l Cr[l] r_l; M_hold / M_prop: one step of the receiver."""

    Cm: np.ndarray
    Dm: np.ndarray
    M_prop: np.ndarray
    Cr: dict[Any, np.ndarray] = field(default_factory=dict)
    fields: tuple[tuple[str, int], ...] = ()

    @property
    def width(self) -> int:
        """Number of values in one message."""
        return self.Cm.shape[0]

    def M(self, receiver: str) -> np.ndarray:
        """The receiver's one-step map of this sender's message (identity: hold)."""
        return self.M_prop if receiver == "propagate" else np.eye(self.width)


@dataclass(frozen=True, eq=False)
class Link:
    """How the value received over j -> i enters vehicle i: X+ += B r, u += Gu r."""

    sender: int | str
    receiver: int
    B: np.ndarray
    Gu: np.ndarray


@dataclass(frozen=True, eq=False)
class MessageForm:
    """The local loop, the senders and the links (module docstring)."""

    Phi: np.ndarray
    Gam: np.ndarray
    W: np.ndarray
    Gx: np.ndarray
    Geta: np.ndarray
    Ce: np.ndarray
    Qc: np.ndarray
    Rc: np.ndarray
    deterministic: np.ndarray
    h: float
    senders: dict[int | str, Sender]
    links: dict[tuple[int | str, int], Link]
    architecture: str
    #: the states of the loop it was cut from that it keeps (None: all)
    keep: np.ndarray | None = None

    def state_of(self, X_loop: np.ndarray) -> np.ndarray:
        """This form's state from a state of the loop it was cut from."""
        return X_loop if self.keep is None else X_loop[self.keep]


def without_leader_links(form: MessageForm) -> MessageForm:
    """The distributed form for a planned path every vehicle knows: no leader messages; a
    pinned vehicle's leader input is its own observer (its weight then adds nothing)."""
    Phi = form.Phi.copy()
    links = {}
    for key, lk in form.links.items():
        if key[0] == "leader":
            own = form.senders[lk.receiver].Cm[:lk.B.shape[1]]
            Phi += lk.B @ own
        else:
            links[key] = lk
    senders = {k: s for k, s in form.senders.items() if k != "leader"}
    return replace(form, Phi=Phi, links=links, senders=senders)


def perfect_links(form: MessageForm) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(Phi, Gam, Gx, Geta) of the loop with r_l = msg_j (every message heard at once).

    Messages that depend on received values (a centralized vehicle's u) are resolved by
    substitution: no link reads the part of a message that does (u is only for propagation).

    Parameters
    ----------
    form : MessageForm
        The cut loop.

    Returns
    -------
    tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
        The closed loop's matrices.
    """
    Phi, Gam, Gx, Geta = (form.Phi.copy(), form.Gam.copy(), form.Gx.copy(),
                          form.Geta.copy())
    for link in form.links.values():
        s = form.senders[link.sender]
        Phi += link.B @ s.Cm
        Gam += link.B @ s.Dm
        Gx += link.Gu @ s.Cm
        Geta += link.Gu @ s.Dm
    return Phi, Gam, Gx, Geta


def _selector(rows: int, n: int, sl: slice) -> np.ndarray:
    E = np.zeros((rows, n))
    E[:, sl] = np.eye(rows)
    return E


def distributed_message_form(loop: DistributedLoop, H: Any, offsets: Sequence[Any]
                             ) -> MessageForm:
    """The distributed loop cut at its messages: [eta_j; eps_j] between vehicles, v from the
    leader to the pinned ones.

    The local loop is the stacked one with only the diagonal of L + G (each vehicle's own
    terms d_i eta_i and the cohesion on its own eps_i) and no leader term; link j -> i adds
    a_ij mu Gam_F r_eta to eta_i's update and c a_ij Kx_i r_eps to u_i (through Bd_i into
    s_i and q_i); the leader's link g_i mu Gam_F v.

    Parameters
    ----------
    loop : DistributedLoop
        The stacked loop (:func:`orchestrator.analysis.per_vehicle.distributed_loop_of`).
    H : Any
        The leader's tracked output.
    offsets : Sequence[Any]
        Formation offsets d_i.

    Returns
    -------
    MessageForm
        The cut loop (``perfect_links`` of it is ``loop``, to rounding).
    """
    LG, kalman = loop.LG, filtered(loop.estimator)
    N = LG.shape[0]
    g = np.array([LG[i].sum() for i in range(N)])          # (L + G) 1 = g
    local = _assemble(loop.sampled, loop.laws, np.diag(np.diag(LG)), np.zeros(N),
                      loop.observer, np.asarray(H, float), [np.asarray(d, float)
                                                            for d in offsets],
                      loop.cohesion, kalman)
    nX, nZ = loop.Phi.shape[0], loop.Gam.shape[1]
    idx = loop.index
    l_ = loop.observer.Phi.shape[0]
    B_obs = loop.observer.B_nbr
    coh = loop.cohesion != 0.0
    ps = [law.Kx.shape[1] for law in loop.laws]
    ms = [law.Kx.shape[0] for law in loop.laws]
    # what each vehicle's eps is, from the stacked loop's own rows (Epsx, Epsn)
    senders: dict[int | str, Sender] = {}
    for j in range(N):
        Cm = _selector(l_, nX, idx["eta"][j])
        Dm = np.zeros((l_, nZ))
        M = loop.observer.Phi
        fields: list[tuple[str, int]] = [("eta", l_)]
        if coh:
            Ex, En = _eps_rows(loop, j)
            Cm, Dm = np.vstack([Cm, Ex]), np.vstack([Dm, En])
            M = block_diag(M, np.eye(ps[j]))
            fields.append(("eps", ps[j]))
        senders[j + 1] = Sender(Cm=Cm, Dm=Dm, M_prop=M, fields=tuple(fields))
    senders["leader"] = Sender(Cm=_selector(l_, nX, idx["v"][0]), Dm=np.zeros((l_, nZ)),
                               M_prop=loop.observer.Phi, fields=(("z", l_),))
    u_rows = np.cumsum([0] + ms)
    links: dict[tuple[int | str, int], Link] = {}
    for i in range(N):
        sa = loop.sampled[i]
        for j in np.flatnonzero(LG[i]):
            if j == i:
                continue
            a = -LG[i, j]
            w = senders[j + 1].width
            B = np.zeros((nX, w))
            Gu = np.zeros((sum(ms), w))
            B[idx["eta"][i], :l_] = a * B_obs
            if coh:
                U = loop.cohesion * a * loop.laws[i].Kx           # m_i x p_j on r_eps
                Gu[u_rows[i]:u_rows[i + 1], l_:] = U
                B[idx["s"][i], l_:] = sa.Bd @ U
                if kalman:
                    B[idx["q"][i], l_:] = sa.Bd @ U
            links[(j + 1, i + 1)] = Link(j + 1, i + 1, B, Gu)
        if g[i] > 0.0:
            B = np.zeros((nX, l_))
            B[idx["eta"][i]] = g[i] * B_obs
            links[("leader", i + 1)] = Link("leader", i + 1, B, np.zeros((sum(ms), l_)))
    return MessageForm(Phi=local["Phi"], Gam=local["Gam"], W=loop.W, Gx=local["Gx"],
                       Geta=local["Geta"], Ce=loop.Ce, Qc=loop.Qc, Rc=loop.Rc,
                       deterministic=loop.deterministic, h=loop.h, senders=senders,
                       links=links, architecture="distributed")


def _eps_rows(loop: DistributedLoop, j: int) -> tuple[np.ndarray, np.ndarray]:
    """eps_j = Ex X + En zeta (the regulation error vehicle j computes and sends)."""
    sa, law, idx = loop.sampled[j], loop.laws[j], loop.index
    nX, nZ = loop.Phi.shape[0], loop.Gam.shape[1]
    kalman = filtered(loop.estimator)
    Est, Esn = estimate_rows(sa, idx["s"][j], idx["q"][j] if kalman else None,
                             idx["zeta_n"][j], nX, nZ)
    T = np.hstack([np.eye(law.Kx.shape[1]), -law.Xw])
    Ex, En = T @ Est, T @ Esn
    Ex[:, idx["eta"][j]] -= law.X
    Ex[:, idx["c"][0].start] -= law.xc
    return Ex, En


def centralized_message_form(loop: DistributedLoop, rows: Sequence[tuple[np.ndarray, np.ndarray]]
                             ) -> MessageForm:
    """The centralized per-vehicle loop cut at its messages.

    Vehicle i applies u_i = u0_i c - K_i [est_1; ...; est_N; z] (its rows of the stacked
    gain, :func:`controller_fmu.vehicle_law.centralized_rows`) with its own estimate est_i
    read directly and every other est_j and z received: link j -> i adds -K_ij r_est, the
    leader's link -K_iz r_z. Vehicle j's message is [est_j; u_j].

    The vehicles, estimators and leader are those of a distributed loop (its observers are
    not used: they are removed from the state).

    Parameters
    ----------
    loop : DistributedLoop
        A distributed loop of the same fleet and estimator mode (for its vehicles).
    rows : Sequence[tuple[np.ndarray, np.ndarray]]
        Per vehicle (K_i, u0_i).

    Returns
    -------
    MessageForm
        The cut loop.
    """
    N = len(loop.sampled)
    kalman = filtered(loop.estimator)
    idx = loop.index
    keep = np.ones(loop.Phi.shape[0], dtype=bool)
    for sl in idx["eta"]:
        keep[sl] = False
    pos = np.cumsum(keep) - 1                              # old index -> new
    nX, nZ = int(keep.sum()), loop.Gam.shape[1]

    def moved(sl: slice) -> slice:
        return slice(int(pos[sl.start]), int(pos[sl.stop - 1]) + 1)

    nidx = {k: [moved(s) for s in v] for k, v in idx.items()
            if k != "eta" and not k.startswith("zeta_")}
    nidx["n"] = idx["zeta_n"]
    ns = [sa.Ad.shape[0] for sa in loop.sampled]
    ms = [sa.Bd.shape[1] for sa in loop.sampled]
    l_ = loop.observer.Phi.shape[0]
    iv, ic = nidx["v"][0], nidx["c"][0].start
    Phi, Gam = np.zeros((nX, nX)), np.zeros((nX, nZ))
    Phi[iv, iv] = loop.observer.Phi
    Phi[ic, ic] = 1.0
    est = [estimate_rows(sa, nidx["s"][j], nidx["q"][j] if kalman else None, nidx["n"][j],
                         nX, nZ) for j, sa in enumerate(loop.sampled)]
    col = np.cumsum([0] + ns)
    Ux, Un = [], []
    for i, (K, u0) in enumerate(rows):
        Kown = K[:, col[i]:col[i + 1]]
        Ux.append(-Kown @ est[i][0])
        Ux[i][:, ic] += u0
        Un.append(-Kown @ est[i][1])
    add_vehicle_rows(Phi, Gam, loop.sampled, nidx, idx["zeta_nu"], Ux, Un,
                     [e[0] for e in est], [e[1] for e in est], kalman)
    Gx, Geta = np.vstack(Ux), np.vstack(Un)
    u_rows = np.cumsum([0] + ms)
    links: dict[tuple[int | str, int], Link] = {}
    senders: dict[int | str, Sender] = {}
    for i, (K, _) in enumerate(rows):
        sa = loop.sampled[i]
        for j in range(N):
            if j == i:
                continue
            U = np.hstack([-K[:, col[j]:col[j + 1]], np.zeros((ms[i], ms[j]))])
            links[(j + 1, i + 1)] = _link_into(j + 1, i + 1, U, sa, nidx, i, nX, u_rows,
                                               kalman)
        Uz = -K[:, col[N]:col[N] + l_]
        links[("leader", i + 1)] = _link_into("leader", i + 1, Uz, sa, nidx, i, nX, u_rows,
                                              kalman)
    for j, sa in enumerate(loop.sampled):
        Cr = {key: lk.Gu[u_rows[j]:u_rows[j + 1]] for key, lk in links.items()
              if lk.receiver == j + 1}
        zr = {key: np.vstack([np.zeros((ns[j], m.shape[1])), m]) for key, m in Cr.items()}
        M = np.block([[sa.Ad, sa.Bd], [np.zeros((ms[j], ns[j])), np.eye(ms[j])]])
        senders[j + 1] = Sender(
            Cm=np.vstack([est[j][0], Gx[u_rows[j]:u_rows[j + 1]]]),
            Dm=np.vstack([est[j][1], Geta[u_rows[j]:u_rows[j + 1]]]), M_prop=M, Cr=zr,
            fields=(("xhat", ns[j] - _r(loop, j)), ("what", _r(loop, j)), ("u", ms[j])))
    senders["leader"] = Sender(Cm=_selector(l_, nX, iv), Dm=np.zeros((l_, nZ)),
                               M_prop=loop.observer.Phi, fields=(("z", l_),))
    det = np.zeros(nX, dtype=bool)
    det[:l_ + 1] = True
    return MessageForm(Phi=Phi, Gam=Gam, W=loop.W, Gx=Gx, Geta=Geta, Ce=loop.Ce[:, keep],
                       Qc=loop.Qc, Rc=loop.Rc, deterministic=det, h=loop.h, senders=senders,
                       links=links, architecture="centralized", keep=keep)


def _r(loop: DistributedLoop, j: int) -> int:
    return loop.sampled[j].Ad.shape[0] - loop.laws[j].Kx.shape[1]


def _link_into(j: int | str, i: int, U: np.ndarray, sa: SampledAgent,
               idx: dict[str, list[slice]], i0: int, nX: int, u_rows: np.ndarray,
               kalman: bool) -> Link:
    """A link whose received value enters u_i as U r (and through Bd_i, s_i and q_i)."""
    B = np.zeros((nX, U.shape[1]))
    B[idx["s"][i0]] = sa.Bd @ U
    if kalman:
        B[idx["q"][i0]] = sa.Bd @ U
    Gu = np.zeros((int(u_rows[-1]), U.shape[1]))
    Gu[u_rows[i0]:u_rows[i0 + 1]] = U
    return Link(j, i, B, Gu)
