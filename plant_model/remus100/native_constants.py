"""The numbers a native (C) REMUS 100 steps with, derived from a Python plant
(fmu_common/native/remus6dof_model.h, ``RemusConst``): the packed vehicle and gains
(:func:`plant_model.remus100.kernel.pack`, ``pack_gains``), the force interface M (kg),
D (kg/s), the current's transition Aw = exp(K h), the noise factor P (the noise row of
sample k is P xi_k, :func:`plant_model.native_plant.noise_map`), the actuator limits
(rad, rad, rpm), h (s), the RK4 sub-steps and the sensors' periods (steps), standard
deviations and dropout probabilities.

These are what need a matrix exponential or an eigen-decomposition (the sampled model's
Qd, Rd and their symmetric square roots, plant_model.noise_factor); the native FMU gets
them at export, computed here by the same code the pythonfmu FMU runs.
"""
from __future__ import annotations

import ctypes

import numpy as np

from ..native_plant import noise_map
from .plant import ActuatedRemus6dofPlant, Remus6dofPlant

__all__ = ["NOISE_SIZE", "P_SIZE", "RemusConst", "remus_constants"]

#: kernel.pack's vector, at most (P_SX + 21 strips); the noise row's length
P_SIZE = 134
NOISE_SIZE = 15


class RemusConst(ctypes.Structure):
    """ctypes mirror of ``RemusConst`` (remus6dof_model.h)."""

    _fields_ = [("p", ctypes.c_double * P_SIZE), ("g", ctypes.c_double * 12),
                ("M", ctypes.c_double * 3), ("D", ctypes.c_double * 3),
                ("Aw", ctypes.c_double * 9), ("P", ctypes.c_double * NOISE_SIZE ** 2),
                ("limits", ctypes.c_double * 3), ("h", ctypes.c_double),
                ("substeps", ctypes.c_int), ("actuated", ctypes.c_int),
                ("sensors", ctypes.c_int), ("nav_period", ctypes.c_int64 * 3),
                ("nav_sigma", ctypes.c_double * 7), ("nav_drop", ctypes.c_double * 3)]


def remus_constants(plant: Remus6dofPlant) -> dict[str, np.ndarray | float | int]:
    """The fields of ``RemusConst`` for a plant (module docstring).

    Raises
    ------
    ValueError
        If the plant's noise is not one stream of 15 normals per step (a vehicle of the
        per-vehicle deployment) or its vehicle needs more than 21 strips.
    """
    P, streams = noise_map(plant.model)
    if P.shape != (NOISE_SIZE, NOISE_SIZE) or len(streams) != 1 or streams[0][0] is None:
        raise ValueError(f"the native REMUS 100 draws one keyed stream of {NOISE_SIZE} "
                         f"normals per step; this plant's noise has streams {streams}")
    if plant._p.size > P_SIZE:
        raise ValueError(f"the vehicle's parameter vector has {plant._p.size} entries, more "
                         f"than the native model's {P_SIZE}")
    p = np.zeros(P_SIZE)
    p[:plant._p.size] = plant._p
    s = plant.sensors
    return {"p": p, "g": plant._g.copy(), "M": plant._M.copy(), "D": plant._D.copy(),
            "Aw": plant._Aw.reshape(-1).copy(), "P": P.reshape(-1).copy(),
            "limits": plant._limits.copy(), "h": float(plant.model.h),
            "substeps": int(plant.substeps),
            "actuated": int(isinstance(plant, ActuatedRemus6dofPlant)),
            "sensors": int(s is not None),
            "nav_period": (s.steps(plant.model.h) if s is not None else np.ones(3, np.int64)),
            "nav_sigma": s.sigmas if s is not None else np.zeros(7),
            "nav_drop": s.dropouts if s is not None else np.zeros(3)}


def const_struct(values: dict) -> RemusConst:
    """A ``RemusConst`` filled from :func:`remus_constants`'s dict."""
    c = RemusConst()
    for name, ctype in RemusConst._fields_:
        v = values[name]
        if hasattr(ctype, "_length_"):
            getattr(c, name)[:] = [type(getattr(c, name)[0])(x) for x in np.asarray(v).ravel()]
        else:
            setattr(c, name, v)
    return c
