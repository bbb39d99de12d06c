"""The pythonfmu slave a native FMU is made from, set up in this process: one template
slave per FMU configuration (a fleet has one FMU file per kind and a hundred components of
it: making the slave, its variables registered, was most of a native build's time), set
to one component's parameters at a time under a lock. Shared by the linear forms
(:mod:`orchestrator.cosim.native`), the REMUS 100 (:mod:`orchestrator.cosim.native_remus`)
and the multi-rate filter (:mod:`orchestrator.cosim.native_multirate`).
"""
from __future__ import annotations

import functools
import importlib
import tempfile
import threading
import zipfile
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from fmu_common.interface import ArraySpec, element_names

from .build import FMU_KINDS

__all__ = ["component_slave", "scalar_arrays"]

#: serializes the use of the template slaves (a Dask worker may run threads)
_TEMPLATE_LOCK = threading.Lock()


def scalar_arrays(specs: list[ArraySpec], values: Mapping[str, Any]) -> dict[str, Any]:
    """Per parameter array its value: the start value with the component's scalars set."""
    out: dict[str, Any] = {}
    for s in specs:
        if s.causality != "parameter":
            continue
        if s.type == "String":
            out[s.name] = str(values.get(s.name, s.start))
            continue
        arr = np.array(s.start if s.start is not None else 0.0,
                       dtype=float if s.type == "Real" else np.int64).reshape(s.shape)
        flat = arr.reshape(-1)
        for i, nm in enumerate(element_names(s.name, s.shape)):
            if nm in values:
                flat[i] = values[nm]
        out[s.name] = arr
    return out


@functools.lru_cache(maxsize=16)
def _template_slave(kind: str, config: str) -> Any:
    """One slave of ``kind`` made from an FMU's configuration file (its text: the key)."""
    k = FMU_KINDS[kind]
    cls = getattr(importlib.import_module(k.module), k.model)
    with tempfile.TemporaryDirectory(prefix="auv_native_") as res:
        (Path(res) / k.config_file).write_text(config)
        return cls(instance_name=f"native-{kind}", resources=res)


@contextmanager
def component_slave(kind: str, fmu: Path | str, parameters: Mapping[str, Any]) -> Iterator[Any]:
    """The template slave of ``kind`` for the configuration inside the built pythonfmu
    ``fmu``, with every parameter array set (its start value with the component's scalars,
    so what an earlier component set is gone) and ``setup()`` run; the block has it alone.

    Parameters
    ----------
    kind : str
        The FMU kind (a key of FMU_KINDS).
    fmu : Path or str
        The built pythonfmu FMU (its configuration is read from resources/).
    parameters : Mapping[str, Any]
        The component's parameter values (FMI scalar names).

    Yields
    ------
    Any
        The set-up slave: copy what the block keeps, the next component reuses it.
    """
    with zipfile.ZipFile(fmu) as z:
        config = z.read(f"resources/{FMU_KINDS[kind].config_file}").decode()
    slave = _template_slave(kind, config)
    with _TEMPLATE_LOCK:
        slave.par.update(scalar_arrays(slave.specs, parameters))
        slave.setup()
        yield slave
