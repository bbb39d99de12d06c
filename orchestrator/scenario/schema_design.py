"""The [design] section of a fleet scenario (docs/design.md): the cost weight chosen from
the vehicle, the controllers' force limit and the path check. Checked here: types, ranges
and the form of u_max; the search, the limits and the path check run in the loader
(:func:`orchestrator.analysis.weight_search.design_fleet`), which names [design] in its
errors too.
"""
from __future__ import annotations

from typing import Annotated, Any, Literal

import numpy as np
from annotated_types import Gt, Le
from pydantic import AllowInfNan, field_validator

from .errors import bad_value
from .schema import Section, expect, one_of

__all__ = ["DesignSection", "PATH_CHECKS"]

#: what [design] path_check does with a target path the vehicle cannot fly
PATH_CHECKS = ("warn", "refuse", "off")

PositiveFinite = Annotated[float, Gt(0.0), AllowInfNan(False)]


class DesignSection(Section):
    """[design]: the cost weight from the vehicle, its actuator limit and the path check
    (orchestrator.analysis.weight_search). ``bandwidth`` (rad/s, or "vehicle": the band
    where the nonlinear vehicle responds like its design model) and/or ``force_budget``
    (the predicted 3-sigma force as a fraction of the vehicle's maximum force, 0 < b <= 1)
    choose R = r I; ``u_max`` the controllers' force limit (N: a number, one per axis, or
    "vehicle": derived from the vehicle; absent: no limit); ``path_check`` "warn",
    "refuse" or "off"; ``max_speed`` (m/s), ``min_turn_radius`` (m), ``max_depth_rate``
    (m/s) override or give the vehicle's limits."""

    bandwidth: Annotated[PositiveFinite | Literal["vehicle"] | None,
                         expect("must be a positive number of rad/s or \"vehicle\"")] = None
    force_budget: Annotated[float | None, Gt(0.0), Le(1.0), AllowInfNan(False),
                            expect("must be a fraction of the maximum force in (0, 1]")] = None
    u_max: Any = None
    path_check: Annotated[str, one_of(PATH_CHECKS)] = "warn"
    max_speed: Annotated[PositiveFinite | None, expect("must be a positive speed in m/s")] = None
    min_turn_radius: Annotated[PositiveFinite | None,
                               expect("must be a positive radius in m")] = None
    max_depth_rate: Annotated[PositiveFinite | None,
                              expect("must be a positive speed in m/s")] = None

    @field_validator("u_max")
    @classmethod
    def is_a_force(cls, value: Any) -> Any:
        """u_max is "vehicle", a positive number or a list of positive numbers (N)."""
        if value == "vehicle":
            return value
        ok = not isinstance(value, (bool, str)) and not (
            isinstance(value, list) and any(isinstance(v, (bool, str)) for v in value))
        if ok:
            try:
                arr = np.asarray(value, dtype=float)
                ok = arr.ndim <= 1 and arr.size > 0 and bool(np.all(np.isfinite(arr))) \
                    and bool(np.all(arr > 0))
            except (TypeError, ValueError):
                ok = False
        if not ok:
            raise bad_value("must be \"vehicle\", a positive force in N or one per axis")
        return value

    @property
    def chooses_weight(self) -> bool:
        """A bandwidth or a force budget is given: the search sets R."""
        return self.bandwidth is not None or self.force_budget is not None


