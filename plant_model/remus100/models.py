"""The REMUS 100 models beside the linear ``remus100``: the nonlinear ``remus100-6dof``
(its linear design model and its nonlinear data, plant_model.remus100.plant) and
``remus100-fitted`` (the first-order model fitted to the nonlinear vehicle). Units: kg,
kg/s, m, s; NED axes as :mod:`plant_model.vehicles`.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import fields, replace
from typing import Any

import numpy as np

from ..linalg_checks import ModelError, as_number, as_positive, as_vector
from ..vehicles import VehicleModel, _ned_axes_model, remus100, remus100_parameters
from .autopilot import AutopilotGains
from .dynamics import REMUS_BOUNDS, Remus100

__all__ = ["FITTED_HORIZONTAL", "FITTED_VERTICAL", "GAIN_FIELDS", "REMUS100_6DOF_PARAMS",
           "REMUS_FIELDS", "remus100_6dof_design", "remus100_6dof_explicit_params",
           "remus100_fitted", "remus100_fitted_from_params", "remus_from_parameters"]


#: the scalar fields of :class:`Remus100` a scenario or an FMU parameter may set
REMUS_FIELDS = tuple(f.name for f in fields(Remus100) if f.name not in ("current", "r_g"))
#: the autopilot gains (:class:`AutopilotGains`)
GAIN_FIELDS = tuple(f.name for f in fields(AutopilotGains))
#: the units of the autopilot gains that have one (for the messages)
GAIN_UNITS = {"U_max": "m/s", "n_max": "rpm", "U_min": "m/s", "delta_max": "rad",
              "K_u": "rpm s/m", "K_ui": "rpm/m", "K_gi": "1/s"}
#: the parameters of a ``remus100-6dof`` vehicle (:func:`remus100_6dof_design`)
REMUS100_6DOF_PARAMS = ("cruise_speed", "design", "substep", "autopilot", "r_g", *REMUS_FIELDS)


def _is_number(value: Any) -> bool:
    """A real number (not a boolean, not text): NaN too, which :class:`Remus100` names."""
    return isinstance(value, (int, float, np.integer, np.floating)) and \
        not isinstance(value, (bool, np.bool_))


def remus_from_parameters(values: dict[str, Any]) -> Remus100:
    """A :class:`Remus100` from {field: value} (any of :data:`REMUS_FIELDS`, ``r_g``).

    Raises
    ------
    ModelError
        Naming an unknown field or an invalid value (:class:`Remus100` checks).
    """
    unknown = sorted(set(values) - set(REMUS_FIELDS) - {"r_g"})
    if unknown:
        raise ModelError(f"remus100-6dof: unknown parameter(s) {', '.join(unknown)}")
    # numbers as TOML numbers: "1525" is refused, not read as 1525 (the key is named)
    kw: dict[str, Any] = {k: float(v) if _is_number(v) else as_number(k, v)
                          for k, v in values.items() if k != "r_g"}
    if "r_g" in values:
        kw["r_g"] = tuple(float(c) for c in as_vector("r_g", values["r_g"], 3))
    return replace(Remus100(), **kw)


#: ``remus100-fitted``: M and D (kg, kg/s) of the first-order model closest to the
#: nonlinear REMUS 100 (remus100-6dof) behind its force interface at 1.5 m/s, fitted to its
#: frequency responses from 0.02 to 0.3 rad/s in relative error (orchestrator.analysis.
#: remus_response.fit_first_order; the horizontal axes together; tests/test_remus_response.py
#: re-fits them)
FITTED_HORIZONTAL = (43.54, 9.618)
FITTED_VERTICAL = (68.88, 2.744)


def remus100_fitted() -> VehicleModel:
    """The REMUS 100 as the first-order model fitted to the nonlinear vehicle at 1.5 m/s
    (:data:`FITTED_HORIZONTAL`, :data:`FITTED_VERTICAL`): per NED axis M_a v_a' =
    -D_a (v_a - w_a) + tau_a, as :func:`remus100` with M = [M_h, M_h, M_v] and D =
    [D_h, D_h, D_v]. Heavier and less damped than ``remus100``: the torpedo's turns and
    pitch changes, seen from the force command, look like extra inertia.

    Returns
    -------
    VehicleModel
        The 6-state model (name ``remus100-fitted``).
    """
    M = np.array([FITTED_HORIZONTAL[0], FITTED_HORIZONTAL[0], FITTED_VERTICAL[0]])
    D = np.array([FITTED_HORIZONTAL[1], FITTED_HORIZONTAL[1], FITTED_VERTICAL[1]])
    return _ned_axes_model("remus100-fitted", M, D, {
        "total_mass": M.tolist(), "damping": D.tolist(), "cruise_speed": 1.5,
        "fitted_to": "remus100-6dof at 1.5 m/s, 0.02 to 0.3 rad/s"})


def remus100_fitted_from_params(params: Mapping[str, Any]) -> VehicleModel:
    """``remus100-fitted`` from a scenario's parameter table, which must be empty.

    Raises
    ------
    ModelError
        If ``params`` names any parameter (the model takes none).
    """
    if params:
        raise ModelError(f"unknown remus100-fitted parameter(s) "
                         f"{', '.join(sorted(map(str, params)))}; it takes none (fitted "
                         "at 1.5 m/s)")
    return remus100_fitted()


def remus100_6dof_design(params: Mapping[str, Any]) -> VehicleModel:
    """The ``remus100-6dof`` vehicle: its linear design model and its nonlinear data.

    ``params``: ``design`` (the linear model the estimator, the controller and the force
    interface use: ``remus100``, default, or ``remus100-fitted``), ``cruise_speed`` (m/s,
    where the ``remus100`` design model's drag is linearized; default 1.5), ``substep``
    (s, the RK4 sub-step; default the longest divisor of h up to 0.05 s), ``autopilot``
    (a table of :class:`plant_model.remus100.autopilot.AutopilotGains`) and any field
    of :class:`plant_model.remus100.dynamics.Remus100` (hull, fins, propeller, limits; ``r_g``
    a 3-vector). The ``remus100`` design model is :func:`remus100` of the same hull:
    rigid-body and added mass of the spheroid, time constants [T_surge, T_sway, T_sway],
    drag coefficient Cd_surge.

    Raises
    ------
    ModelError
        Naming an unknown parameter or an invalid value.
    """
    accepted = REMUS100_6DOF_PARAMS
    unknown = sorted(str(k) for k in params if k not in accepted)
    if unknown:
        raise ModelError(f"unknown remus100-6dof parameter(s) {', '.join(unknown)}; "
                         f"accepted: {', '.join(accepted)}")
    data = {k: v for k, v in params.items() if k in REMUS_FIELDS or k == "r_g"}
    vehicle = remus_from_parameters(data)
    gains = params.get("autopilot", {})
    if not isinstance(gains, Mapping) or set(gains) - set(GAIN_FIELDS):
        bad = sorted(set(gains) - set(GAIN_FIELDS)) if isinstance(gains, Mapping) else gains
        raise ModelError(f"remus100-6dof autopilot: unknown gain(s) {bad}; accepted: "
                         f"{', '.join(GAIN_FIELDS)}")
    gains = {k: as_positive(f"autopilot.{k}", v, GAIN_UNITS.get(k, "")) for k, v in
             gains.items()}
    if "delta_max" in gains:                        # the fins' limit, as the vehicle's
        REMUS_BOUNDS["delta_max"].check("autopilot.delta_max", gains["delta_max"])
    AutopilotGains(**gains)
    substep = params.get("substep")
    if substep is not None:
        substep = as_positive("substep", substep, "s")
    design = params.get("design", "remus100")
    if design == "remus100-fitted":
        lin = remus100_fitted()
    elif design == "remus100":
        hull = remus100_parameters(vehicle.rho, vehicle.L, vehicle.diam, vehicle.Cd_surge)
        lin = remus100(mass=hull["mass"], added_mass=hull["added_mass"],
                       time_constant=[vehicle.T_surge, vehicle.T_sway, vehicle.T_sway],
                       drag_coefficient=vehicle.Cd_surge,
                       cruise_speed=params.get("cruise_speed", 1.5))
    else:
        raise ModelError(f"remus100-6dof design = {design!r} is not one of remus100, "
                         "remus100-fitted")
    nonlinear = {k: getattr(vehicle, k) for k in REMUS_FIELDS}
    nonlinear["r_g"] = list(vehicle.r_g)
    return VehicleModel(
        name="remus100-6dof", A=lin.A, B1=lin.B1, B2=lin.B2, C=lin.C,
        state_names=lin.state_names, state_units=lin.state_units,
        input_names=lin.input_names, input_units=lin.input_units,
        disturbance_names=lin.disturbance_names, disturbance_units=lin.disturbance_units,
        output_names=lin.output_names, output_units=lin.output_units,
        position_states=lin.position_states,
        parameters={**lin.parameters, "nonlinear": nonlinear, "autopilot": gains,
                    "substep": substep, "design": design})


def remus100_6dof_explicit_params(model: VehicleModel) -> dict[str, Any]:
    """The parameters of a ``remus100-6dof`` vehicle (:func:`remus100_6dof_design`) with
    every default made explicit: its data as given, the design model, the gains, the
    sub-step if one was set."""
    par = model.parameters
    return {"cruise_speed": par["cruise_speed"], "design": par["design"],
            **par["nonlinear"],
            "autopilot": dict(par["autopilot"]),
            **({"substep": par["substep"]} if par["substep"] else {})}
