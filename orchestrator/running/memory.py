"""Will a run fit? Checked before anything is built or written: its traces in memory
(:func:`orchestrator.running.systems.check_memory`) and the time
and memory of the stacked design (:func:`check_design`, estimated from a model calibrated
on this machine: :data:`DESIGN_COST`). A fleet's stacked model is checked when the
scenario is loaded (:func:`orchestrator.scenario.size.check_fleet_model`)."""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from ..scenario.size import MEMORY_SHARE, available_memory, memory_short

if TYPE_CHECKING:
    from ..scenario import Scenario

__all__ = ["ANNOUNCE_S", "DESIGN_COST", "DesignEstimate", "MAX_DESIGN_S", "MEMORY_SHARE",
           "STACKED_DESIGNS", "available_memory", "check_design",
           "design_estimate", "stacked_states"]

# --- the stacked design: one Riccati, Sylvester and Kalman design for the whole system ------

#: seconds per (state^3, state^4) of each phase of the stacked set-up, n = n + r + l the
#: states of the stacked [x; w; z]. Calibrated once on the project's 2-core machine, shared
#: with other jobs as it usually is: grid-N fleets (orchestrator.scenario.generator, N = 20,
#: 30, 40, 50, 60, 80: n = 186 ... 726) timed phase by phase in a fresh process each, then
#: least squares on the relative error (every fit within -30 % / +40 % of the measured
#: times; 320 s in all at n = 726). "design": sampling the model, the Riccati equation (13),
#: the Sylvester equations (14)-(15) and the regulator equations, with their PBH
#: stabilizability test (one SVD of an n x 2n matrix per marginal mode: the n^4 term);
#: "filter": a Kalman filter's (steady or time-varying) PBH detectability test and
#: discrete Riccati equation;
#: "predictions": the Lyapunov equations of the closed loop (about 3n states) and the
#: window's covariance.
DESIGN_COST = {"design": (1.6e-8, 7.5e-11), "filter": (0.0, 6.9e-10),
               "predictions": (1.5e-7, 3.0e-10)}
#: the phases of DESIGN_COST as messages name them
PHASE_NAMES = {"design": "tracking design", "filter": "Kalman filter",
               "predictions": "predictions"}
#: bytes per state^2 the stacked set-up holds at its peak beyond the loaded scenario (the
#: same calibration's maximum resident set: about 90 dense n x n float64 matrices)
DESIGN_BYTES_PER_STATE2 = 90 * 8
#: the longest stacked set-up a command starts, estimated, s
MAX_DESIGN_S = 600.0
#: a step estimated to take longer is announced in one line before it starts, s
ANNOUNCE_S = 2.0
#: who solves one stacked design -> how its refusal starts, and what a fleet too large for
#: it should do instead (a single system is told to be smaller)
STACKED_DESIGNS = {
    "stacked": ("the stacked deployment solves one design for",
                "use --deployment per-vehicle --architecture distributed (each vehicle "
                "designed on its own, independent of N)"),
    "centralized": ("the centralized architecture solves one stacked design for",
                    "use --architecture distributed (designed per vehicle, independent "
                    "of N)"),
}


@dataclass(frozen=True)
class DesignEstimate:
    """What the stacked set-up of a scenario is estimated to cost."""

    states: int            #: n + r + l of the stacked system
    seconds: float         #: estimated time on the calibration machine, s
    bytes: int             #: estimated peak memory beyond the loaded scenario, bytes
    phases: tuple[str, ...]  #: the phases of DESIGN_COST it includes

    def text(self) -> str:
        """``about 320 s and 0.38 GB (estimated)``."""
        t = (f"{self.seconds:.2g} s" if self.seconds < 10 else f"{self.seconds:.0f} s"
             if self.seconds < 1e4 else f"{self.seconds:.3g} s ({self.seconds / 3600:.0f} h)")
        return f"about {t} and {self.bytes / 1e9:.2g} GB (estimated)"


def design_estimate(states: int, kalman: bool = True, predict: bool = True) -> DesignEstimate:
    """The time and memory of the stacked set-up of ``states`` states (DESIGN_COST).

    Parameters
    ----------
    states : int
        n + r + l of the stacked system.
    kalman : bool, optional
        Whether a method runs the steady Kalman filter (the classical and ideal estimators
        solve no Riccati equation).
    predict : bool, optional
        Whether the predictions are computed (``--predict none``: not).

    Returns
    -------
    DesignEstimate
    """
    phases = ("design",) + (("filter",) if kalman else ()) + (("predictions",) if predict
                                                                else ())
    n = float(states)
    seconds = sum(DESIGN_COST[p][0] * n ** 3 + DESIGN_COST[p][1] * n ** 4 for p in phases)
    return DesignEstimate(int(states), seconds, int(DESIGN_BYTES_PER_STATE2 * n * n), phases)


def stacked_states(sc: Scenario) -> int:
    """n + r + l of a scenario's stacked system."""
    return sc.system.n + sc.system.r + sc.system.l


def check_design(sc: Scenario, estimators: Iterable[str], predict: str = "stationary",
                 solver: str = "stacked", available: int | None = None) -> DesignEstimate:
    """Refuse, before it starts, a stacked set-up that would take longer than MAX_DESIGN_S
    or more than MEMORY_SHARE of the memory available (:func:`design_estimate`): the
    stacked deployment's, or the one of the centralized per-vehicle methods.

    Parameters
    ----------
    sc : Scenario
    estimators : iterable of str
        The estimator modes the methods run ('kalman' adds the filter's phase); none: the
        scenario's own.
    predict : str, optional
        The prediction level ('none' leaves the predictions out).
    solver : str, optional
        Who solves the design, a key of :data:`STACKED_DESIGNS` (the message's words).
    available : int, optional
        Bytes available (default :func:`available_memory`).

    Returns
    -------
    DesignEstimate

    Raises
    ------
    ModelError
        One line with the vehicles, the states, the estimate and the limit.
    """
    from estimator_fmu.registry import estimator_kind
    from plant_model.linalg_checks import ModelError
    estimators = list(estimators) or [sc.estimator]
    est = design_estimate(stacked_states(sc), any(estimator_kind(e).solves_riccati
                                                  for e in set(estimators)),
                          predict != "none")
    short = memory_short(est.bytes, available)
    too_slow = est.seconds > MAX_DESIGN_S
    too_big = short is not None
    if too_slow or too_big:
        what = (f"all {sc.fleet.N} vehicles" if sc.fleet is not None
                else "the system")
        limit = (f"more than the {MAX_DESIGN_S:g} s allowed" if too_slow else
                 f"more than {MEMORY_SHARE:.0%} of the {short / 1e9:.3g} GB of memory "
                 "available")
        phases = ", ".join(PHASE_NAMES[p] for p in est.phases)
        who, remedy = STACKED_DESIGNS[solver]
        remedy = remedy if sc.fleet is not None else "a smaller system"
        raise ModelError(f"{who} {what} ({est.states} states; {phases}): "
                         f"{est.text()}, {limit}; {remedy}")
    return est
