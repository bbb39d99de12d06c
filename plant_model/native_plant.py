"""The sampled plant as a native FMU's linear form (fmu_common.native_form).

With s = [x; w; z] the state and xi the standard normals of the step (ns + 2p):

    out[k]  = [M s + Lr xi; s; E s]        (selected rows: y, ybar, x, w, z, e or a subset)
    s[k+1]  = Ad s + Bd u + Lq xi

xi is the pythonfmu plant's own standard normal row (plant_model.plant.NoiseStream), and
[Lq; Lr] the factor it colours it with, so a native plant draws the same noise, bit for bit
before the products: with one unkeyed stream xi = [xi_v; xi_m], Lq Lq' = Qd acting on xi_v
and Lr Lr' = Rd on xi_m; with streams (a fleet's vehicles and leader, or one vehicle keyed
by its number) xi is the streams' rows one after the other and [Lq; Lr] places each
stream's factor at its positions of the noise row. Units: s in m, m/s and the exosystems'
units; u in N.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fmu_common.interface import ArraySpec
from fmu_common.native_form import NativeForm, Role

from .discretization import DiscreteModel
from .plant import _noise_factors, _streams

__all__ = ["noise_map", "plant_native_form"]


def noise_map(model: DiscreteModel) -> tuple[np.ndarray, tuple[tuple[int | None, int], ...]]:
    """The noise row [v; n; n_z] as P xi, and the streams that draw xi.

    Parameters
    ----------
    model : DiscreteModel
        The sampled model (Qd, Rd and its noise streams).

    Returns
    -------
    P : np.ndarray
        noise_dim x noise_dim; P P' = blkdiag(Qd, Rd).
    streams : tuple[tuple[int | None, int], ...]
        (key, count) per stream, in the order of xi; key None: numpy's default_rng(seed).
    """
    dim = model.noise_dim
    P = np.zeros((dim, dim))
    streams = _streams(model)
    if streams is None:                    # one generator: blkdiag(Lq, Lr) on [xi_v; xi_m]
        LqT, LrT = _noise_factors(model)
        ns = model.ns
        P[:ns, :ns], P[ns:, ns:] = LqT.T, LrT.T
        return P, ((None, dim),)
    col = 0
    for _, idx, LT in streams:             # stream by stream: noise[idx] = L xi_stream
        P[idx, col:col + idx.size] = LT.T
        col += idx.size
    return P, tuple((int(key), int(idx.size)) for key, idx, _ in streams)


def plant_native_form(model: DiscreteModel, s0: np.ndarray, rows: Sequence[int],
                      inputs: list[ArraySpec], outputs: list[ArraySpec], *, seed: int,
                      description: str) -> NativeForm:
    """A sampled plant as y = Cq s + Lr xi (selected rows), s+ = Ad s + Bd u + Lq xi.

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
    seed : int
        The noise generators' seed (the pythonfmu slave's).
    description : str
        Of the FMU.

    Returns
    -------
    NativeForm
        Roles Ad, Bd, Lq (F), Cq (C), Lr (G), s0 (q0); the noise streams of the slave.
    """
    ns, p2 = model.ns, 2 * model.p
    full = np.vstack([model.M, np.eye(ns), model.E])
    rows = np.asarray(rows, dtype=int)
    P, streams = noise_map(model)
    # one unkeyed stream: Lq on xi_v and Lr on xi_m alone; streams: every column of xi
    col0 = ns if streams[0][0] is None else 0
    Lr_full = np.zeros((full.shape[0], P.shape[1] - col0))
    Lr_full[:p2] = P[ns:, col0:]
    G = Lr_full[rows]
    used = np.flatnonzero(np.any(G != 0.0, axis=1))
    Lq = P[:ns, :ns] if col0 else P[:ns]
    roles = [
        Role("A", "Ad", model.Ad, "state transition over one step: s+ = Ad s + Bd u + Lq xi"),
        Role("B", "Bd", model.Bd, "input matrix over one step (u held)"),
        Role("F", "Lq", Lq, "process noise factor (numpy's normals xi), Lq Lq' = Qd"),
        Role("C", "Cq", full[rows], "outputs from the state (measurements, truth, error)"),
        Role("q0", "s0", s0, "initial state s(0) = [x0; w0; z0]"),
    ]
    if used.size:
        roles.append(Role("G", "Lr", G[:used[-1] + 1], "measurement noise factor, Lr Lr' = Rd "
                          "(the measured outputs' rows)", col0=col0))
    return NativeForm(inputs=inputs, outputs=outputs, roles=roles, nq=ns, h=model.h,
                      nxi=ns + p2, seed=int(seed), streams=streams, description=description)
