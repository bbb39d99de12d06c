"""What the static-gain controller slaves share (the stacked LQ law, one vehicle's rows of it).

A static law's outputs are computed from the inputs on demand (``compute_outputs``); a
step has nothing to advance, and its native (C) form is a static gain.
"""
from __future__ import annotations

from fmu_common.native_form import NativeForm, Role
from fmu_common.slave_base import ArraySlave

__all__ = ["StaticLawSlave"]


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
