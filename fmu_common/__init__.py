"""FMI 2.0 plumbing shared by the project's pythonfmu slaves (no mathematics here)."""
from .interface import UNIT_DEFINITIONS, ArraySpec, element_names, expand

__all__ = ["UNIT_DEFINITIONS", "ArraySpec", "element_names", "expand"]
