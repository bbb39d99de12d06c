"""The link-model registry: how an acoustic link loses messages, in one place.

Each row of :data:`LINK_MODELS` is a frozen dataclass that holds everything its kind needs:

- its parameters (:attr:`PARAMETERS`, the ``[network]`` keys and the network FMU's per-link
  parameters), parsed and validated by :meth:`parse` (every error one line naming the
  parameter and the value);
- how it draws: :meth:`draw` makes the loss decision of the next ``n`` messages of one link
  from that link's own PCG64 stream (numpy ``default_rng([seed, 1_000_000 + key])``) and a
  channel state carried from one call to the next (:meth:`start`), so that drawing message
  by message (the network FMUs, :class:`~.links.LinkChannel`) and all at once (the
  monolithic loop, ``orchestrator.analysis.acoustic.loop``) give the same losses;
- the terms the second-moment predictions use: the mean loss, and for a Markov channel its
  two states' loss rates, stationary bad-state probability and second eigenvalue
  (``orchestrator.analysis.acoustic.bursty``, derivation in docs/theory.md).

Rows:

``independent`` (:class:`Independent`)
    each message lost with probability ``loss``, independently: one uniform u per message,
    lost iff u < loss (the draws of every earlier version, bit for bit).
``gilbert-elliott`` (:class:`GilbertElliott`)
    a two-state Markov channel per link, good (G) and bad (B), stepped once per message
    slot (every send of the link, lost or not, down in a schedule or out of range): message
    n sees state s_n and is lost with probability ``loss_good`` or ``loss_bad``; s_0 is drawn
    from the stationary distribution, s_(n+1) from s_n with P(G -> B) = ``p_gb`` and
    P(B -> G) = ``p_bg``. Per message two uniforms in this order: u1 decides the state
    (s_0 = B iff u1 < pi_B; then B iff u1 < p_gb from G, iff u1 < 1 - p_bg from B), u2 the
    loss (lost iff u2 < loss_s). Stationary bad-state probability
    pi_B = p_gb / (p_gb + p_bg), mean loss (1 - pi_B) loss_good + pi_B loss_bad, mean burst
    (a stay in B) 1 / p_bg messages, mean gap (a stay in G) 1 / p_gb messages; successive
    states are correlated by lambda = 1 - p_gb - p_bg (0: independent states).

Pure numpy, no FMI. Look a model up with :func:`link_model`; docs/network.md.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from ..linalg_checks import ModelError
from .base import _number

__all__ = ["DEFAULT_MODEL", "GilbertElliott", "Independent", "LINK_MODELS", "LinkModel",
           "MODEL_KEY", "link_model", "min_burst", "model_code", "model_names",
           "model_of_code", "model_parameter_keys"]

#: the ``[network]`` (and links entry) key naming the model
MODEL_KEY = "loss_model"
#: the model of a link that names none
DEFAULT_MODEL = "independent"


def _probability(where: str, key: str, value: Any, *, low_open: bool = False,
                 high_open: bool = False) -> float:
    v = _number(f"{where}: {key}", value)
    lo_ok = v > 0.0 if low_open else v >= 0.0
    hi_ok = v < 1.0 if high_open else v <= 1.0
    if not (lo_ok and hi_ok):
        interval = f"{'(' if low_open else '['}0, 1{')' if high_open else ']'}"
        raise ModelError(f"{where}: {key} = {v:g} is not a probability in {interval}")
    return v


@dataclass(frozen=True)
class Independent:
    """Each message lost independently with probability ``loss`` (module docstring)."""

    loss: float = 0.0                   #: probability in [0, 1)

    name: ClassVar[str] = "independent"
    PARAMETERS: ClassVar[tuple[str, ...]] = ("loss",)
    #: per parameter: the network FMU's description
    DOCS: ClassVar[dict[str, str]] = {"loss": "probability a message is lost, in [0, 1)"}

    @classmethod
    def parse(cls, where: str, params: Mapping[str, Any]) -> Independent:
        """The model from its parameters (``loss``, default 0), or one line naming it."""
        p = _number(f"{where}: loss", params.get("loss", 0.0))
        if not 0.0 <= p < 1.0:
            raise ModelError(f"{where}: loss = {p:g} is not a probability in [0, 1) (a link "
                             "that loses every message carries nothing)")
        return cls(loss=p)

    @property
    def mean_loss(self) -> float:
        """The long-run fraction of messages lost."""
        return self.loss

    def parameters(self) -> dict[str, float]:
        """{parameter: value}, the keys of :attr:`PARAMETERS`."""
        return {"loss": self.loss}

    def start(self) -> int:
        """The channel state before the first message (no state: 0)."""
        return 0

    def draw(self, rng: np.random.Generator, n: int, state: int) -> tuple[np.ndarray, int]:
        """(lost, state): the next n messages' losses, one uniform each (u < loss)."""
        return rng.random(n) < self.loss, state

    def with_mean_burst(self, burst: float) -> Independent:
        """No bursts: itself."""
        return self


