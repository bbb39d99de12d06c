"""FMI 2.0 co-simulation slave of one vehicle's acoustic modem inbox (plant_model.acoustic.inbox).

One FMU per receiving vehicle: its S neighbour links ``link[1..S]`` (messages made of the
build configuration's ``fields``, e.g. eta and eps) and, if ``leader_size`` > 0, its leader
link ``leader`` (message z). Inputs ``<link>.tx.<field>``: what the sender sends at t_k;
outputs ``<link>.rx.<field>``: what the receiver uses at t_k (the newest message that has
arrived, held or propagated by M, the launch value rx0 before the first arrival), the age
of information ``<link>.age`` (s) and the counts ``delivered``, ``lost``, ``in_flight``.
Timing, loss and the loss streams: plant_model.acoustic.links. With a bursty link in the
configuration (``loss_models``) every link also has ``<link>.loss_model`` (Integer: the
row of plant_model.acoustic.link_models, 0 independent with ``loss``, 1 Gilbert-Elliott
with ``p_gb``, ``p_bg``, ``loss_good``, ``loss_bad``). With a switching schedule
(``schedule`` in the configuration, plant_model.acoustic.schedule) the parameters
``schedule.t`` (the switch times, s), ``schedule.period`` (s; 0: no repetition) and per
link ``<link>.up`` (1 if the link carries messages in each graph, else 0): a message sent
while its link is down is lost. No direct feedthrough: a message sent at t_k is heard at
t_(k+1) at the earliest. FMU state: the inbox's state (step counter, every link's messages
and loss stream), plus what the base class saves.
"""
from typing import Any

import numpy as np

from fmu_common.interface import ArraySpec

# pythonfmu's loader looks for "class X(Fmi2Slave):"
from fmu_common.slave_base import DelegatedStateSlave as Fmi2Slave
from plant_model.acoustic.base import whole_steps
from plant_model.acoustic.inbox import Inbox, LinkSettings
from plant_model.acoustic.link_models import (
    LINK_MODELS,
    MODEL_KEY,
    GilbertElliott,
    model_of_code,
)
from plant_model.acoustic.links import check_link, in_range
from plant_model.acoustic.schedule import LinkSchedule
from plant_model.linalg_checks import ModelError
from plant_model.parameters import sample_period_spec

_STATS = (("age", "age of information: t - t_send of the message held", "s"),
          ("delivered", "messages that arrived so far", None),
          ("lost", "messages lost so far (counted when they would have arrived)", None),
          ("in_flight", "messages sent and not yet arrived", None))


def link_layout(config: dict[str, Any]) -> list[tuple[str, str, list[tuple[str, int]], dict]]:
    """(prefix, label, fields, start values) of every link: link[1..S], then the leader's.

    Parameters
    ----------
    config : dict[str, Any]
        The build configuration (``receiver``, ``slots``, ``fields``, ``leader_size``,
        ``links``, ``leader``).

    Returns
    -------
    list[tuple[str, str, list[tuple[str, int]], dict]]
        FMI name prefix, the link's name in messages, [(field, size), ...], its start values.

    Raises
    ------
    ModelError
        One line naming the configuration entry that does not fit.
    """
    where = "auv_network_config.json"
    S, nl, i = config["slots"], config["leader_size"], config["receiver"]
    fields = [(str(f), int(n)) for f, n in config["fields"]] if S else []
    if any(n < 1 for _, n in fields) or len({f for f, _ in fields}) != len(fields):
        raise ModelError(f"{where}: fields {config['fields']} need distinct names, sizes >= 1")
    if S < 0 or nl < 0 or len(config["links"]) != S:
        raise ModelError(f"{where}: slots = {S}, leader_size = {nl} and "
                         f"{len(config['links'])} links do not fit")
    out = [(f"link[{k}]", f"link[{k}] of vehicle {i}", fields, st)
           for k, st in enumerate(config["links"], start=1)]
    if nl:
        if not isinstance(config.get("leader"), dict):
            raise ModelError(f"{where}: leader_size = {nl} needs the leader link's settings")
        out.append(("leader", f"leader link of vehicle {i}", [("z", nl)], config["leader"]))
    return out


