"""The expected cost of the distributed loop with the multi-rate Kalman filter of the
navigation sensors (plant_model.navigation, estimator_fmu.multirate): a periodic loop.

Without dropouts the sensors report on a fixed schedule of period P = lcm(n_fix, n_dvl,
n_depth) steps. Each vehicle's filter then converges to a periodic one: at phase
k = 0..P-1 the rows J_k that report, the gain L_k = P_k H_k' (H_k P_k H_k' + R_k)^-1 of
the periodic Riccati recursion P_{k+1} = Ad (I - L_k H_k) P_k Ad' + Qd, computed here
until it repeats. Each phase is then the distributed loop of
:mod:`orchestrator.analysis.distributed` with those rows and gains, Phi_k, Gam_k, W_k
(sensor noise diag(sigma^2) of the rows present), and the second moment is periodic:

    Sigma_{k+1} = Phi_k Sigma_k Phi_k' + Gam_k W_k Gam_k'        (on the random part)
    Sigma_0 = Phi_L Sigma_0 Phi_L' + Q_L,  Phi_L = Phi_{P-1} ... Phi_0  (lifted, one period)

The cost rate is the average over the period of tr(Qc Ce Sigma_k Ce') +
tr(Rc (Gx_k Sigma_k Gx_k' + Geta_k W_k Geta_k')), plus the leader's mean motion over the
statistics window (X[k+1] = Phi_k X[k] from X0), as :func:`orchestrator.analysis.
distributed_verdict.predict_cost` does for the steady loop. The current estimate's bound
(``current_max``) is taken as inactive. With dropouts the gains depend on which reports
were lost: there is no prediction.
"""
from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.linalg import solve_discrete_lyapunov

from estimator_fmu.multirate import navigation_rows, periodic_filter
from plant_model.linalg_checks import ModelError
from plant_model.navigation import NavigationSensors

from .distributed import DistributedLoop, _assemble, fleet_agents
from .distributed_verdict import DistributedPrediction

if TYPE_CHECKING:
    from ..scenario import Scenario

__all__ = ["multirate_reference", "periodic_loop", "predict_multirate_cost"]

#: the largest loop the prediction builds (states); beyond it the summary says so
MAX_STATES = 800
#: the most memory the loop's phases may take (bytes: Phi, Gam and the rows per phase of
#: the sensors' cycle); beyond it the summary says so
MAX_PHASE_BYTES = 1_000_000_000


def periodic_loop(sc: Scenario, base: DistributedLoop, sensors: NavigationSensors
                  ) -> list[dict[str, Any]]:
    """Per phase of the sensors' period the loop's matrices (Phi, Gam, W, Gx, Geta, ...) of
    :func:`orchestrator.analysis.distributed._assemble` with the periodic filter's rows
    and gains (module docstring); the error rows are the vehicles' outputs.

    Raises
    ------
    ModelError
        With dropouts, or a loop over :data:`MAX_STATES`.
    """
    if not sensors.lossless:
        raise ModelError("no prediction with sensor dropouts: the filter's gains depend on "
                         "which reports were lost")
    nX = base.Phi.shape[0]
    if nX > MAX_STATES:
        raise ModelError(f"the periodic loop has {nX} states, more than the {MAX_STATES} "
                         "this prediction builds")
    cycle = math.lcm(*(int(n) for n in sensors.steps(sc.h)))
    need = 16 * cycle * nX * (nX + base.Gam.shape[1])      # Phi, Gam and their row blocks
    if need > MAX_PHASE_BYTES:
        raise ModelError(f"the periodic loop of the sensors' {cycle}-step cycle ({nX} states "
                         f"per phase) needs about {need / 1e9:.3g} GB, more than the "
                         f"{MAX_PHASE_BYTES / 1e9:g} GB this prediction builds")
    agents, graph, leader = fleet_agents(sc.fleet)
    g = np.diag(graph.pinning_matrix()).copy()
    n, r = agents[0].A.shape[0], agents[0].Kw.shape[0]
    cache: dict[bytes, list] = {}            # identical vehicles share one filter
    schedules = []
    for sa in base.sampled:
        key = sa.Ad.tobytes() + sa.Qd.tobytes()
        if key not in cache:
            cache[key] = periodic_filter(sa.Ad, sa.Qd, sensors, sc.h, n, r)
        schedules.append(cache[key][0])
    H_all = navigation_rows(n, r)
    phases = []
    for k in range(len(schedules[0])):
        sampled = [replace(sa, M=H_all[sched[k][0]], L=sched[k][1], Rd=sched[k][2])
                   for sa, sched in zip(base.sampled, schedules)]
        ph = _assemble(sampled, base.laws, base.LG, g, base.observer,
                       np.asarray(leader["H"], float), [a.offset for a in agents],
                       base.cohesion, True, [sa.M for sa in base.sampled])
        phases.append(dict(ph, rows=schedules[0][k][0]))
    return phases


