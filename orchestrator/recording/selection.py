"""Which outputs a recording holds: the groups ``--record`` chooses from, one table per
layout (the paper's per-component layout and the fleet's), each group the trace keys its
entities are drawn from and the entities it writes (docs/recording.md lists them).

A recording of a selection holds the entities of the chosen groups only, and its default
blueprint only their views; the statistics and summary.json are computed from every output
at every step whatever is recorded (libcosim's observers and fmpy's ``output=`` choose
variables the same way: what is logged, not what is simulated).
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

__all__ = ["FLEET_GROUPS", "LINK_KEYS", "PAPER_GROUPS", "Selection"]

#: the per-link traces of a fleet over acoustic links (age of information, s; messages
#: delivered, lost, in flight)
LINK_KEYS = ("link_age", "link_delivered", "link_lost", "link_in_flight")

#: the paper layout's groups: name (the entity root) -> (trace keys, what it holds)
PAPER_GROUPS: dict[str, tuple[tuple[str, ...], str]] = {
    "error": (("e",), "tracking error e (error/i)"),
    "state": (("x", "xhat"), "state x and its estimate (state/i)"),
    "control": (("u",), "control u (control/i)"),
    "disturbance": (("w", "what"), "disturbance w and its estimate (disturbance/i)"),
    "reference": (("z", "zhat"), "reference z and its estimate (reference/i)"),
    "measurement": (("y", "ybar"), "measurements y and ybar (measurement/*)"),
}

#: the fleet layout's groups: name -> (trace keys, what it holds)
FLEET_GROUPS: dict[str, tuple[tuple[str, ...], str]] = {
    "error": (("e",), "each vehicle's tracking error (vehicles/i/error)"),
    "control": (("u",), "each vehicle's control (vehicles/i/control)"),
    "state": (("x", "xhat"), "each vehicle's state and estimate (vehicles/i/state)"),
    "current": (("w", "what"), "each vehicle's current and estimate (vehicles/i/current)"),
    "leader": (("z",), "the leader's position (leader/m)"),
    "scene": (("x", "z", "attitude"), "the 3D scene: vehicles, leader, targets, edges, "
              "trails (world/m)"),
    "actuators": (("rpm", "rudder", "stern", "saturated"), "the nonlinear vehicles' "
                  "propeller, fins, saturation and limits (vehicles/i/propeller, ...)"),
    "setpoint": (("setpoint",), "the guidance set-points (vehicles/i/setpoint)"),
    "links": (LINK_KEYS, "the acoustic links' counts and ages (network/links, "
              "vehicles/i/network)"),
}


@dataclass(frozen=True)
class Selection:
    """The groups a recording holds (``groups`` None: every group of its layout).

    Parameters
    ----------
    fleet : bool
        The fleet layout's groups (:data:`FLEET_GROUPS`), else the paper's
        (:data:`PAPER_GROUPS`).
    groups : frozenset[str] or None
        The chosen groups, None for all.
    """

    fleet: bool
    groups: frozenset[str] | None = None

    @classmethod
    def of(cls, fleet: bool, names: Iterable[str] | None) -> Selection:
        """The selection of ``names`` (None: everything), each checked against the layout.

        Raises
        ------
        ValueError
            One line naming the first unknown group and the layout's groups.
        """
        if names is None:
            return cls(bool(fleet))
        table = FLEET_GROUPS if fleet else PAPER_GROUPS
        chosen = [str(n).strip() for n in names]
        if not chosen or any(not n for n in chosen):
            raise ValueError(f"record: name at least one group, separated by commas "
                             f"({', '.join(table)})")
        for name in chosen:
            if name not in table:
                raise ValueError(f"record: {name!r} is not a group of the "
                                 f"{'fleet' if fleet else 'paper'} layout "
                                 f"({', '.join(table)})")
        return cls(bool(fleet), frozenset(chosen))

    @property
    def table(self) -> dict[str, tuple[tuple[str, ...], str]]:
        """The layout's groups."""
        return FLEET_GROUPS if self.fleet else PAPER_GROUPS

    def has(self, group: str) -> bool:
        """Whether ``group`` is recorded."""
        return self.groups is None or group in self.groups

    def keys(self) -> frozenset[str]:
        """The trace keys the recorded groups are drawn from."""
        return frozenset(k for g, (keys, _) in self.table.items() if self.has(g) for k in keys)

    def names(self) -> list[str]:
        """The recorded groups, in the layout's order."""
        return [g for g in self.table if self.has(g)]