def _model_specs(config: dict[str, Any], p: str, label: str,
                 st: dict[str, Any]) -> list[ArraySpec]:
    """With bursty links in the configuration (``loss_models``): the link's model (its row
    number in plant_model.acoustic.link_models) and the Gilbert-Elliott parameters (neutral
    start values on a link of another model, which ignores them)."""
    if not config.get("loss_models"):
        return []
    names = ", ".join(f"{c} {n}" for c, n in enumerate(LINK_MODELS))
    out = [ArraySpec(f"{p}.{MODEL_KEY}", (), "parameter", f"{label}: how messages are lost "
                     f"({names})", start=int(st.get(MODEL_KEY, 0)), type="Integer", min=0,
                     max=len(LINK_MODELS) - 1)]
    neutral = {"p_gb": 0.5, "p_bg": 0.5, "loss_good": 0.0, "loss_bad": 1.0}
    out += [ArraySpec(f"{p}.{k}", (), "parameter", f"{label}: {GilbertElliott.DOCS[k]}",
                      start=float(st.get(k, neutral[k])), min=0.0, max=1.0)
            for k in GilbertElliott.PARAMETERS]
    return out


def _finite(name: str, value: np.ndarray) -> np.ndarray:
    """``value`` if finite, else a one-line ModelError naming the first bad FMI variable."""
    bad = np.argwhere(~np.isfinite(value))
    if bad.size:
        ix = tuple(int(j) for j in bad[0])
        raise ModelError(f"{name}[{','.join(str(j + 1) for j in ix)}] = {value[ix]} is not "
                         "finite")
    return value