@dataclass(frozen=True)
class GilbertElliott:
    """A two-state Markov channel per link, stepped per message slot (module docstring)."""

    p_gb: float                         #: P(good -> bad) per message slot, in (0, 1]
    p_bg: float                         #: P(bad -> good) per message slot, in (0, 1]
    loss_good: float = 0.0              #: loss probability in the good state
    loss_bad: float = 1.0               #: loss probability in the bad state

    name: ClassVar[str] = "gilbert-elliott"
    PARAMETERS: ClassVar[tuple[str, ...]] = ("p_gb", "p_bg", "loss_good", "loss_bad")
    DOCS: ClassVar[dict[str, str]] = {
        "p_gb": "Gilbert-Elliott: probability good -> bad per message slot, in (0, 1]",
        "p_bg": "Gilbert-Elliott: probability bad -> good per message slot, in (0, 1] "
                "(mean burst 1 / p_bg messages)",
        "loss_good": "Gilbert-Elliott: loss probability in the good state, in [0, 1)",
        "loss_bad": "Gilbert-Elliott: loss probability in the bad state, in [0, 1], at "
                    "least loss_good"}

    @classmethod
    def parse(cls, where: str, params: Mapping[str, Any]) -> GilbertElliott:
        """The model from ``p_gb``, ``p_bg`` (required), ``loss_good`` (default 0) and
        ``loss_bad`` (default 1), or one line naming the parameter and its value."""
        for key in ("p_gb", "p_bg"):
            if key not in params:
                raise ModelError(f"{where}: {MODEL_KEY} = \"{cls.name}\" needs {key} (the "
                                 "probability of switching good -> bad (p_gb) and bad -> "
                                 "good (p_bg) per message slot)")
        gb = _probability(where, "p_gb", params["p_gb"], low_open=True)
        bg = _probability(where, "p_bg", params["p_bg"], low_open=True)
        eg = _probability(where, "loss_good", params.get("loss_good", 0.0), high_open=True)
        eb = _probability(where, "loss_bad", params.get("loss_bad", 1.0))
        if eb < eg:
            raise ModelError(f"{where}: loss_bad = {eb:g} is below loss_good = {eg:g} (the "
                             "bad state loses at least as often as the good one)")
        return cls(p_gb=gb, p_bg=bg, loss_good=eg, loss_bad=eb)

    @property
    def pi_bad(self) -> float:
        """Stationary probability of the bad state, p_gb / (p_gb + p_bg)."""
        return self.p_gb / (self.p_gb + self.p_bg)

    @property
    def mean_loss(self) -> float:
        """The long-run fraction of messages lost, (1 - pi_B) loss_good + pi_B loss_bad."""
        return (1.0 - self.pi_bad) * self.loss_good + self.pi_bad * self.loss_bad

    @property
    def mean_burst(self) -> float:
        """Mean stay in the bad state, 1 / p_bg messages."""
        return 1.0 / self.p_bg

    @property
    def correlation(self) -> float:
        """lambda = 1 - p_gb - p_bg: E[1_B(s_(n+1)) - pi_B | s_n] = lambda (1_B(s_n) - pi_B)."""
        return 1.0 - self.p_gb - self.p_bg

    def parameters(self) -> dict[str, float]:
        """{parameter: value}, the keys of :attr:`PARAMETERS`."""
        return {k: float(getattr(self, k)) for k in self.PARAMETERS}

    def start(self) -> int:
        """The channel state before the first message: -1 (s_0 not drawn yet)."""
        return -1

    def draw(self, rng: np.random.Generator, n: int, state: int) -> tuple[np.ndarray, int]:
        """(lost, state) of the next n messages: per message u1 (state) then u2 (loss)."""
        lost = np.empty(n, dtype=bool)
        s = int(state)
        for m in range(n):
            u1 = rng.random()
            if s < 0:
                s = int(u1 < self.pi_bad)
            elif s == 0:
                s = int(u1 < self.p_gb)
            else:
                s = int(u1 < 1.0 - self.p_bg)
            lost[m] = rng.random() < (self.loss_bad if s else self.loss_good)
        return lost, s

    def with_mean_burst(self, burst: float) -> GilbertElliott:
        """The same stationary bad-state probability and state losses (hence the same mean
        loss) with a mean burst of ``burst`` messages: p_bg = 1 / burst,
        p_gb = p_bg pi_B / (1 - pi_B) (needs burst >= max(1, pi_B / (1 - pi_B)))."""
        pb = self.pi_bad
        bg = 1.0 / float(burst)
        gb = bg * pb / (1.0 - pb)
        if not (0.0 < bg <= 1.0 and 0.0 < gb <= 1.0 + 1e-12):
            raise ModelError(f"mean burst {burst:g} messages is not reachable at a bad-state "
                             f"probability {pb:g} (at least {min_burst(pb):g})")
        return GilbertElliott(p_gb=min(gb, 1.0), p_bg=bg, loss_good=self.loss_good,
                              loss_bad=self.loss_bad)


