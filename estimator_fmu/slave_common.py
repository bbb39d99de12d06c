"""What the two estimator slaves share: est = estimate(mvec) on demand, q advanced per step.

A slave sets, in ``setup``, ``self.estimator`` (an
:class:`estimator_fmu.estimators.LinearEstimator`), ``self._mvec`` (the view of its input
buffer holding the measurement vector) and ``self._u`` (the applied input); its outputs are
the estimate, in the estimator's order.
"""
from __future__ import annotations

from fmu_common.slave_base import DelegatedStateSlave

__all__ = ["EstimatorSlave"]


class EstimatorSlave(DelegatedStateSlave):
    """est[k] = Ce q[k] + Dm mvec[k] (direct feedthrough), q[k+1] = Aq est[k] + Bu u[k]."""

    math_name = "estimator"
    evolving_name = "q"

    def compute_outputs(self) -> None:
        """est[k] = Ce q[k] + Dm mvec[k] into the output buffer."""
        self.estimator.estimate(self._mvec, out=self._out)

    def advance(self, step: float) -> None:
        """One sample period: q[k+1] = Aq est[k] + Bu u[k].

        Parameters
        ----------
        step : float
            The communication step, s (checked against h by the base class).
        """
        self.estimator.update(self._outputs_view(self._out), self._u)
