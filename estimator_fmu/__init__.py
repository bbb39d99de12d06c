"""State estimators (Kalman, classical, ideal) and the estimator FMU."""
from .estimators import LinearEstimator, steady_kalman
from .registry import ESTIMATOR_MODES, make_estimator

__all__ = ["ESTIMATOR_MODES", "LinearEstimator", "make_estimator", "steady_kalman"]
