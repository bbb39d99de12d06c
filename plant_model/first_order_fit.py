"""The first-order frequency-response fit of a vehicle behind a force interface, as plain
numpy functions (no FMI, no vehicle): used on the nonlinear REMUS 100
(:mod:`orchestrator.analysis.remus_response`, ``remus100-fitted``) and on a vehicle the user
brings as an FMU (:mod:`plant_model.vehicle_fmu_identification`).

Per NED axis the design model is M v' = u - D v (M kg, D kg/s, u the force in N, v the
velocity in m/s), whose velocity per force at frequency w (rad/s) is

    G_f(jw) = 1 / (D + j w M)                                          (m/s per N)

A measured response G (from a sinusoidal force A sin(w t): the velocity's components in
v = c + a sin(w t) + b cos(w t) by least squares, G = (a + j b) / A,
:func:`sine_response`) is fitted in
relative error, sum_k |G_k - G_f,k|^2 / |G_k|^2 = sum_k |1/G_k - (D + j w_k M)|^2 /
|D + j w_k M|^2, by Sanathanan-Koerner iteration: linear least squares on the inverse
response, each pass weighted by the previous pass's 1 / |D + j w M|.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["FIT_OMEGAS", "fit_errors", "fit_first_order_response", "sine_response"]

#: the frequencies the first-order fit uses, rad/s: periods from 21 s to 5 minutes
FIT_OMEGAS = tuple(float(w) for w in np.geomspace(0.02, 0.3, 8))


def sine_response(t: np.ndarray, v: np.ndarray, omega: float, amplitude: float) -> complex:
    """The complex response (m/s per N) of a velocity trace to a force A sin(w t).

    v (m/s) is fitted by least squares to c + a sin(w t) + b cos(w t) over the samples
    given; the response is (a + j b) / A, whose modulus is the gain and whose argument
    atan2(b, a) the phase (rad; negative: the velocity lags the force).

    Parameters
    ----------
    t, v : np.ndarray
        Sample times (s) and velocities (m/s), whole periods after the transient.
    omega : float
        The force's frequency, rad/s.
    amplitude : float
        The force's amplitude A, N.
    """
    X = np.column_stack([np.ones(len(t)), np.sin(omega * t), np.cos(omega * t)])
    _, a, b = np.linalg.lstsq(X, v, rcond=None)[0]
    return complex(a, b) / amplitude


def fit_first_order_response(omegas: np.ndarray, G: np.ndarray,
                             passes: int = 20) -> tuple[float, float]:
    """(M, D): the first-order model 1 / (D + j w M) (kg, kg/s) closest to the responses
    G (m/s per N) at ``omegas`` (rad/s) in relative error (module docstring)."""
    om = np.asarray(omegas, float)
    inv = 1.0 / np.asarray(G, complex)
    weight = np.ones(len(om))
    M = D = math.nan
    for _ in range(passes):
        rows = np.zeros((2 * len(om), 2))
        rows[0::2, 0] = weight
        rows[1::2, 1] = weight * om
        rhs = np.empty(2 * len(om))
        rhs[0::2], rhs[1::2] = weight * inv.real, weight * inv.imag
        (D, M), *_ = np.linalg.lstsq(rows, rhs, rcond=None)
        weight = 1.0 / np.abs(D + 1j * om * M)
    return float(M), float(D)


def fit_errors(omegas: np.ndarray, G: np.ndarray, M: float, D: float) -> np.ndarray:
    """|G - G_f| / |G| at each frequency: the relative error of the fitted model."""
    G = np.asarray(G, complex)
    return np.abs(G - 1.0 / (D + 1j * np.asarray(omegas, float) * M)) / np.abs(G)
