"""A parameter interface for fleets that grows with N, not with (N p)^2.

The stacked matrices of N vehicles (plant_model.fleet) have (N p)^2 entries; exposing them
as scalar parameters makes an FMU slow to load and useless to read. A fleet FMU instead
exposes the quantities a user would change, with FMI structured names:

    vehicle[i].mass, vehicle[i].added_mass[k], ...  model parameters of vehicle i
    vehicle[i].A[a,b] ...                          (generic models: their own matrices)
    vehicle[i].x0[k], vehicle[i].offset[k]          initial state, formation offset (m)
    vehicle[i].current.time_constant / .sigma / .w0 ocean current (Gauss-Markov)
    vehicle[i].W_x, .V_y, .V_ybar, .Q, .R           noise intensities and cost weights
    a[i,j]     weight of the edge j -> i (vehicle i hears j), only for existing edges
    a0[i]      pinning weight of vehicle i (only for vehicles that hear the leader)
    coupling[a,b]                                    coupling matrix on the vehicle state
    leader.F[a,b], leader.H[a,b], leader.z0[k], leader.W_z   the virtual leader

Each FMU exposes only what its mathematics reads (the controller has no noise and no
initial state; the plant has no cost weights). In exitInitializationMode the slave writes
the parameter values back into the spec and rebuilds the stacked system
(:func:`plant_model.fleet.fleet_system`). The graph's structure (which edges exist) and the
vehicle models are fixed when the FMU is built.
"""
from __future__ import annotations

import copy
from collections.abc import Iterator
from typing import Any

import numpy as np

from fmu_common.interface import ArraySpec

from .linalg_checks import ModelError
from .vehicle_models import DEFAULT_MODEL, get

__all__ = ["fleet_parameter_specs", "fleet_spec_from_parameters"]

ALL = frozenset({"plant", "estimator", "controller"})
SIM = frozenset({"plant", "estimator"})
CTRL = frozenset({"controller"})

#: vehicle field -> (FMU kinds that read it, unit, description)
_VEHICLE_FIELDS: dict[str, tuple[frozenset, str | None, str]] = {
    "x0": (SIM, None, "initial state x_i(0) (model state order)"),
    "offset": (ALL, "m", "formation offset d_i (NED): target = leader position + d_i"),
    "W_x": (SIM, None, "intensity of the process noise m_i (times I if scalar)"),
    "V_y": (SIM, None, "intensity of the position sensor noise n_i (times I if scalar)"),
    "V_ybar": (SIM, None, "intensity of the leader measurement noise n_z,i"),
    "Q": (CTRL, "1/m2", "tracking error weight Q_i (times I if scalar)"),
    "R": (CTRL, "1/N2", "control weight R_i (times I if scalar)"),
}
#: current / disturbance key -> (kinds, unit, description)
_DIST_FIELDS: dict[str, tuple[frozenset, str | None, str]] = {
    "time_constant": (ALL, "s", "correlation time tau of the Gauss-Markov current"),
    "sigma": (SIM, "m/s", "stationary standard deviation of the current per axis"),
    "w0": (SIM, "m/s", "initial current w_i(0)"),
    "K": (ALL, None, "disturbance exosystem matrix K_i"),
    "W_w": (SIM, None, "intensity of the disturbance process noise"),
}
_LEADER_FIELDS: dict[str, tuple[frozenset, str | None, str]] = {
    "F": (ALL, None, "leader exosystem z_l' = F z_l"),
    "H": (ALL, None, "leader position (NED, m) = H z_l"),
    "z0": (SIM, None, "leader initial state z_l(0)"),
    "W_z": (SIM, None, "intensity of the leader process noise (0: a planned path)"),
}


