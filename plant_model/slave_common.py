"""What the plant-like slaves share (plant, leader, vehicle, nonlinear REMUS 100).

A slave sets, in ``setup``, ``self.plant`` (an object with ``step(u)``, ``get_state()``,
``set_state(state)`` and the state ``s``, writing the outputs of sample k into the slave's
output buffer) and ``self._u`` (the input it holds over the step).
"""
from __future__ import annotations

from typing import Any

from fmu_common.native_form import NativeForm
from fmu_common.slave_base import DelegatedStateSlave

from .discretization import DiscreteModel, discretize
from .native_plant import plant_native_form
from .parameters import system_from_parameters, system_mapping_from_parameters
from .per_vehicle import vehicle_alone
from .system import LinearSystem

__all__ = ["PlantSlave", "sampled_system", "vehicle_view"]


def sampled_system(slave: Any, kind: str,
                   names: tuple[str, ...]) -> tuple[LinearSystem, DiscreteModel]:
    """The system a slave's parameters describe (its noise convention) and its sampling at h.

    Parameters
    ----------
    slave : Any
        The slave (``config``, ``par`` with ``h`` and ``noise_convention``).
    kind : str
        'plant' or 'estimator' (:func:`plant_model.parameters.system_from_parameters`).
    names : tuple[str, ...]
        The system matrices held in the parameters.

    Returns
    -------
    system : LinearSystem
        The validated system.
    model : DiscreteModel
        It, sampled at h.

    Raises
    ------
    ModelError
        If the parameters do not make a valid system or h is not positive.
    """
    system = system_from_parameters(slave.config, kind, slave.par, names,
                                    slave.par["noise_convention"])
    return system, discretize(system, float(slave.par["h"]))


def vehicle_view(slave: Any, names: tuple[str, ...]) -> LinearSystem:
    """One vehicle alone, from a per-vehicle slave's parameters (its noise convention).

    Parameters
    ----------
    slave : Any
        The slave (``config`` with ``dims``, ``par`` with ``noise_convention``).
    names : tuple[str, ...]
        The vehicle's matrices held in the parameters.

    Returns
    -------
    LinearSystem
        :func:`plant_model.per_vehicle.vehicle_alone` of those parameters.

    Raises
    ------
    ModelError
        If the parameters do not make a valid vehicle.
    """
    mp = system_mapping_from_parameters(slave.par, names)
    return vehicle_alone(mp, int(slave.config["dims"]["l"]), slave.par["noise_convention"])


class PlantSlave(DelegatedStateSlave):
    """Outputs kept current by ``self.plant``; a step is ``self.plant.step(self._u)``."""

    step_parameter = "h"

    def plant_native_form(self, s0: Any, rows: Any) -> NativeForm:
        """The linear plant ``self.model`` started at ``s0`` as a native form, its outputs
        the rows ``rows`` of the plant's output vector (its noise: the stream of ``seed``).

        Parameters
        ----------
        s0 : Any
            Initial state.
        rows : Any
            Which of the plant's outputs are this FMU's, in order.

        Returns
        -------
        NativeForm
            :func:`plant_model.native_plant.plant_native_form` of this slave.
        """
        return plant_native_form(self.model, s0, rows, *self.io_specs(),
                                 seed=int(self.par["seed"]), description=self.description)

    def compute_outputs(self) -> None:
        """Nothing to do: the plant keeps the outputs of sample k in the buffer."""
        pass

    def advance(self, step: float) -> None:
        """One sample period with u held: ``self.plant.step(self._u)``.

        Parameters
        ----------
        step : float
            The communication step, s (checked against h by the base class).
        """
        self.plant.step(self._u)
