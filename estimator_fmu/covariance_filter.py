"""What the Kalman filters that carry their covariance share (the time-varying filter of
:mod:`estimator_fmu.kalman_tv` and the multi-rate one of :mod:`estimator_fmu.multirate`):
the restart, the time update and their state.

A subclass sets q0, P0, Ad, Bd, Qd and, in its ``estimate``, the filtered covariance
``_P_post`` = P+[k] of the step; then once per step::

    q[k+1] = Ad est[k] + Bd u[k],   P[k+1] = sym(Ad P+[k] Ad' + Qd)   (sym(X) = (X + X')/2)
"""
from __future__ import annotations

import numpy as np

__all__ = ["CovarianceFilter"]


class CovarianceFilter:
    """The restart, time update and state of a filter with a covariance (module docstring)."""

    #: the ``mode`` its serialized state carries
    state_mode: str = ""
    #: how its errors name it
    label: str = "the filter"
    uses_truth = False
    q0: np.ndarray
    P0: np.ndarray
    Ad: np.ndarray
    Bd: np.ndarray
    Qd: np.ndarray

    def reset(self) -> None:
        """Restart from q0, P0."""
        self.q = self.q0.copy()
        self.P = self.P0.copy()
        self._P_post = self.P0.copy()

    def update(self, est: np.ndarray, u: np.ndarray) -> None:
        """q[k+1] = Ad est[k] + Bd u[k];  P[k+1] = sym(Ad P+[k] Ad' + Qd)."""
        q = self.Ad.dot(est)
        q += self.Bd.dot(u)
        self.q = q
        P = self.Ad @ self._P_post @ self.Ad.T + self.Qd
        self.P = 0.5 * (P + P.T)

    def get_state(self) -> dict:
        """q, P and the last filtered covariance (copies)."""
        return {"mode": self.state_mode, "q": self.q.copy(), "P": self.P.copy(),
                "P_post": self._P_post.copy()}

    def set_state(self, state: dict) -> None:
        """Restore :meth:`get_state` (validated first: on error nothing changes)."""
        if state.get("mode") != self.state_mode:
            raise ValueError(f"the estimator state is of mode {state.get('mode')!r}, this "
                             f"estimator is {self.label}")
        q = np.array(state["q"], dtype=float)
        P, Pp = np.array(state["P"], dtype=float), np.array(state["P_post"], dtype=float)
        if q.shape != self.q0.shape or P.shape != self.P0.shape or Pp.shape != P.shape:
            raise ValueError(f"the estimator state does not fit {self.label}")
        self.q, self.P, self._P_post = q, P, Pp