def _leaves(spec: dict[str, Any], kind: str) -> Iterator[tuple[tuple, str, Any, str | None, str]]:
    """(path in spec, FMI name, value, unit, description) of every parameter of ``kind``."""
    for i, v in enumerate(spec["vehicles"], start=1):
        model = v.get("model", DEFAULT_MODEL)
        docs = get(model).param_docs
        for key, value in v.get("params", {}).items():
            if key not in docs:
                raise ModelError(f"vehicle {i}: parameter {key!r} of the {model} model is not "
                                 "a parameter a fleet FMU can take (it takes "
                                 f"{', '.join(docs) or 'none of this model'})")
            unit, doc = docs[key]
            yield (("vehicles", i - 1, "params", key), f"vehicle[{i}].{key}", value, unit,
                   f"vehicle {i}: {doc}")
        for key, (kinds, unit, doc) in _VEHICLE_FIELDS.items():
            if kind in kinds and key in v:
                yield (("vehicles", i - 1, key), f"vehicle[{i}].{key}", v[key], unit,
                       f"vehicle {i}: {doc}")
        for group in ("current", "disturbance"):
            for key, value in v.get(group, {}).items():
                kinds, unit, doc = _DIST_FIELDS[key]
                if kind in kinds:
                    yield (("vehicles", i - 1, group, key), f"vehicle[{i}].{group}.{key}",
                           value, unit, f"vehicle {i}: {doc}")
    graph = spec["graph"]
    for e, (j, i, a) in enumerate(graph.get("edges", [])):
        yield (("graph", "edges", e, 2), f"a[{i},{j}]", a, None,
               f"weight a_ij of the edge {j} -> {i}: vehicle {i} hears vehicle {j}")
    for e, (i, a) in enumerate(graph.get("pinning", [])):
        yield (("graph", "pinning", e, 1), f"a0[{i}]", a, None,
               f"pinning weight a_i0: vehicle {i} hears the leader")
    yield (("graph", "coupling"), "coupling", graph["coupling"], None,
           "coupling matrix Gamma of the consensus protocol on the vehicle state")
    for key, (kinds, unit, doc) in _LEADER_FIELDS.items():
        if kind in kinds and key in spec["leader"]:
            yield (("leader", key), f"leader.{key}", spec["leader"][key], unit, doc)


def fleet_parameter_specs(spec: dict[str, Any], kind: str) -> list[ArraySpec]:
    """The parameters of an FMU of ``kind`` for the fleet ``spec`` (start = spec values).

    Parameters
    ----------
    spec : dict[str, Any]
        The resolved fleet spec (:func:`plant_model.fleet.resolve_fleet_spec`).
    kind : str
        'plant', 'estimator' or 'controller': only what that FMU reads is exposed.

    Returns
    -------
    list[ArraySpec]
        One parameter array per leaf, with structured names such as ``vehicle[1].mass``.
    """
    out = []
    for _, name, value, unit, doc in _leaves(spec, kind):
        arr = np.asarray(value, dtype=float)
        out.append(ArraySpec(name, arr.shape, "parameter", doc, start=arr, unit=unit))
    return out


def _assign(root: Any, path: tuple, value: Any) -> None:
    for key in path[:-1]:
        root = root[key]
    root[path[-1]] = value


def fleet_spec_from_parameters(spec: dict[str, Any], kind: str,
                               par: dict[str, Any]) -> dict[str, Any]:
    """A copy of ``spec`` with the parameter values ``par`` (name -> array) written in.

    Parameters
    ----------
    spec : dict[str, Any]
        The fleet spec the FMU was built with.
    kind : str
        'plant', 'estimator' or 'controller'.
    par : dict[str, Any]
        Parameter values by the names of :func:`fleet_parameter_specs`.

    Returns
    -------
    dict[str, Any]
        A deep copy of ``spec`` holding the values as lists / floats.
    """
    new = copy.deepcopy(spec)
    for path, name, _, _, _ in _leaves(spec, kind):
        value = np.asarray(par[name], dtype=float)
        _assign(new, path, value.tolist() if value.ndim else float(value))
    return new
