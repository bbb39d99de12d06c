"""State estimators (Kalman, classical, ideal) and the estimator FMU."""
from .estimators import LinearEstimator, make_estimator, steady_kalman
from .registry import ESTIMATOR_MODES

__all__ = ["ESTIMATOR_MODES", "LinearEstimator", "make_estimator", "steady_kalman"]
