"""The model parameters the three FMUs share: names, shapes, descriptions, start values.

Domain knowledge (what the system matrices mean), expressed as FMI interface tables
(:class:`fmu_common.interface.ArraySpec`); fleets use :mod:`plant_model.fleet_parameters`.
"""
from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from fmu_common.interface import ArraySpec

from .system import LinearSystem

__all__ = ["PARAMETER_DOCS", "VEHICLE_PARAMETERS", "sample_period_spec", "integer_spec",
           "vehicle_seed_spec", "noise_convention_spec", "vehicle_parameter_specs",
           "system_parameter_specs", "system_mapping_from_parameters",
           "model_parameter_specs", "system_from_parameters"]

#: name -> (shape in terms of the dimensions n, m, r, p, l; description)
PARAMETER_DOCS: dict[str, tuple[tuple[str, ...], str]] = {
    "A": (("n", "n"), "vehicle state matrix: x' = A x + B1 u + B2 w + m"),
    "B1": (("n", "m"), "control input matrix B1"),
    "B2": (("n", "r"), "disturbance input matrix B2"),
    "C": (("p", "n"), "output matrix: y = C x + n"),
    "F": (("l", "l"), "reference (virtual leader) exosystem: z' = F z + m_z"),
    "H": (("p", "l"), "reference output: ybar = H z + n_z"),
    "K": (("r", "r"), "disturbance exosystem: w' = K w + m_w"),
    "Q": (("p", "p"), "tracking error weight Q of the cost e'Qe + u'Ru (positive definite)"),
    "R": (("m", "m"), "control weight R of the cost e'Qe + u'Ru (positive definite)"),
    "x0": (("n",), "initial vehicle state x(0)"),
    "w0": (("r",), "initial disturbance state w(0)"),
    "z0": (("l",), "initial reference state z(0)"),
    "W_x": (("n", "n"), "intensity (PSD) of the vehicle process noise m; per-step "
                        "covariance if noise_convention = per_sample"),
    "W_w": (("r", "r"), "intensity (PSD) of the disturbance process noise m_w"),
    "W_z": (("l", "l"), "intensity (PSD) of the reference process noise m_z"),
    "V_y": (("p", "p"), "intensity of the vehicle sensor noise n (covariance V_y/h per "
                        "sample; V_y itself if noise_convention = per_sample)"),
    "V_ybar": (("p", "p"), "intensity of the reference sensor noise n_z (covariance "
                           "V_ybar/h per sample)"),
}

#: the model parameters of one vehicle's FMU (the per-vehicle deployment)
VEHICLE_PARAMETERS = ("A", "B1", "B2", "C", "K", "x0", "w0", "W_x", "W_w", "V_y", "V_ybar")


def system_parameter_specs(config: dict[str, Any], names: Iterable[str]) -> list[ArraySpec]:
    """Parameter specs for ``names``, start values from ``config['system']``.

    Parameters
    ----------
    config : dict[str, Any]
        The FMU's build configuration: ``dims`` (n, m, r, p, l) and ``system`` (the
        :meth:`LinearSystem.to_mapping` of the scenario).
    names : Iterable[str]
        Keys of :data:`PARAMETER_DOCS` to expose.

    Returns
    -------
    list[ArraySpec]
        One parameter array per name, shaped from ``dims``.
    """
    system = config["system"]
    dims = config["dims"]
    specs = []
    for name in names:
        shape_syms, doc = PARAMETER_DOCS[name]
        shape = tuple(int(dims[s]) for s in shape_syms)
        start = np.asarray(system[name], dtype=float).reshape(shape)
        specs.append(ArraySpec(name, shape, "parameter", doc, start=start))
    return specs


def system_mapping_from_parameters(par: dict[str, Any], names: Iterable[str]) -> dict[str, Any]:
    """The subset of a LinearSystem mapping held in the slave's parameter arrays.

    Parameters
    ----------
    par : dict[str, Any]
        The slave's parameter values by array name.
    names : Iterable[str]
        The system entries to take (those absent from ``par`` are skipped).

    Returns
    -------
    dict[str, Any]
        Name -> float array copy, ready for :meth:`LinearSystem.from_mapping`.
    """
    return {name: np.array(par[name], dtype=float) for name in names if name in par}


def sample_period_spec(config: dict[str, Any], description: str) -> ArraySpec:
    """The parameter ``h`` (s): the communication step an FMU is sampled or designed for.

    Parameters
    ----------
    config : dict[str, Any]
        The FMU's build configuration; ``config['h']`` is the start value, s.
    description : str
        The variable's description in modelDescription.xml.

    Returns
    -------
    ArraySpec
        The scalar Real parameter ``h`` with unit s.
    """
    return ArraySpec("h", (), "parameter", description, start=config["h"], unit="s")


