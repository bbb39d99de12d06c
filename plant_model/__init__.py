"""Plant model: the paper's vehicles, exosystems and sensors, sampled exactly.

The names below are loaded when first used (PEP 562), so importing one submodule (the
.rrd writer's quaternions, an FMU slave's kernel) does not import scipy with
:mod:`.discretization`.
"""
from __future__ import annotations

import importlib
from typing import Any

__all__ = ["DiscreteModel", "discretize", "ModelError", "NoiseStream", "Plant",
           "plant_output_layout", "LinearSystem"]

#: each public name -> the submodule that defines it
_HOME = {"DiscreteModel": ".discretization", "discretize": ".discretization",
         "ModelError": ".linalg_checks", "NoiseStream": ".plant", "Plant": ".plant",
         "plant_output_layout": ".plant", "LinearSystem": ".system"}


def __getattr__(name: str) -> Any:
    if name in _HOME:
        value = getattr(importlib.import_module(_HOME[name], __name__), name)
        globals()[name] = value                   # found directly from now on
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])
