"""Driving one FMU instance by hand in a test: opening it at t = 0, stepping it until a step
is refused, saving and restoring its state."""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
from fmpy import extract

from orchestrator.cosim.instance import FmuInstance

#: fmi2OK
OK = 0


def open_initializing(path: Path, folder: Path, name: str = "probe", label: str | None = None,
                      **parameters: float) -> FmuInstance:
    """An instance ``name`` of the FMU at ``path`` (extracted into ``folder / name``), its
    experiment set up at t = 0 and in initialization mode, the Real ``parameters`` set;
    ``label`` names it in errors (default ``name``)."""
    inst = FmuInstance(label or name, path, extract(str(path), unzipdir=str(folder / name)),
                       name)
    s = inst.slave
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    if parameters:
        s.setReal([inst.vr[k] for k in parameters], list(parameters.values()))
    return inst


def steps_until_refused(step: Callable[[float], int], h: float, limit: int) -> tuple[int, int]:
    """Step at t = k h from k = 0 while the steps return fmi2OK, ``limit`` steps at most:
    the number of steps taken (the refused one included) and the last status."""
    k, status = 0, OK
    while status == OK and k < limit:
        status = step(k * h)
        k += 1
    return k, status


def assert_state_round_trip(inst: FmuInstance, drive: Callable[..., np.ndarray],
                            inputs: np.ndarray, k: int) -> np.ndarray:
    """Drive ``inst`` over ``inputs[:k]``, save its state, and check that the rest of the
    inputs give the same outputs again after fmi2SetFMUState, and after the state is
    serialized and read back; ``drive(inst, inputs, k0)`` returns the outputs of each step.
    Returns those outputs (the state is freed)."""
    drive(inst, inputs[:k], 0)
    state = inst.slave.getFMUState()
    first = drive(inst, inputs[k:], k)
    inst.slave.setFMUState(state)
    assert np.array_equal(drive(inst, inputs[k:], k), first)
    blob = inst.slave.serializeFMUState(state)
    inst.slave.setFMUState(inst.slave.deserializeFMUState(blob))
    assert np.array_equal(drive(inst, inputs[k:], k), first)
    inst.slave.freeFMUState(state)
    return first
