"""Predictions and the monolithic reference of a per-vehicle fleet run.

``centralized``: the stacked law cut by vehicle is the same sampled loop as the stacked
deployment in the protocol form (block-diagonal physics and noise, so the stacked Kalman
filter is the N vehicle filters), and its prediction is the stacked one
(:func:`orchestrator.analysis.prediction.predict_stationary`).

``distributed``: the stacked loop of the per-vehicle pieces
(:func:`orchestrator.analysis.distributed.distributed_closed_loop`) built with the very laws
the controller FMUs solve (:func:`controller_fmu.vehicle_law.vehicle_law`), its stability
verdict per eigenvalue of L + G and its Lyapunov cost prediction
(:mod:`orchestrator.analysis.distributed_verdict`); :func:`distributed_reference` simulates
that loop as one matrix recursion, X[k+1] = Phi X + Gam zeta[k], with each vehicle's noise
drawn from its own stream ([seed, i], :func:`plant_model.per_vehicle.sample_vehicle`): the
FMUs must reproduce it to rounding.
"""
from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

import numpy as np

from controller_fmu.distributed import sampled_observer
from controller_fmu.vehicle_law import observer_start, vehicle_law
from plant_model.per_vehicle import sample_vehicle
from plant_model.plant import NoiseStream

from .distributed import DistributedLoop, distributed_closed_loop, fleet_agents

if TYPE_CHECKING:
    from ..scenario import Scenario

__all__ = ["distributed_loop_of", "distributed_initial_state", "distributed_noise",
           "distributed_reference"]


def distributed_loop_of(sc: Scenario, mode: str, tracking: str, settings: Any) -> DistributedLoop:
    """The stacked sampled loop of a fleet scenario under the distributed law.

    Parameters
    ----------
    sc : Scenario
        A fleet scenario (h, fleet spec, noise convention).
    mode : str
        Estimator mode: ``ideal`` or ``kalman``.
    tracking : str
        ``lq`` or ``regulator``.
    settings : DistributedSettings
        Observer gain mu (1/s), cohesion c, regulator form.

    Returns
    -------
    DistributedLoop
        Phi, Gam, W, Gx, Geta, Ce and the pieces.
    """
    agents, graph, leader = fleet_agents(sc.fleet)
    laws = [vehicle_law(A=a.A, B1=a.B, B2=a.E, C=a.C, K=a.Kw, Q=a.Q, R=a.R, F=leader["F"],
                        H=leader["H"], offset=a.offset, tracking=tracking,
                        regulator=settings.regulator, h=sc.h, where=f"vehicle {i}: ")
            for i, a in enumerate(agents, start=1)]
    obs = sampled_observer(leader["F"], sc.h, settings.mu)
    return distributed_closed_loop(agents, laws, graph, obs, leader["H"],
                                   cohesion=settings.cohesion, estimator=mode,
                                   convention=sc.system.noise_convention)


def distributed_initial_state(sc: Scenario, loop: DistributedLoop) -> np.ndarray:
    """X(0) of the loop as the FMUs start: leader z0, vehicles at x0, w0 (the stacked
    system's), Kalman q(0) = [x0; w0], observers at
    :func:`controller_fmu.vehicle_law.observer_start` (0, or z0 for a planned path: the
    observer error starts and stays at 0, so the loop with the leader's messages is the
    loop without them).

    Parameters
    ----------
    sc : Scenario
        The fleet scenario.
    loop : DistributedLoop
        Its loop (:func:`distributed_loop_of`).

    Returns
    -------
    np.ndarray
        X(0).
    """
    views = sc.fleet.views
    z0 = sc.fleet.leader.z0
    eta0 = observer_start(z0, sc.distributed)
    return loop.initial_state(z0, [v.x0 for v in views], [v.w0 for v in views],
                              [eta0] * len(views))


def distributed_noise(sc: Scenario, seed: int, steps: int) -> np.ndarray:
    """zeta[k] = [nu_1..N; n_1..N] of the loop: each vehicle's process and sensor noise,
    drawn from its own stream ([seed, i], :func:`plant_model.per_vehicle.sample_vehicle`).

    Parameters
    ----------
    sc : Scenario
        The fleet scenario.
    seed : int
        The noise seed.
    steps : int
        Number of samples.

    Returns
    -------
    np.ndarray
        (steps, sum of the vehicles' (n + r) + sum of their s).
    """
    nu, nn = [], []
    for i, view in enumerate(sc.fleet.views, start=1):
        rows = NoiseStream.all_rows(sample_vehicle(view, sc.h, i), seed, steps)
        ns = view.n + view.r
        nu.append(rows[:, :ns])
        nn.append(rows[:, ns:ns + view.p])
    return np.hstack(nu + nn)


def distributed_reference(sc: Scenario, loop: DistributedLoop, seed: int, steps: int,
                          timing: dict[str, float] | None = None) -> dict[str, np.ndarray]:
    """The loop simulated as one recursion with the FMUs' noise: traces x, u, e, eta.

    The step matrices are sparse (each vehicle hears a few others), so this is also the
    monolithic loop the benchmark times.

    Parameters
    ----------
    sc : Scenario
        The fleet scenario.
    loop : DistributedLoop
        Its loop.
    seed : int
        The noise seed (vehicle i draws from [seed, i]).
    steps : int
        Number of samples.
    timing : dict or None, optional
        Receives ``loop_s``, the seconds of the recursion.

    Returns
    -------
    dict[str, np.ndarray]
        ``x`` (steps, N p), ``u`` (steps, N q), ``e`` (steps, N s) and ``eta`` (steps, N l),
        in the stacked layout of :func:`orchestrator.cosim.per_vehicle.stacked_traces`.
    """
    from scipy.sparse import csr_matrix

    zeta = distributed_noise(sc, seed, steps)
    Phi, Gam = csr_matrix(loop.Phi), csr_matrix(loop.Gam)
    X = distributed_initial_state(sc, loop)
    Xs = np.empty((steps, X.size))
    t = time.perf_counter()
    for k in range(steps):
        Xs[k] = X
        X = Phi @ X + Gam @ zeta[k]
    if timing is not None:
        timing["loop_s"] = time.perf_counter() - t
    p = loop.laws[0].Kx.shape[1]
    x = np.hstack([Xs[:, sl][:, :p] for sl in loop.index["s"]])
    eta = np.hstack([Xs[:, sl] for sl in loop.index["eta"]])
    return {"x": x, "u": Xs @ loop.Gx.T + zeta @ loop.Geta.T, "e": Xs @ loop.Ce.T,
            "eta": eta}
