"""The leader and a formation offset in one vehicle's state space.

The consensus protocol of eq. 1 compares the vehicle's state with the leader's, x_0 - x_i;
the leader is an exosystem z with a tracked output H z (positions, for the NED paths of
:mod:`plant_model.leader`). :func:`leader_state_map` gives x_0 = T z, the state of a vehicle
that follows the leader exactly; :func:`state_offset` the state-space offset delta_i of a
formation offset d_i in the output (metres for ``remus100``).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .linalg_checks import ModelError, as_matrix, as_vector
from .vehicle_models import find
from .vehicles import VehicleModel

__all__ = ["leader_state_map", "state_offset"]


def _layout(model: VehicleModel) -> str | None:
    """The model's state layout (plant_model.vehicle_models.LAYOUTS; None: unknown)."""
    entry = find(model.name)
    return None if entry is None else entry.layout


def leader_state_map(model: VehicleModel, H_leader: Any, F_leader: Any) -> np.ndarray:
    """T (p x l) with x_0 = T z: the virtual leader's state in the vehicle's state space.

    The leader's exosystem is z' = F z with position H z. For ``remus100`` (output =
    NED position, velocity states = position derivative) T = [H; H F]: position and
    velocity of the leader path, so C T = H exactly; H must have 3 rows (n, e, d in m).
    For ``generic`` T = pinv(C) H, the least-squares state with output H z (exact,
    C T = H, when C has full row rank); H must have s rows.

    Parameters
    ----------
    model : VehicleModel
        The vehicle's model.
    H_leader : Any
        Leader output matrix H, s x l (NED position in m for ``remus100``).
    F_leader : Any
        Leader exosystem matrix F, l x l, 1/s.

    Returns
    -------
    np.ndarray
        T, p x l.

    Raises
    ------
    ModelError
        If the shapes do not fit the model or the model is unknown.
    """
    F = as_matrix("leader F", F_leader)
    l_ = F.shape[0]
    F = as_matrix("leader F", F, (l_, l_))
    if _layout(model) == "ned":
        H = as_matrix("leader H", H_leader)
        if H.shape[0] != 3:
            raise ModelError(
                f"leader H: wrong shape {H.shape[0]}x{H.shape[1]}, expected 3x{l_} "
                "(a remus100 vehicle tracks the leader's north, east, down position)"
            )
        H = as_matrix("leader H", H, (3, l_))
        return np.vstack([H, H @ F])
    if _layout(model) == "outputs":
        H = as_matrix("leader H", H_leader)
        if H.shape[0] != model.s:
            raise ModelError(
                f"leader H: wrong shape {H.shape[0]}x{H.shape[1]}, expected {model.s}x{l_} "
                f"(one row per vehicle output; the vehicle has {model.s})"
            )
        H = as_matrix("leader H", H, (model.s, l_))
        return np.linalg.pinv(model.C) @ H
    raise ModelError(f"leader_state_map: unknown vehicle model {model.name!r}")


def state_offset(model: VehicleModel, offset: Any) -> np.ndarray:
    """The formation offset delta_i (p,) in the vehicle's state space.

    ``offset`` is the desired output offset d from the leader (for ``remus100`` the NED
    position offset in m, giving delta = [d; 0, 0, 0]: same velocity as the leader). For
    ``generic`` delta = pinv(C) d (least squares; C delta = d when C has full row rank).

    Parameters
    ----------
    model : VehicleModel
        The vehicle's model.
    offset : Any
        The output offset d, length s (m for ``remus100``).

    Returns
    -------
    np.ndarray
        delta, shape (p,).

    Raises
    ------
    ModelError
        If ``offset`` has the wrong length or the model is unknown.
    """
    if _layout(model) == "ned":
        d = as_vector("formation offset", offset, 3)
        return np.concatenate([d, np.zeros(3)])
    if _layout(model) == "outputs":
        d = as_vector("formation offset", offset, model.s)
        return np.linalg.pinv(model.C) @ d
    raise ModelError(f"state_offset: unknown vehicle model {model.name!r}")