def integer_spec(name: str, description: str, start: int, low: int) -> ArraySpec:
    """A scalar Integer parameter from ``low`` to 2**31 - 1 (a seed, a vehicle number).

    Parameters
    ----------
    name : str
        The variable's name.
    description : str
        Its description in modelDescription.xml.
    start : int
        Start value.
    low : int
        Smallest value.

    Returns
    -------
    ArraySpec
        The parameter.
    """
    return ArraySpec(name, (), "parameter", description, start=start, type="Integer", min=low,
                     max=2**31 - 1)


def vehicle_seed_spec(config: dict[str, Any]) -> ArraySpec:
    """The ``seed`` (start ``config['seed']``) of one vehicle's FMU, which draws from the
    generator seeded [seed, vehicle]."""
    return integer_spec("seed", "seed of the fleet's noise (numpy PCG64; this vehicle draws "
                        "from the generator seeded [seed, vehicle])", config["seed"], 0)


def noise_convention_spec(config: dict[str, Any]) -> ArraySpec:
    """The String parameter ``noise_convention`` ('intensity' or 'per_sample').

    Parameters
    ----------
    config : dict[str, Any]
        The FMU's build configuration; the start value is
        ``config['system']['noise_convention']``.

    Returns
    -------
    ArraySpec
        The scalar String parameter.
    """
    return ArraySpec("noise_convention", (), "parameter",
                     "'intensity' (W, V are continuous intensities) or 'per_sample'",
                     start=config["system"]["noise_convention"], type="String")


def vehicle_parameter_specs(config: dict[str, Any], period: str, vehicle: str
                            ) -> list[ArraySpec]:
    """The parameters every vehicle FMU starts with: its model (:data:`VEHICLE_PARAMETERS`,
    start values from ``config['system']``), the sample period h (described by
    ``period``), the fleet's seed, its number in the fleet 1..N (described by ``vehicle``,
    start ``config['vehicle']``, default 1) and the noise convention."""
    return system_parameter_specs(config, VEHICLE_PARAMETERS) + [
        sample_period_spec(config, period),
        vehicle_seed_spec(config),
        integer_spec("vehicle", vehicle, config.get("vehicle", 1), 1),
        noise_convention_spec(config),
    ]


def model_parameter_specs(config: dict[str, Any], kind: str,
                          names: Iterable[str]) -> list[ArraySpec]:
    """The model parameters of an FMU of ``kind``.

    The fleet interface (:mod:`plant_model.fleet_parameters`) when the FMU was built for a
    fleet, else the system matrices ``names``.

    Parameters
    ----------
    config : dict[str, Any]
        The FMU's build configuration (``fleet`` is its fleet spec, or None).
    kind : str
        'plant', 'estimator' or 'controller': what the FMU's mathematics reads.
    names : Iterable[str]
        The system matrices to expose when there is no fleet.

    Returns
    -------
    list[ArraySpec]
        The model parameters, start values from the configuration.
    """
    if config.get("fleet") is not None:
        from .fleet_parameters import fleet_parameter_specs
        return fleet_parameter_specs(config["fleet"], kind)
    return system_parameter_specs(config, names)


def system_from_parameters(config: dict[str, Any], kind: str, par: dict[str, Any],
                           names: Iterable[str],
                           noise_convention: str | None = None) -> LinearSystem:
    """The LinearSystem described by the parameter values ``par`` (see model_parameter_specs).

    Parameters
    ----------
    config : dict[str, Any]
        The FMU's build configuration (``fleet`` is its fleet spec, or None).
    kind : str
        'plant', 'estimator' or 'controller'.
    par : dict[str, Any]
        The slave's parameter values by array name.
    names : Iterable[str]
        The system matrices held in ``par`` when there is no fleet.
    noise_convention : str or None, optional
        Replaces the noise convention of the configuration when given.

    Returns
    -------
    LinearSystem
        The validated system (the stacked fleet system for a fleet FMU).

    Raises
    ------
    ModelError
        If the parameter values do not make a valid system.
    """
    if config.get("fleet") is not None:
        from .fleet import fleet_system  # lazily: it brings in networkx
        from .fleet_parameters import fleet_spec_from_parameters
        spec = fleet_spec_from_parameters(config["fleet"], kind, par)
        if noise_convention is not None:
            spec["noise_convention"] = noise_convention
        return fleet_system(spec)
    mapping = system_mapping_from_parameters(par, names)
    if noise_convention is not None:
        mapping["noise_convention"] = noise_convention
    return LinearSystem.from_mapping(mapping)
