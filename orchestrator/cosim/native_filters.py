"""The native FMU of an estimator whose filter has no linear form, by its filter: the
multi-rate navigation filter (:mod:`.native_multirate`) or the time-varying Kalman filter
from P0 (:mod:`.native_tvkf`)."""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from fmu_common.interface import ArraySpec
from plant_model.linalg_checks import ModelError

from .native_multirate import KIND, multirate_components
from .native_tvkf import tv_components

__all__ = ["filter_components"]


def filter_components(kind: str, components: list[Any], fmu: Path | str, out_dir: Path | str,
                      T: float, platforms: Sequence[str] | None = None
                      ) -> tuple[Path, dict[str, tuple[tuple[ArraySpec, ...], dict[str, float]]]]:
    """The native FMU of estimator components whose filter has no linear form: the
    multi-rate navigation filter, or the time-varying Kalman filter from P0 (by the filter
    the first component's slave makes); the arguments and result as
    :func:`multirate_components`."""
    from estimator_fmu.kalman_tv import TimeVaryingKalman

    from .native_template import component_slave
    with component_slave(kind, Path(fmu), components[0].parameters) as slave:
        tv = isinstance(slave.estimator, TimeVaryingKalman)
    if tv:
        return tv_components(kind, components, fmu, out_dir, T, platforms)
    if kind != KIND:
        raise ModelError(f"the {kind} FMU's estimator has no native form")
    return multirate_components(components, fmu, out_dir, T, platforms)
