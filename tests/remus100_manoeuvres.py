"""The manoeuvres that compare ``remus100-6dof`` with its published reference, T. I.
Fossen's Python Vehicle Simulator (``vehicles/remus100.py``), defined once for the test
(tests/test_remus100_published.py) and for the script that runs the reference
(tests/make_remus100_reference.py).

Each manoeuvre holds a command [delta_r (rad), delta_s (rad), n (rpm)] for a time; the
turn and the stern step start from the end of the straight run with the position and the
heading reset. Figures: ``speed`` (m/s) and ``roll`` (deg) at the end of the straight run,
``drift`` (m east) and ``depth`` (m) there; ``turn_diameter`` (m, the north extent of
the path over the turn's last 100 s), ``turn_dive_rate`` (m/s) and ``turn_roll`` (deg);
``pitch_1s``, ``pitch_2s``, ``pitch_5s`` (deg) after the stern-plane step.
"""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

#: (name, command, duration s)
STRAIGHT = ("straight", (0.0, 0.0, 1525.0), 150.0)
TURN = ("turn", (math.radians(15.0), 0.0, 1525.0), 200.0)
STERN_STEP = ("stern_step", (0.0, math.radians(10.0), 1525.0), 5.0)

#: a step function: (state x (15) = [eta, nu, delta_r, delta_s, n], command, dt) -> x
Stepper = Callable[[np.ndarray, np.ndarray, float], np.ndarray]


def _run(step: Stepper, x0: np.ndarray, command: tuple, T: float, dt: float) -> np.ndarray:
    x, rows = np.array(x0, float), [np.array(x0, float)]
    cmd = np.array(command, float)
    for _ in range(round(T / dt)):
        x = step(x, cmd, dt)
        rows.append(x.copy())
    return np.array(rows)


def manoeuvre_figures(step: Stepper, dt: float, dt_step: float) -> dict[str, float]:
    """The figures (module docstring) of a vehicle advanced by ``step`` with time steps
    ``dt`` (straight run, turn) and ``dt_step`` (stern step), s."""
    a = _run(step, np.zeros(15), STRAIGHT[1], STRAIGHT[2], dt)
    end = a[-1]
    start = end.copy()
    start[[0, 1, 2, 5]] = 0.0
    b = _run(step, start, TURN[1], TURN[2], dt)
    last = b[-round(100.0 / dt) - 1:]
    c = _run(step, start, STERN_STEP[1], STERN_STEP[2], dt_step)
    figures = {"speed": float(np.linalg.norm(end[6:9])), "roll": math.degrees(end[3]),
               "drift": float(end[1]), "depth": float(end[2]),
               "turn_diameter": float(np.ptp(last[:, 0])),
               "turn_dive_rate": float((last[-1, 2] - last[0, 2]) / 100.0),
               "turn_roll": math.degrees(last[-1, 3])}
    for t in (1, 2, 5):
        figures[f"pitch_{t}s"] = math.degrees(c[round(t / dt_step), 4])
    return figures