class AuvNetwork(Fmi2Slave):
    """One vehicle's acoustic inbox: neighbour and leader links with latency and loss."""

    step_parameter = "h"
    math_name = "inbox"
    evolving_name = "s"
    description = ("Acoustic modem inbox of one AUV: the links it hears (message schedule, "
                   "latency, losses independent or in bursts), the receiver holding or "
                   "propagating the newest message")

    @staticmethod
    def interface(config: dict[str, Any]) -> list[ArraySpec]:
        """Per link: timing, loss, key, M, rx0; tx inputs; rx and statistics outputs; then
        h and seed. Configuration keys (see :meth:`ArraySlave.interface`): those of
        :func:`link_layout`, ``h``, ``seed``.
        """
        specs = []
        for p, label, fields, st in link_layout(config):
            w = sum(n for _, n in fields)
            specs += [
                ArraySpec(f"{p}.latency", (), "parameter", f"{label}: time a message "
                          "travels", start=st["latency"], unit="s", min=0.0),
                ArraySpec(f"{p}.period", (), "parameter", f"{label}: one message per period",
                          start=st["period"], unit="s"),
                ArraySpec(f"{p}.loss", (), "parameter", f"{label}: probability a message is "
                          "lost, in [0, 1) (its loss model's mean loss)", start=st["loss"],
                          min=0.0, max=1.0),
                ArraySpec(f"{p}.offset", (), "parameter", f"{label}: time of the first "
                          "transmission, in [0, period)", start=st["offset"], unit="s"),
                ArraySpec(f"{p}.key", (), "parameter", f"{label}: key of its loss stream "
                          "[seed, 1000000 + key]", start=st["key"], type="Integer", min=0,
                          max=2**31 - 1),
                *_model_specs(config, p, label, st),
                ArraySpec(f"{p}.M", (w, w), "parameter", f"{label}: the receiver propagates "
                          "the message it holds, rx <- M rx, every step (I: hold)",
                          start=st["M"]),
                ArraySpec(f"{p}.rx0", (w,), "parameter", f"{label}: the message exchanged "
                          "before launch (sent at t = 0)", start=st["rx0"]),
            ]
            specs += [ArraySpec(f"{p}.tx.{f}", (n,), "input", f"{label}: {f} the sender "
                                "sends at t_k") for f, n in fields]
            specs += [ArraySpec(f"{p}.rx.{f}", (n,), "output", f"{label}: {f} the receiver "
                                "uses at t_k") for f, n in fields]
            specs += [ArraySpec(f"{p}.{s}", (), "output", f"{label}: {d}", unit=u)
                      for s, d, u in _STATS]
            if config.get("schedule"):
                G = len(config["schedule"]["t"])
                specs.append(ArraySpec(f"{p}.up", (G,), "parameter", f"{label}: 1 if it "
                                       "carries messages in each graph of the schedule, else 0",
                                       start=np.asarray(st.get("up", [1] * G), int),
                                       type="Integer", min=0, max=1))
            if config.get("range") and p != "leader":
                specs.append(ArraySpec(f"{p}.tx.x", (config["state_size"],), "input",
                                       f"{label}: the sender's true state (its position "
                                       "decides whether it is in range)"))
        if config.get("range"):
            specs += [
                ArraySpec("range", (), "parameter", "modem range: a message sent farther "
                          "than this is lost", start=float(config["range"]), unit="m",
                          min=0.0),
                ArraySpec("x", (config["state_size"],), "input", "the receiver's true state "
                          "(its position decides whether a sender is in range)"),
            ]
            if config["leader_size"]:
                specs.append(ArraySpec("leader.H", (3, config["leader_size"]), "parameter",
                                       "the leader's position H z, NED", unit="m",
                                       start=np.asarray(config["leader_H"], float)))
        if config.get("schedule"):
            sch = config["schedule"]
            specs += [
                ArraySpec("schedule.t", (len(sch["t"]),), "parameter", "switch times of the "
                          "schedule: graph g holds from t[g] (increasing from 0)",
                          start=np.asarray(sch["t"], float), unit="s"),
                ArraySpec("schedule.period", (), "parameter", "the schedule repeats with "
                          "this period (0: the last graph holds to the end)",
                          start=float(sch["period"]), unit="s", min=0.0),
            ]
        return specs + [
            sample_period_spec(config, "communication step the links are stepped at"),
            ArraySpec("seed", (), "parameter", "seed of the fleet's noise (each link draws "
                      "its losses from the generator seeded [seed, 1000000 + key])",
                      start=config["seed"], type="Integer", min=0, max=2**31 - 1),
        ]

    def setup(self) -> None:
        """Validate every link and build the inbox at the experiment's first step.

        Raises
        ------
        ModelError
            One line naming the link or the variable: a bad timing, h not positive, a
            non-finite entry of M or rx0.
        """
        par = self.par
        h = float(par["h"])
        if not h > 0.0 or not np.isfinite(h):
            raise ModelError(f"h = {h} s must be a positive number")
        links, starts = [], {s.name: 0 for s in self.specs}
        pos = {"input": 0, "output": 0}
        for s in self.specs:
            if s.causality in pos:
                starts[s.name], pos[s.causality] = pos[s.causality], pos[s.causality] + s.size
        self._tx, self._blocks, self._pos = [], [], []
        self._range = float(par["range"]) if self.config.get("range") else None
        if self._range is not None:
            if not self._range > 0.0:
                raise ModelError(f"range = {self._range} m must be positive")
            self._where = np.asarray(self.config["position_index"], dtype=int)
            n = self.config["state_size"]
            self._own = self._in[starts["x"]:starts["x"] + n]
        for p, label, fields, _ in link_layout(self.config):
            w = sum(n for _, n in fields)
            code = int(par[f"{p}.{MODEL_KEY}"]) if self.config.get("loss_models") else 0
            row = list(LINK_MODELS.values())[code] if 0 <= code < len(LINK_MODELS) else None
            model = model_of_code(label, code, {} if row is None else {
                k: float(par[f"{p}.{k}"]) for k in row.PARAMETERS})
            timing = check_link(label, float(par[f"{p}.latency"]), float(par[f"{p}.period"]),
                                model, float(par[f"{p}.offset"]))
            whole_steps(f"{label}: period", timing.period, h)
            M = _finite(f"{p}.M", par[f"{p}.M"])
            rx0 = _finite(f"{p}.rx0", par[f"{p}.rx0"])
            hold = np.array_equal(M, np.eye(w))
            links.append(LinkSettings(label, timing, int(par[f"{p}.key"]), rx0.copy(),
                                      None if hold else M.copy()))
            i, o = starts[f"{p}.tx.{fields[0][0]}"], starts[f"{p}.rx.{fields[0][0]}"]
            self._tx.append(self._in[i:i + w])
            self._blocks.append(self._out[o:o + w + len(_STATS)])
            if self.config.get("range"):
                n = self.config["state_size"]
                if p == "leader":
                    H = _finite("leader.H", par["leader.H"])
                    self._pos.append(lambda tx=self._tx[-1], H=H: H @ tx)
                else:
                    j = starts[f"{p}.tx.x"]
                    self._pos.append(lambda x=self._in[j:j + n]: x[self._where])
        self._schedule = self._link_schedule(h)
        self.inbox = Inbox(links, h, int(par["seed"]), k0=round(self._start_time / h))

    def _link_schedule(self, h: float) -> LinkSchedule | None:
        """The schedule parameters checked: times from 0 increasing, whole steps; 0/1."""
        if not self.config.get("schedule"):
            return None
        par = self.par
        t = _finite("schedule.t", np.asarray(par["schedule.t"], float).reshape(-1))
        T = float(par["schedule.period"])
        if t[0] != 0.0 or np.any(np.diff(t) <= 0.0):
            raise ModelError(f"schedule.t = {t.tolist()} must start at 0 s and increase")
        if not (np.isfinite(T) and (T == 0.0 or T > t[-1])):
            raise ModelError(f"schedule.period = {T} s must be 0 or after the last switch "
                             f"at {t[-1]:g} s")
        switch = tuple(whole_steps(f"schedule.t[{g + 1}]", v, h) for g, v in enumerate(t))
        up = {}
        for j, (p, _, _, _) in enumerate(link_layout(self.config)):
            flags = np.asarray(par[f"{p}.up"]).reshape(-1)
            if not np.all(np.isin(flags, (0, 1))):
                raise ModelError(f"{p}.up = {flags.tolist()} must be 0 or 1 per graph")
            up[j] = tuple(bool(f) for f in flags)
        return LinkSchedule(switch=switch, period=whole_steps("schedule.period", T, h)
                            if T else 0, up=up)

    def compute_outputs(self) -> None:
        """Per link: rx, then age (s), delivered, lost, in flight, at the inbox's step."""
        ib = self.inbox
        stats = (ib.age(ib.k), ib.delivered, ib.lost, ib.in_flight)
        for j, (block, rx) in enumerate(zip(self._blocks, ib.rx)):
            block[:rx.size] = rx
            block[rx.size:] = [s[j] for s in stats]

    def advance(self, step: float) -> None:
        """One communication step: every link from step k to k + 1 with the tx inputs of t_k.

        Parameters
        ----------
        step : float
            The communication step, s (checked against h by the base class).
        """
        heard, k = None, self.inbox.k
        if self._range is not None:
            own = self._own[self._where]
            heard = [in_range(pos(), own, self._range) for pos in self._pos]
        if self._schedule is not None:
            up = [self._schedule.is_up(j, k) for j in range(len(self._tx))]
            heard = up if heard is None else [a and b for a, b in zip(heard, up)]
        self.inbox.advance(k, self._tx, heard)
