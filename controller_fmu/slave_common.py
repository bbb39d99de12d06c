"""What the controller slaves share: the static-gain law (the stacked LQ law, one vehicle's
rows of it) and the actuator limit every controller applies to its force.

A static law's outputs are computed from the inputs on demand (``compute_outputs``); a
step has nothing to advance, and its native (C) form is a static gain.

**The actuator limit**. Every controller FMU has a parameter
``u_max`` (N, one per force axis, FMI names ``u_max[1]`` ...) and outputs

    u = sat(u_law) = min(max(u_law, -u_max), u_max)      (per axis)

The default :data:`UNLIMITED` (1e300 N) is no limit: the clip is then skipped, and u is
bit for bit the law's. The same ``u`` feeds the vehicle and the vehicle's estimator, so
the estimator's model states (the velocity and the current estimate, the regulator's
internal model of the disturbance) are driven by the force the vehicle was given, not by
the law's wish: they do not wind up while the force is limited. The distributed
observer of the leader (eta) is driven by the neighbours' and the leader's messages only,
never by u, so nothing else in the loop integrates the clipped difference. The native (C)
form clips the same way (the role ``sat``, :func:`clip_roles`).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from fmu_common.interface import ArraySpec
from fmu_common.native_form import NativeForm, Role
from fmu_common.slave_base import ArraySlave

__all__ = ["StaticLawSlave", "UNLIMITED", "clip_roles", "force_limit", "saturate",
           "u_max_spec"]

#: the default actuator limit: no limit (N)
UNLIMITED = 1e300


def saturate(u: np.ndarray, u_max: np.ndarray) -> np.ndarray:
    """sat(u) = min(max(u, -u_max), u_max) per axis (N), a new array.

    Parameters
    ----------
    u : np.ndarray
        The law's force, (m,) or (k, m), N.
    u_max : np.ndarray
        The limit per axis, (m,), N, positive.

    Returns
    -------
    np.ndarray
        The clipped force, the shape of ``u``.
    """
    return np.minimum(np.maximum(u, -u_max), u_max)


def u_max_spec(config: dict[str, Any], m: int) -> ArraySpec:
    """The ``u_max`` parameter (m,) of a controller: ``config["u_max"]`` or no limit."""
    start = np.asarray(config.get("u_max", [UNLIMITED] * m), dtype=float)
    return ArraySpec("u_max", (m,), "parameter", "actuator limit per force axis: the output "
                     f"u is clipped to [-u_max, u_max] (default {UNLIMITED:g}: no limit)",
                     start=start, unit="N", min=0.0)


def force_limit(par: dict[str, Any]) -> np.ndarray | None:
    """The checked ``u_max`` of a slave's parameters; None when no axis is limited.

    Raises
    ------
    ValueError
        Naming the first element u_max[k] that is not positive.
    """
    u_max = np.array(par["u_max"], dtype=float).reshape(-1)
    bad = np.flatnonzero(~(u_max > 0.0))
    if bad.size:
        k = int(bad[0])
        raise ValueError(f"parameter u_max[{k + 1}] = {float(u_max[k])!r} must be a positive "
                         "force in N (the actuator limit)")
    return None if np.all(u_max >= UNLIMITED) else u_max


def clip_roles(limit: np.ndarray | None, row0: int = 0) -> list[Role]:
    """The native form's clip of the force outputs (rows row0.. of y): the role ``sat``
    named ``u_max`` (fmu_common.native_form), none without a limit (today's form).

    Parameters
    ----------
    limit : np.ndarray or None
        u_max per axis (N), as :func:`force_limit` returns it.
    row0 : int, optional
        The first output row of the force u.

    Returns
    -------
    list[Role]
        [] or the one role.
    """
    if limit is None:
        return []
    return [Role("sat", "u_max", limit, "actuator limit per force axis: the output u is "
                 "clipped to [-u_max, u_max]", row0=row0, unit="N")]


class StaticLawSlave(ArraySlave):
    """A memoryless law u = f(inputs): any communication step, nothing to advance."""

    def static_native_form(self, roles: list[Role]) -> NativeForm:
        """This slave's interface as a static native form with ``roles``.

        Parameters
        ----------
        roles : list[Role]
            The form's gains and constants.

        Returns
        -------
        NativeForm
            No internal state, any communication step.
        """
        inputs, outputs = self.io_specs()
        return NativeForm(inputs=inputs, outputs=outputs, nq=0, h=1.0, static=True,
                          description=self.description, roles=roles)

    def advance(self, step: float) -> None:
        """Nothing to do: the law is static.

        Parameters
        ----------
        step : float
            The communication step, s (any step works).
        """
        pass