def min_burst(pi_bad: float) -> float:
    """The shortest mean burst (messages) a two-state chain with this stationary bad-state
    probability has: max(1, pi_B / (1 - pi_B)) (p_bg <= 1 and p_gb <= 1)."""
    return max(1.0, pi_bad / (1.0 - pi_bad))


LinkModel = Independent | GilbertElliott

#: the registry: model name -> its row, in the order of the network FMU's ``loss_model``
#: codes (0, 1, ...)
LINK_MODELS: dict[str, type[Independent] | type[GilbertElliott]] = {
    Independent.name: Independent, GilbertElliott.name: GilbertElliott}


def model_names() -> tuple[str, ...]:
    """The registered model names."""
    return tuple(LINK_MODELS)


def model_code(model: LinkModel) -> int:
    """The model's row number (the network FMU's Integer ``loss_model``)."""
    return list(LINK_MODELS).index(model.name)


def model_of_code(where: str, code: int, params: Mapping[str, Any]) -> LinkModel:
    """The model of row ``code`` from its parameters (the network FMU's), or one line."""
    names = list(LINK_MODELS)
    if not 0 <= int(code) < len(names):
        raise ModelError(f"{where}: loss_model = {code} is not one of "
                         + ", ".join(f"{c} ({n})" for c, n in enumerate(names)))
    return LINK_MODELS[names[int(code)]].parse(where, params)


def link_model(where: str, params: Mapping[str, Any]) -> LinkModel:
    """The model a table names (``loss_model``, default independent) with its parameters.

    Parameters
    ----------
    where : str
        Names the table in errors, e.g. "[network]" or "network link 2 -> 4".
    params : Mapping[str, Any]
        ``loss_model`` and the model's parameters; another model's parameters are refused.

    Returns
    -------
    LinkModel
        The validated row instance.

    Raises
    ------
    ModelError
        One line: an unknown model, a parameter of another model, a bad value.
    """
    name = params.get(MODEL_KEY, DEFAULT_MODEL)
    if name not in LINK_MODELS:
        raise ModelError(f"{where}: {MODEL_KEY} = {name!r} is not one of "
                         f"{', '.join(repr(n) for n in LINK_MODELS)}")
    row = LINK_MODELS[name]
    others = sorted({k for r in LINK_MODELS.values() for k in r.PARAMETERS}
                    - set(row.PARAMETERS))
    wrong = [k for k in others if k in params]
    if wrong:
        raise ModelError(f"{where}: {', '.join(wrong)} = "
                         f"{', '.join(repr(params[k]) for k in wrong)} is not a parameter of "
                         f"{MODEL_KEY} = \"{name}\" (it takes {', '.join(row.PARAMETERS)})")
    return row.parse(where, params)


def model_parameter_keys() -> tuple[str, ...]:
    """Every parameter key of every row (the keys a ``[network]`` table may hold for them)."""
    out: list[str] = []
    for row in LINK_MODELS.values():
        out += [k for k in row.PARAMETERS if k not in out]
    return tuple(out)
