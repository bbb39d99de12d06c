"""The multi-rate Kalman filter (estimator_fmu.multirate) against scipy's Riccati solution
and its own covariance, on the linear REMUS vehicle with navigation sensors."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

from estimator_fmu.multirate import MultiRateKalman, navigation_rows
from orchestrator.scenario import load_scenario
from plant_model.navigation import NAV_SIZE, NavigationSensors, SensedVehicle
from plant_model.per_vehicle import sample_vehicle
from plant_model.plant import Plant


@pytest.fixture(scope="module")
def vehicle():
    view = load_scenario("formation-4").fleet.views[1]
    return view, sample_vehicle(view, 0.01, 2)


def _loop(view, model, sensors, steps, seed=5, current_max=1.0):
    nav = np.zeros(NAV_SIZE)
    plant = SensedVehicle(Plant(model, np.concatenate([view.x0, view.w0]), seed), sensors, nav)
    kf = MultiRateKalman(model, sensors, np.concatenate([view.x0, view.w0]))
    rng = np.random.default_rng(seed)
    errs, covs = [], []
    for _ in range(steps):
        est = kf.estimate(np.concatenate([nav, np.zeros(9)]))
        errs.append(plant.s - est)
        covs.append(kf._P_post.copy())
        u = rng.normal(scale=10.0, size=3)
        kf.update(est, u)
        plant.step(u)
    return np.array(errs), np.array(covs), kf


@pytest.mark.slow
def test_with_every_sensor_every_step_the_gain_is_the_riccati_one(vehicle):
    """The filter's covariance after 5,000 steps is scipy's Riccati solution to 1e-9 of its
    scale (measured: 7e-11 after 1,000 steps, 3.3e-13 from 4,000 steps on, as after
    30,000)."""
    view, model = vehicle
    s = NavigationSensors(fix_period=0.01, dvl_period=0.01, depth_period=0.01,
                          fix_dropout=0.0, dvl_dropout=0.0, depth_dropout=0.0)
    _, _, kf = _loop(view, model, s, 5_000)
    H = navigation_rows(6, 3)
    P = solve_discrete_are(model.Ad.T, H.T, model.Qd, kf.R)
    assert np.abs(kf.P - P).max() < 1e-9 * np.abs(P).max()


def test_the_filter_believes_its_own_covariance(vehicle):
    """NEES: the estimation error against P+ averaged over the run is the state size (9)
    within its sampling spread, with fixes every 2 s, DVL at 5 Hz, dropouts."""
    view, model = vehicle
    errs, covs, _ = _loop(view, model, NavigationSensors(current_max=100.0), 40_000)
    k = np.arange(2000, len(errs))
    nees = np.array([e @ np.linalg.solve(P, e) for e, P in zip(errs[k], covs[k])])
    # correlated samples: compare the mean over 10 long blocks with its spread
    blocks = nees.reshape(10, -1).mean(axis=1)
    assert abs(blocks.mean() - 9.0) < 4 * blocks.std(ddof=1) / np.sqrt(10) + 0.5
    assert 6.0 < blocks.mean() < 12.0


def test_the_current_estimate_is_bounded(vehicle):
    """A vehicle that does not move as the model says: the current stays within current_max."""
    view, model = vehicle
    s = NavigationSensors(current_max=0.5)
    kf = MultiRateKalman(model, s, np.concatenate([view.x0, view.w0]))
    nav = np.zeros(NAV_SIZE + 9)
    nav[7:10] = 1.0
    for _ in range(2000):          # a huge push, and the vehicle measured standing still
        est = kf.estimate(nav)
        kf.update(est, np.array([500.0, 0.0, 0.0]))
    assert np.abs(est[6:9]).max() == pytest.approx(0.5)
    state = kf.get_state()
    again = kf.estimate(nav)
    kf.set_state(state)
    assert np.array_equal(again, kf.estimate(nav))
