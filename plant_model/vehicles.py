"""Vehicle model library: the linear per-vehicle model (A_ii, B1i, B2i, C_i) of paper eq. 1-2.

Every vehicle i of the formation is a linear time-invariant model

    x_i' = A x_i + B1 u_i + B2 w_i,      y_i = C x_i

(the coupling terms sum_j A_ij x_j of eq. 1 come from the communication graph, see
:mod:`plant_model.graph`). Two models are provided here; every model name a scenario may
use (these two, ``remus100-6dof`` and ``remus100-fitted`` of :mod:`plant_model.remus100`)
is an entry of the registry :mod:`plant_model.vehicle_models`.

``remus100`` -- translational dynamics of a REMUS 100 torpedo AUV in the NED frame
(north, east, down), one decoupled axis a in (n, e, d):

    n_a' = v_a                                              (m/s)
    M_a v_a' = -D_a (v_a - w_a) + tau_a                     (N)

with state x = [n, e, d, v_n, v_e, v_d] (m, m/s), input tau = [X_n, X_e, X_d] (force in
N, NED axes), disturbance w = ocean-current velocity [v_cn, v_ce, v_cd] (m/s) and output
y = [n, e, d] (m). Hence the velocity rows of B1 are 1/M_a (1/kg) and of B2 are D_a/M_a
(1/s), and A has -D_a/M_a (1/s) on the velocity diagonal.

    M_a = m + added mass                      (kg)
    D_a = M_a / T_a + 0.5 rho Cd A_f U_c      (kg/s; the drag term on n and e only)

The horizontal axes (n, e) both use the *surge* added mass and surge time constant: a
torpedo AUV whose heading autopilot points it along its velocity moves through the water
in surge whichever NED direction it goes. The down axis uses the heave values. The drag
term is the secant linearization of the quadratic parasitic drag 0.5 rho Cd A_f |U| U
through U = 0 and the cruise speed U_c: it equals the nonlinear drag exactly at 0 and at
U_c, and overestimates it in between (underestimates above U_c).

Numbers (:func:`remus100_parameters`, as in Fossen's Python Vehicle Simulator
``remus100.py``, Fossen 2021, Section 8.4.2): the hull is a prolate spheroid with
semi-axes a = L/2 = 0.8 m and b = diam/2 = 0.095 m, so m = 4/3 pi rho a b^2 = 31.03 kg
(the real vehicle weighs 31.9 kg; the spheroid value is what the MSS model uses). Lamb's
k-factors give the added mass: e = sqrt(1 - (b/a)^2),

    alpha0 = 2 (1 - e^2)/e^3 (0.5 ln((1+e)/(1-e)) - e)
    beta0  = 1/e^2 - (1 - e^2)/(2 e^3) ln((1+e)/(1-e))
    k1 = alpha0/(2 - alpha0),  k2 = beta0/(2 - beta0)

added mass surge m k1 = 0.839 kg, sway = heave = m k2 = 29.44 kg. (Fossen's Python code
divides by the logarithm in beta0 instead of multiplying, which gives k2 = 1.026 > 1;
Lamb's formula above gives k2 = 0.949, and satisfies alpha0 + 2 beta0 = 2.) Low-speed
linear damping time constants T_surge = T_sway = T_heave = 20 s; parasitic drag
coefficient Cd = 0.42 (Allen et al. 2000) on the frontal area A_f = pi b^2 = 0.02835 m^2;
sea water rho = 1026 kg/m^3.

Assumptions and range of validity of ``remus100``:

* inner heading, depth and speed autopilots and the actuators (rudder, stern planes,
  propeller: 1 s time constants in the MSS model) are much faster than the formation
  loop, so the force tau is what the formation controller commands;
* small roll and pitch; no restoring forces (neutral buoyancy, W = B);
* speeds up to the REMUS maximum of 2.5 m/s; the damping is exact only at 0 and at the
  cruise speed, so keep speed variations around ``cruise_speed`` small;
* axes decoupled (no Coriolis, lift or cross-flow terms).

``generic`` -- any matrices A (p x p), B1 (p x q), B2 (p x r), C (s x p), unitless.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .linalg_checks import (
    ModelError,
    as_matrix,
    as_nonnegative,
    as_positive,
    as_square,
    readonly,
)

__all__ = [
    "GENERIC_PARAMS",
    "REMUS100_MAX_SPEED",
    "REMUS100_PARAMS",
    "VehicleModel",
    "generic",
    "generic_from_params",
    "lamb_factors",
    "remus100",
    "remus100_from_params",
    "remus100_parameters",
]

#: Maximum speed of the REMUS 100 (m/s, propeller at 1525 rpm in zero current).
REMUS100_MAX_SPEED = 2.5


@dataclass(frozen=True, eq=False)
class VehicleModel:
    """One vehicle's linear model x' = A x + B1 u + B2 w, y = C x (paper's A_ii etc.).

    Build it with :func:`remus100`, :func:`generic` or by name with
    :func:`plant_model.vehicle_models.make_vehicle`. The matrices are stored read-only.
    ``position_states`` are the indices in x of north, east, down (m), or None when the
    model has no NED position.
    """

    name: str
    A: np.ndarray
    B1: np.ndarray
    B2: np.ndarray
    C: np.ndarray
    state_names: tuple[str, ...]
    state_units: tuple[str, ...]
    input_names: tuple[str, ...]
    input_units: tuple[str, ...]
    disturbance_names: tuple[str, ...]
    disturbance_units: tuple[str, ...]
    output_names: tuple[str, ...]
    output_units: tuple[str, ...]
    position_states: tuple[int, int, int] | None
    parameters: dict

    def __post_init__(self) -> None:
        A = as_square("A", self.A)
        p = A.shape[0]
        B1 = as_matrix("B1", self.B1, (p, None))
        B2 = as_matrix("B2", self.B2, (p, None))
        C = as_matrix("C", self.C, (None, p))
        for attr, val in (("A", A), ("B1", B1), ("B2", B2), ("C", C)):
            object.__setattr__(self, attr, readonly(val))
        for names, units, size, what in (
            ("state_names", "state_units", p, "states"),
            ("input_names", "input_units", B1.shape[1], "inputs"),
            ("disturbance_names", "disturbance_units", B2.shape[1], "disturbances"),
            ("output_names", "output_units", C.shape[0], "outputs"),
        ):
            for attr in (names, units):
                val = tuple(str(v) for v in getattr(self, attr))
                if len(val) != size:
                    raise ModelError(
                        f"{self.name}: {attr} has {len(val)} entries but the model has "
                        f"{size} {what}"
                    )
                object.__setattr__(self, attr, val)
        if self.position_states is not None:
            ps = tuple(int(i) for i in self.position_states)
            if len(ps) != 3 or any(not 0 <= i < p for i in ps):
                raise ModelError(
                    f"{self.name}: position_states {self.position_states!r} must be 3 "
                    f"state indices in 0..{p - 1}"
                )
            object.__setattr__(self, "position_states", ps)

    @property
    def p(self) -> int:
        """Number of states."""
        return self.A.shape[0]

    @property
    def q(self) -> int:
        """Number of control inputs."""
        return self.B1.shape[1]

    @property
    def r(self) -> int:
        """Number of disturbance inputs."""
        return self.B2.shape[1]

    @property
    def s(self) -> int:
        """Number of tracked / measured outputs."""
        return self.C.shape[0]


# ------------------------------------------------------------------------------------
# argument checks
def _triple(name: str, value: Any, unit: str, *, strict: bool) -> list[float]:
    is_list = isinstance(value, (Sequence, np.ndarray)) and not isinstance(value, (str, bytes))
    if not is_list or len(value) != 3:
        raise ModelError(
            f"{name}: expected a list of 3 numbers [surge, sway, heave] ({unit}), got {value!r}"
        )
    check = as_positive if strict else as_nonnegative
    return [check(f"{name}[{k + 1}]", v, unit) for k, v in enumerate(value)]


# ------------------------------------------------------------------------------------
# REMUS 100
def lamb_factors(a: float, b: float) -> tuple[float, float, float]:
    """Lamb's added-mass factors of a prolate spheroid with semi-axes a > b (m): (k1, k2,
    k') for surge, sway/heave and pitch/yaw (module docstring), e = sqrt(1 - (b/a)^2),
    k' = e^4 (beta0 - alpha0) / ((2 - e^2) (2 e^2 - (2 - e^2)(beta0 - alpha0)))."""
    e = math.sqrt(1.0 - (b / a) ** 2)
    log_term = math.log((1.0 + e) / (1.0 - e))
    alpha0 = 2.0 * (1.0 - e * e) / e**3 * (0.5 * log_term - e)
    beta0 = 1.0 / e**2 - (1.0 - e * e) / (2.0 * e**3) * log_term
    kp = e**4 * (beta0 - alpha0) / ((2.0 - e * e) * (2.0 * e * e - (2.0 - e * e) *
                                                     (beta0 - alpha0)))
    return alpha0 / (2.0 - alpha0), beta0 / (2.0 - beta0), kp


def remus100_parameters(rho: float = 1026.0, length: float = 1.6, diameter: float = 0.19,
                        drag_coefficient: float = 0.42) -> dict[str, Any]:
    """Physical parameters of the REMUS 100 from its hull dimensions (SI units).

    Prolate spheroid hull of semi-axes a = length/2, b = diameter/2 (m) in water of density
    ``rho`` (kg/m^3): mass m = 4/3 pi rho a b^2 (kg; 31.03 kg for the defaults, the real
    vehicle is 31.9 kg), added mass [m k1, m k2, m k2] (kg) from Lamb's k-factors (see the
    module docstring), low-speed damping time constants [20, 20, 20] s, parasitic drag
    coefficient ``drag_coefficient`` (Allen et al. 2000) on frontal area pi b^2 (m^2).

    Parameters
    ----------
    rho : float, optional
        Water density, kg/m^3.
    length : float, optional
        Hull length 2 a, m.
    diameter : float, optional
        Hull diameter 2 b, m (smaller than ``length``).
    drag_coefficient : float, optional
        Parasitic drag coefficient Cd (>= 0).

    Returns
    -------
    dict[str, Any]
        Keys mass (kg), added_mass [surge, sway, heave] (kg), time_constant [surge, sway,
        heave] (s), drag_coefficient, frontal_area (m^2), rho (kg/m^3), length (m),
        diameter (m).

    Raises
    ------
    ModelError
        If an argument is not positive (Cd: negative) or the diameter is not smaller
        than the length.
    """
    rho = as_positive("rho", rho, "kg/m^3")
    length = as_positive("length", length, "m")
    diameter = as_positive("diameter", diameter, "m")
    drag_coefficient = as_nonnegative("drag_coefficient", drag_coefficient, "")
    a = length / 2.0
    b = diameter / 2.0
    if b >= a:
        raise ModelError(
            f"diameter = {diameter:g} m must be smaller than length = {length:g} m "
            "(the hull is a prolate spheroid)"
        )
    m = 4.0 / 3.0 * math.pi * rho * a * b * b
    k1, k2, _ = lamb_factors(a, b)
    return {
        "mass": m,
        "added_mass": [m * k1, m * k2, m * k2],
        "time_constant": [20.0, 20.0, 20.0],
        "drag_coefficient": drag_coefficient,
        "frontal_area": math.pi * b * b,
        "rho": rho,
        "length": length,
        "diameter": diameter,
    }


def remus100(mass: float | None = None, added_mass: Sequence[float] | None = None,
             time_constant: Sequence[float] | None = None,
             drag_coefficient: float | None = None,
             cruise_speed: float = 0.0) -> VehicleModel:
    """The REMUS 100 linear translational model in NED (see the module docstring).

    Arguments (None = the published default of :func:`remus100_parameters`):
    ``mass`` rigid-body mass (kg), ``added_mass`` [surge, sway, heave] (kg),
    ``time_constant`` [surge, sway, heave] low-speed damping time constants (s),
    ``drag_coefficient`` parasitic drag coefficient Cd on the frontal area, and
    ``cruise_speed`` (m/s, 0..2.5) where the quadratic drag is linearized.

    The north and east axes use the surge added mass and time constant; the down axis the
    heave ones (the sway values are kept in ``parameters`` but unused). Per axis a:
    M_a = m + added mass (kg), D_a = M_a / T_a + 0.5 rho Cd A_f U_c (kg/s, drag on n and
    e only), A = [[0, I], [0, diag(-D/M)]], B1 = [0; diag(1/M)], B2 = [0; diag(D/M)],
    C = [I, 0].

    Parameters
    ----------
    mass : float or None, optional
        Rigid-body mass m, kg.
    added_mass : Sequence[float] or None, optional
        Added mass [surge, sway, heave], kg.
    time_constant : Sequence[float] or None, optional
        Low-speed damping time constants T [surge, sway, heave], s.
    drag_coefficient : float or None, optional
        Parasitic drag coefficient Cd on the frontal area.
    cruise_speed : float, optional
        Speed U_c where the quadratic drag is linearized (secant), m/s, 0..2.5.

    Returns
    -------
    VehicleModel
        The 6-state model (states n, e, d in m and v_n, v_e, v_d in m/s; inputs forces
        in N; disturbances current velocities in m/s; outputs n, e, d in m).

    Raises
    ------
    ModelError
        If an argument is out of range or of the wrong type.
    """
    base = remus100_parameters()
    m = base["mass"] if mass is None else as_positive("mass", mass, "kg")
    ma = base["added_mass"] if added_mass is None else _triple(
        "added_mass", added_mass, "kg", strict=False)
    tc = base["time_constant"] if time_constant is None else _triple(
        "time_constant", time_constant, "s", strict=True)
    cd = base["drag_coefficient"] if drag_coefficient is None else as_nonnegative(
        "drag_coefficient", drag_coefficient, "")
    uc = as_nonnegative("cruise_speed", cruise_speed, "m/s")
    if uc > REMUS100_MAX_SPEED:
        raise ModelError(
            f"cruise_speed = {uc:g} m/s is above the REMUS 100 maximum speed of "
            f"{REMUS100_MAX_SPEED:g} m/s"
        )
    rho, area = base["rho"], base["frontal_area"]
    drag = 0.5 * rho * cd * area * uc          # secant slope of 0.5 rho Cd A |U| U (kg/s)
    M = np.array([m + ma[0], m + ma[0], m + ma[2]])
    D = np.array([M[0] / tc[0] + drag, M[1] / tc[0] + drag, M[2] / tc[2]])
    params = {
        "mass": m,
        "added_mass": list(ma),
        "time_constant": list(tc),
        "drag_coefficient": cd,
        "frontal_area": area,
        "rho": rho,
        "length": base["length"],
        "diameter": base["diameter"],
        "cruise_speed": uc,
        "total_mass": M.tolist(),
        "damping": D.tolist(),
    }
    return _ned_axes_model("remus100", M, D, params)


def _ned_axes_model(name: str, M: np.ndarray, D: np.ndarray, params: dict[str, Any]
                    ) -> VehicleModel:
    """A = [[0, I], [0, diag(-D/M)]], B1 = [0; diag(1/M)], B2 = [0; diag(D/M)], C = [I, 0]
    with the REMUS names and units."""
    Z = np.zeros((3, 3))
    A = np.block([[Z, np.eye(3)], [Z, np.diag(-D / M)]])
    B1 = np.vstack([Z, np.diag(1.0 / M)])
    B2 = np.vstack([Z, np.diag(D / M)])
    C = np.hstack([np.eye(3), Z])
    return VehicleModel(
        name=name, A=A, B1=B1, B2=B2, C=C,
        state_names=("n", "e", "d", "v_n", "v_e", "v_d"),
        state_units=("m", "m", "m", "m/s", "m/s", "m/s"),
        input_names=("X_n", "X_e", "X_d"), input_units=("N", "N", "N"),
        disturbance_names=("v_cn", "v_ce", "v_cd"), disturbance_units=("m/s",) * 3,
        output_names=("n", "e", "d"), output_units=("m", "m", "m"),
        position_states=(0, 1, 2), parameters=params,
    )


# ------------------------------------------------------------------------------------
# generic
def generic(A: Any, B1: Any, B2: Any, C: Any) -> VehicleModel:
    """Any linear model: A (p x p), B1 (p x q), B2 (p x r), C (s x p); no units.

    Parameters
    ----------
    A : Any
        State matrix, p x p.
    B1 : Any
        Control input matrix, p x q.
    B2 : Any
        Disturbance input matrix, p x r.
    C : Any
        Output matrix, s x p.

    Returns
    -------
    VehicleModel
        The model, with names x1.., u1.., w1.., y1.. and no position states.

    Raises
    ------
    ModelError
        If A is not square, B1 or B2 has not p rows, C not p columns, or a value is not
        finite.
    """
    A = as_square("A", A)
    p = A.shape[0]
    B1 = as_matrix("B1", B1, (p, None))
    B2 = as_matrix("B2", B2, (p, None))
    C = as_matrix("C", C, (None, p))

    def names(prefix: str, k: int) -> tuple[str, ...]:
        return tuple(f"{prefix}{i + 1}" for i in range(k))

    q, r, s = B1.shape[1], B2.shape[1], C.shape[0]
    return VehicleModel(
        name="generic", A=A, B1=B1, B2=B2, C=C,
        state_names=names("x", p), state_units=("",) * p,
        input_names=names("u", q), input_units=("",) * q,
        disturbance_names=names("w", r), disturbance_units=("",) * r,
        output_names=names("y", s), output_units=("",) * s,
        position_states=None,
        parameters={"A": A.tolist(), "B1": B1.tolist(), "B2": B2.tolist(), "C": C.tolist()},
    )


#: the parameters of a ``remus100`` vehicle (:func:`remus100`, all optional)
REMUS100_PARAMS = ("mass", "added_mass", "time_constant", "drag_coefficient", "cruise_speed")
#: the parameters of a ``generic`` vehicle (:func:`generic`, all required)
GENERIC_PARAMS = ("A", "B1", "B2", "C")


def _unknown_params(model: str, params: Mapping[str, Any], accepted: tuple[str, ...]) -> None:
    unknown = sorted(str(k) for k in params if k not in accepted)
    if unknown:
        raise ModelError(f"unknown {model} parameter(s) {', '.join(unknown)}; "
                         f"accepted: {', '.join(accepted)}")


def remus100_from_params(params: Mapping[str, Any]) -> VehicleModel:
    """``remus100`` from a scenario's parameter table (keys :data:`REMUS100_PARAMS`).

    Raises
    ------
    ModelError
        Naming an unknown parameter or an invalid value.
    """
    _unknown_params("remus100", params, REMUS100_PARAMS)
    return remus100(**dict(params))


def generic_from_params(params: Mapping[str, Any]) -> VehicleModel:
    """``generic`` from a scenario's parameter table (keys :data:`GENERIC_PARAMS`, all
    required).

    Raises
    ------
    ModelError
        Naming an unknown parameter, the missing matrices or an invalid value.
    """
    _unknown_params("generic", params, GENERIC_PARAMS)
    missing = [k for k in GENERIC_PARAMS if k not in params]
    if missing:
        raise ModelError(f"missing generic matrices: {', '.join(missing)}")
    return generic(**dict(params))
