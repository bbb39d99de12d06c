"""Example host with its own autopilot: it takes only AuvGuidance's set-points.

    position fix -> AuvVehicleEstimator -> AuvVehicleController -> AuvGuidance
                 -> the host's PID speed/heading/depth autopilot (torpedo.PidAutopilot)
                 -> the torpedo's rpm, rudder and stern planes

Same FMUs and vehicle as host_autopilot.py, whose ``load`` and ``vec`` this reuses (fmpy
only; nothing of the auv-cosim project is imported). Run: ``python host_pid.py <folder>``.
"""
import json
import os
import sys
from collections.abc import Sequence

import numpy as np
from host_autopilot import load, vec
from torpedo import PidAutopilot, Torpedo


# --- glue (the lines the docs count) --------------------------------------------------------
def run(fmus: str, T: float = 200.0, h: float = 0.05) -> np.ndarray:
    """Fly the torpedo for T s; its true NED positions (m) at t = 0, h, 2h, ..."""
    car, pid = Torpedo([-15.0, -5.0, 22.0], [1.9, 0.05, 0.0], [0.1, -0.05, 0.0]), PidAutopilot()
    (est, fe), (ctl, fc), (gd, fg) = (load(f"{fmus}/{name}.fmu") for name in (
        "AuvVehicleEstimator", "AuvVehicleController", "AuvGuidance"))
    path: list[Sequence[float]] = []
    for k in range(round(T / h)):
        est(vec("y", 3), car.fix())
        ctl(vec("z", 6), ctl(vec("eta", 6)))
        ctl(vec("xhat", 6) + vec("what", 3), est(vec("xhat", 6) + vec("what", 3)))
        est(vec("u", 3), u := ctl(vec("u", 3))), gd(vec("u", 3), u)  # the NED force, N
        path.append(car.position)
        car.step(pid.command(gd(["speed", "course", "depth"]), car.sensors(), h), h)
        for f in (fe, fc, fg):
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
