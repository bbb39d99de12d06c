"""The leader paths by name (a scenario's ``[leader] path``): :func:`make_leader` builds one
from its parameter table, refusing an unknown path, an unknown or a missing parameter in
one line that starts with "leader: "."""
from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from .leader import LeaderPath, circle, explicit, lawnmower, straight
from .linalg_checks import ModelError

__all__ = ["LEADER_PATHS", "make_leader"]

#: Names accepted by :func:`make_leader`.
LEADER_PATHS = ("straight", "circle", "lawnmower", "explicit")

_BUILDERS: dict[str, tuple[Callable[..., LeaderPath], tuple[str, ...], tuple[str, ...]]] = {
    # kind: (builder, required keys, optional keys)
    "straight": (straight, ("speed",), ("heading_deg", "start", "climb_rate")),
    "circle": (circle, ("radius", "speed"), ("center", "clockwise", "start_angle_deg")),
    "lawnmower": (lawnmower, ("leg_length", "spacing", "speed"),
                  ("harmonics", "start", "depth")),
    "explicit": (explicit, ("F", "H", "z0"), ()),
}


def make_leader(kind: str, params: Mapping[str, Any]) -> LeaderPath:
    """Build a leader path by name from a parameter mapping (e.g. a scenario table).

    Parameters
    ----------
    kind : str
        One of :data:`LEADER_PATHS`.
    params : Mapping[str, Any]
        The keyword arguments of the matching function.

    Returns
    -------
    LeaderPath
        The path.

    Raises
    ------
    ModelError
        If the kind or a parameter is unknown, a required parameter is missing or a value
        is invalid; every message starts with "leader: ".
    """
    if kind not in _BUILDERS:
        raise ModelError(
            f"leader: unknown path {kind!r}; known paths: {', '.join(LEADER_PATHS)}"
        )
    if not isinstance(params, Mapping):
        raise ModelError(f"leader: the {kind} parameters must be a table, got {params!r}")
    build, required, optional = _BUILDERS[kind]
    accepted = required + optional
    unknown = sorted(str(k) for k in params if k not in accepted)
    if unknown:
        raise ModelError(
            f"leader: unknown {kind} parameter(s) {', '.join(unknown)}; "
            f"accepted: {', '.join(accepted)}"
        )
    missing = [k for k in required if k not in params]
    if missing:
        raise ModelError(f"leader: {kind} path needs {', '.join(missing)}")
    try:
        return build(**dict(params))
    except ModelError as exc:
        msg = str(exc)
        raise ModelError(msg if msg.startswith("leader: ") else f"leader: {msg}") from None
