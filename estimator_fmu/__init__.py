"""State estimators (Kalman, classical, ideal) and the estimator FMU."""
from .estimators import ESTIMATOR_MODES, LinearEstimator, make_estimator, steady_kalman

__all__ = ["ESTIMATOR_MODES", "LinearEstimator", "make_estimator", "steady_kalman"]