def multirate_reference(sc: Scenario, base: DistributedLoop, sensors: NavigationSensors,
                        seed: int, steps: int) -> dict[str, np.ndarray]:
    """The periodic loop simulated as one recursion with the FMUs' noise: the vehicles'
    process noise from their streams [seed, i], the sensors' from theirs
    [seed, 3000000 + i] (plant_model.navigation); traces x, u, e as
    :func:`orchestrator.analysis.per_vehicle.distributed_reference`."""
    from plant_model.navigation import SensorStream

    from .per_vehicle import distributed_initial_state, distributed_noise
    phases = periodic_loop(sc, base, sensors)
    N = len(base.sampled)
    ns = base.sampled[0].Ad.shape[0]
    nu = distributed_noise(sc, seed, steps)[:, :N * ns]
    draws = []
    for i in range(1, N + 1):
        stream = SensorStream(sensors, sc.h, seed, i)
        draws.append(np.array([stream._next()[0].copy() for _ in range(steps)]))
    sig = sensors.sigmas
    X = distributed_initial_state(sc, base)
    xs, us, es = [], [], []
    p = base.laws[0].Kx.shape[1]
    for k in range(steps):
        ph = phases[k % len(phases)]
        J = ph["rows"]
        zeta = np.concatenate([nu[k]] + [sig[J] * d[k][J] for d in draws])
        xs.append(np.concatenate([X[sl][:p] for sl in base.index["s"]]))
        us.append(ph["Gx"] @ X + ph["Geta"] @ zeta)
        es.append(base.Ce @ X)
        X = ph["Phi"] @ X + ph["Gam"] @ zeta
    return {"x": np.array(xs), "u": np.array(us), "e": np.array(es)}


def predict_multirate_cost(sc: Scenario, base: DistributedLoop, sensors: NavigationSensors,
                           window: tuple[int, int] | None = None,
                           X0: np.ndarray | None = None) -> DistributedPrediction:
    """The periodic loop's stationary cost rate, and with ``window`` and ``X0`` the mean
    motion over the window (module docstring).

    Parameters
    ----------
    sc : Scenario
        The fleet scenario (its fleet spec, h).
    base : DistributedLoop
        The steady loop of the same fleet, law and settings (kalman): its laws, observer,
        graph, error rows and weights.
    sensors : NavigationSensors
        The sensors; every dropout must be 0.
    window, X0 : optional
        As :func:`orchestrator.analysis.distributed_verdict.predict_cost`.

    Raises
    ------
    ModelError
        With dropouts, a loop over :data:`MAX_STATES`, or a periodic loop that is not stable.
    """
    phases = periodic_loop(sc, base, sensors)
    R = ~base.deterministic
    PhiL = np.eye(int(R.sum()))
    QL = np.zeros_like(PhiL)
    for ph in phases:
        PhiR, GamR = ph["Phi"][np.ix_(R, R)], ph["Gam"][R]
        PhiL = PhiR @ PhiL
        QL = PhiR @ QL @ PhiR.T + GamR @ ph["W"] @ GamR.T
    rho_L = float(np.max(np.abs(np.linalg.eigvals(PhiL)))) if PhiL.size else 0.0
    if rho_L >= 1.0:
        raise ModelError(f"the periodic loop with [sensors] is not stable (spectral radius "
                         f"{rho_L:.6g} over one period)")
    S = solve_discrete_lyapunov(PhiL, QL)
    See = np.zeros((base.Ce.shape[0],) * 2)
    Suu = np.zeros((base.Gx.shape[0],) * 2)
    Sigma = np.zeros_like(base.Phi)
    for ph in phases:
        Sigma[np.ix_(R, R)] = S
        See += base.Ce @ Sigma @ base.Ce.T
        Suu += ph["Gx"] @ Sigma @ ph["Gx"].T + ph["Geta"] @ ph["W"] @ ph["Geta"].T
        PhiR, GamR = ph["Phi"][np.ix_(R, R)], ph["Gam"][R]
        S = PhiR @ S @ PhiR.T + GamR @ ph["W"] @ GamR.T
    See, Suu = See / len(phases), Suu / len(phases)
    if window is not None and X0 is not None:
        k0, K = window
        X = np.asarray(X0, dtype=float)
        ee, uu = np.zeros_like(See), np.zeros_like(Suu)
        for k in range(K):
            ph = phases[k % len(phases)]
            if k >= k0:
                e, u = base.Ce @ X, ph["Gx"] @ X
                ee += np.outer(e, e)
                uu += np.outer(u, u)
            X = ph["Phi"] @ X
        See, Suu = See + ee / max(K - k0, 1), Suu + uu / max(K - k0, 1)
    rho = rho_L ** (1.0 / len(phases)) if rho_L > 0 else 0.0
    tau = -sc.h / math.log(rho) if 0 < rho < 1 else sc.h
    cost = float(np.trace(base.Qc @ See) + np.trace(base.Rc @ Suu))
    return DistributedPrediction(rms_e=np.sqrt(np.clip(np.diag(See), 0, None)).tolist(),
                                 rms_u=np.sqrt(np.clip(np.diag(Suu), 0, None)).tolist(),
                                 cost_rate=cost, spectral_radius=rho, settling_time=5 * tau)
