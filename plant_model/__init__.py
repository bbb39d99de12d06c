"""Plant model: the paper's vehicles, exosystems and sensors, sampled exactly."""
from .discretization import DiscreteModel, discretize
from .linalg_checks import ModelError
from .plant import NoiseStream, Plant, plant_output_layout
from .system import LinearSystem

__all__ = ["DiscreteModel", "discretize", "ModelError", "NoiseStream", "Plant",
           "plant_output_layout", "LinearSystem"]
