"""Declarative FMU interfaces: named arrays expanded to FMI 2.0 scalar variables.

FMI 2.0 has no arrays, so an array ``A`` of shape (2, 3) becomes the scalar variables
``A[1,1]`` ... ``A[2,3]`` (structured naming convention, 1-based, row major), a vector
``x0`` becomes ``x0[1]``..., and a scalar keeps its name. The same table drives the slave
(registration, value references) and the build step (units, descriptions,
ModelStructure), so the two cannot drift apart.
"""
from __future__ import annotations

import functools
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["ArraySpec", "element_names", "expand", "UNIT_DEFINITIONS"]

#: SI base-unit exponents of the units the FMUs use (FMI 2.0 <BaseUnit> attributes; a
#: ``factor`` converts to SI: value_SI = factor * value).
UNIT_DEFINITIONS: dict[str, dict[str, int]] = {
    "s": {"s": 1},
    "m": {"m": 1},
    "m/s": {"m": 1, "s": -1},
    "m/s2": {"m": 1, "s": -2},
    "N": {"kg": 1, "m": 1, "s": -2},
    "rad": {"rad": 1},
    "rad/s": {"rad": 1, "s": -1},
    "kg": {"kg": 1},
    "kg/s": {"kg": 1, "s": -1},
    "1/s": {"s": -1},
    "1/m2": {"m": -2},
    "1/N2": {"kg": -2, "m": -2, "s": 4},
    "m2": {"m": 2},
    "kg/m3": {"kg": 1, "m": -3},
    "rpm": {"rad": 1, "s": -1, "factor": 0.10471975511965977},   # 2 pi / 60 rad/s
}


@dataclass(frozen=True)
class ArraySpec:
    """One named array of an FMU interface."""

    name: str
    shape: tuple[int, ...]
    causality: str                       #: "parameter", "input" or "output"
    description: str
    start: Any = None                    #: start value (parameters and inputs)
    unit: str | None = None
    type: str = "Real"                   #: "Real", "Integer" or "String"
    variability: str | None = None       #: default: fixed for parameters, else continuous
    depends_on: tuple[str, ...] = ()     #: outputs: inputs with direct feedthrough
    min: float | None = None             #: smallest value a parameter accepts
    max: float | None = None             #: largest value a parameter accepts
    #: the FMI names of its elements when they are not the structured names ``name[i]``
    #: (a vehicle FMU of the user's, its scalar variables through the port map); None: those
    scalars: tuple[str, ...] | None = None

    @property
    def elements(self) -> list[str]:
        """The FMI names of its elements, row major: :attr:`scalars`, else
        :func:`element_names` of its name and shape."""
        return list(self.scalars) if self.scalars is not None else \
            element_names(self.name, self.shape)

    @property
    def size(self) -> int:
        """Number of scalar elements (1 for a scalar)."""
        return int(np.prod(self.shape)) if self.shape else 1

    @property
    def fmi_variability(self) -> str:
        """The FMI variability: ``variability`` if set, else fixed / discrete / continuous."""
        if self.variability:
            return self.variability
        if self.causality == "parameter":
            return "fixed"
        return "discrete" if self.type != "Real" else "continuous"


def element_names(name: str, shape: tuple[int, ...]) -> list[str]:
    """FMI structured names of the elements of an array, row major.

    Parameters
    ----------
    name : str
        The array's name.
    shape : tuple[int, ...]
        Its shape; () for a scalar.

    Returns
    -------
    list[str]
        ``name[i,j,...]`` with 1-based indices, or ``[name]`` for a scalar.
    """
    return list(_element_names(name, tuple(shape)))


@functools.lru_cache(maxsize=4096)
def _element_names(name: str, shape: tuple[int, ...]) -> tuple[str, ...]:
    """:func:`element_names`, kept: a fleet asks for the same arrays' names per vehicle."""
    if not shape:
        return (name,)
    return tuple(f"{name}[{','.join(str(i + 1) for i in ix)}]" for ix in np.ndindex(*shape))


def expand(specs: list[ArraySpec]) -> Iterator[tuple[ArraySpec, int, str]]:
    """(spec, flat index, scalar name) for every scalar variable, in registration order.

    Parameters
    ----------
    specs : list[ArraySpec]
        The interface table.

    Yields
    ------
    tuple[ArraySpec, int, str]
        The array, the element's row-major flat index and its FMI name.
    """
    for spec in specs:
        for i, nm in enumerate(element_names(spec.name, spec.shape)):
            yield spec, i, nm
