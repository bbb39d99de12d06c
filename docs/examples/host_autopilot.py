"""Example host: its own vehicle (torpedo.py) under the exported FMUs, with fmpy only.

    position fix -> AuvVehicleEstimator -> AuvVehicleController -> AuvGuidance
                 -> AuvAutopilot -> the torpedo's rpm, rudder and stern planes

The FMUs come from ``auv-cosim export osp --scenario docs/examples/straight-leader.toml``
(their start values are that scenario's: one vehicle 10 m behind a leader flying north at
2 m/s, 20 m deep, from [0, 0, 20] m). Nothing of the auv-cosim project is imported here.
Run: ``python host_autopilot.py <folder of the exported FMUs>``.
"""
import json
import os
import sys
from collections.abc import Callable, Sequence

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from torpedo import Torpedo

Io = Callable[..., list[float] | None]       # get(names) / set(names, values) by name


# --- glue (the lines the docs count) --------------------------------------------------------
def vec(name: str, n: int) -> list[str]:
    return [f"{name}[{i}]" for i in range(1, n + 1)]


SETPOINTS = ["speed", "course", "depth", "speed_rate", "course_rate", "depth_rate"]
SENSORS = vec("velocity", 3) + vec("attitude", 3) + vec("rates", 3) + ["measured_depth"]


# load: one FMU, instantiated and initialized with parameter values ``start``; returns a
# function that gets (names) or sets (names, values) its variables by name, and the FMU
def load(path: str, **start: float) -> tuple[Io, FMU2Slave]:
    md = read_model_description(path)
    f = FMU2Slave(guid=md.guid, unzipDirectory=extract(path), instanceName=md.modelName,
                  modelIdentifier=md.coSimulation.modelIdentifier)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    f.instantiate(), f.setupExperiment(startTime=0.0), f.enterInitializationMode()
    f.setReal([vr[k] for k in start], list(start.values())), f.exitInitializationMode()
    return lambda names, x=None: (f.getReal([vr[n] for n in names]) if x is None
                                  else f.setReal([vr[n] for n in names], list(x))), f


def run(fmus: str, T: float = 200.0, h: float = 0.05) -> np.ndarray:
    """Fly the torpedo for T s; its true NED positions (m) at t = 0, h, 2h, ..."""
    car = Torpedo([-15.0, -5.0, 22.0], [1.9, 0.05, 0.0], current=[0.1, -0.05, 0.0])
    (est, fe), (ctl, fc), (gd, fg) = (load(f"{fmus}/{name}.fmu") for name in (
        "AuvVehicleEstimator", "AuvVehicleController", "AuvGuidance"))
    ap, fa = load(f"{fmus}/AuvAutopilot.fmu", delta_max=car.delta_max, n_max=car.n_max)
    path: list[Sequence[float]] = []
    for k in range(round(T / h)):
        est(vec("y", 3), car.fix())                               # position fix
        ctl(vec("z", 6), ctl(vec("eta", 6)))      # planned path: its observer is the leader
        ctl(vec("xhat", 6) + vec("what", 3), est(vec("xhat", 6) + vec("what", 3)))
        est(vec("u", 3), u := ctl(vec("u", 3))), gd(vec("u", 3), u)  # the NED force, N
        ap(SETPOINTS, gd(SETPOINTS)), ap(SENSORS, car.sensors())  # set-points, measurements
        path.append(car.position)
        car.step(ap(["rudder", "stern", "rpm"]), h)
        for f in (fe, fc, fg, fa):
            f.doStep(currentCommunicationPoint=k * h, communicationStepSize=h)
    return np.array(path)
# --- end of glue ---------------------------------------------------------------------------


if __name__ == "__main__":
    p = run(sys.argv[1])
    t = 0.05 * np.arange(len(p))
    err = np.linalg.norm(p - np.column_stack([2.0 * t - 10.0, 0 * t, 20.0 + 0 * t]), axis=1)
    late = err[t >= 100.0]
    print(json.dumps({"max_error_after_100s": late.max(), "rms_error_after_100s":
                      float(np.sqrt(np.mean(late ** 2))), "steps": len(p)}), flush=True)
    # pythonfmu 0.7 FMUs can corrupt the heap at interpreter teardown (upstream issue #228,
    # "free(): corrupted unsorted chunks"); leave without it, as auv-cosim's own CLI does
    os._exit(0)
