"""The sampled plant as a native FMU's linear form (fmu_common.native_form).

With s = [x; w; z] the state and xi = [xi_v; xi_m] standard normals (ns + 2p per step):

    out[k]  = [M s + Lr xi_m; s; E s]      (selected rows: y, ybar, x, w, z, e or a subset)
    s[k+1]  = Ad s + Bd u + Lq xi_v

with Lq Lq' = Qd and Lr Lr' = Rd (plant_model.plant; the covariances are the same, the
draws are the native generator's, not numpy's). Units: s in m, m/s and the exosystems'
units; u in N.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fmu_common.interface import ArraySpec
from fmu_common.native_form import NativeForm, Role

from .discretization import DiscreteModel
from .linalg_checks import psd_factor

__all__ = ["plant_native_form"]


def plant_native_form(model: DiscreteModel, s0: np.ndarray, rows: Sequence[int],
                      inputs: list[ArraySpec], outputs: list[ArraySpec], *, seed: int,
                      stream: int, description: str) -> NativeForm:
    """A sampled plant as y = Cq s + Lr xi_m (selected rows), s+ = Ad s + Bd u + Lq xi_v.

    Parameters
    ----------
    model : DiscreteModel
        The sampled model.
    s0 : np.ndarray
        Initial state [x0; w0; z0].
    rows : Sequence[int]
        The FMU's outputs as rows of the plant's output [y; ybar; x; w; z; e]
        (:func:`plant_model.plant.plant_output_layout`).
    inputs, outputs : list[ArraySpec]
        The pythonfmu slave's input (u) and output arrays.
    seed, stream : int
        The native generator's keys.
    description : str
        Of the FMU.

    Returns
    -------
    NativeForm
        Roles Ad, Bd, Lq (F), Cq (C), Lr (G), s0 (q0).
    """
    ns, p2 = model.ns, 2 * model.p
    full = np.vstack([model.M, np.eye(ns), model.E])
    rows = np.asarray(rows, dtype=int)
    Lr_full = np.zeros((full.shape[0], p2))
    Lr_full[:p2] = psd_factor(model.Rd) if p2 else Lr_full[:p2]
    G = Lr_full[rows]
    used = np.flatnonzero(np.any(G != 0.0, axis=1))
    roles = [
        Role("A", "Ad", model.Ad, "state transition over one step: s+ = Ad s + Bd u + Lq xi_v"),
        Role("B", "Bd", model.Bd, "input matrix over one step (u held)"),
        Role("F", "Lq", psd_factor(model.Qd), "process noise factor, Lq Lq' = Qd"),
        Role("C", "Cq", full[rows], "outputs from the state (measurements, truth, error)"),
        Role("q0", "s0", s0, "initial state s(0) = [x0; w0; z0]"),
    ]
    if used.size:
        roles.append(Role("G", "Lr", G[:used[-1] + 1], "measurement noise factor, Lr Lr' = Rd "
                          "(the measured outputs' rows)", col0=ns))
    return NativeForm(inputs=inputs, outputs=outputs, roles=roles, nq=ns, h=model.h,
                      nxi=ns + p2, seed=int(seed), stream=int(stream), description=description)
