"""The native (C) time-varying Kalman filter from P0 (``kalman-tv``): an estimator FMU.

Its gain follows the Riccati difference equation (:class:`estimator_fmu.kalman_tv.
TimeVaryingKalman`), so it has no fixed linear form (:mod:`fmu_common.native_form`). Its
native FMU is fmu_common/native/tvkf_fmu.c, which runs the filter from the design the
pythonfmu slave makes, on the navigation filter's state and Kalman core
(multirate_model.h, kalman_core.h) and the same header and modelDescription writers
(:mod:`orchestrator.cosim.native_multirate`):

- parameters ``Ad``, ``Bd``, ``Qd`` (the model sampled at h), ``Rd`` (the measurement
  covariance per sample), ``Mm`` (the measurement matrix), ``P0``, ``q0`` and ``h``; the
  slave's inputs (stacked: ``y``, ``ybar``, ``x``, ``w``, ``z``, ``u``; per vehicle: ``y``,
  ``x``, ``w``, ``u``) and outputs (the estimate), names and order unchanged;
- the same filter step by step, equal to the pythonfmu one to rounding.

The stacked deployment's ``estimator`` and the per-vehicle ``vehicle_estimator`` both use it.
"""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from fmu_common.interface import ArraySpec, element_names
from plant_model.linalg_checks import ModelError

from .native_build import arrays_model_description, compile_fmu, native_model
from .native_multirate import MULTIRATE_H, TVKF_C, _header, changed_starts

__all__ = ["tv_components", "tv_specs"]


def _design(kind: str, fmu: Path, parameters: Any) -> tuple[tuple, list[ArraySpec],
                                                            list[ArraySpec]]:
    """(design, inputs, outputs) of a component's time-varying filter (its slave set up)."""
    from estimator_fmu.kalman_tv import TimeVaryingKalman

    from .native_template import component_slave
    with component_slave(kind, fmu, parameters) as slave:
        est = slave.estimator
        if not isinstance(est, TimeVaryingKalman):
            raise ModelError(f"{kind}: this estimator is not the time-varying Kalman filter")
        inputs, outputs = slave.io_specs()
        kf = (est.Ad.copy(), est.Bd.copy(), est.Qd.copy(), est.P0.copy(), est.q0.copy(),
              est.Rd.copy(), est.Mm.copy(), float(slave.par["h"]))
    return kf, list(inputs), list(outputs)


def tv_specs(kf: tuple, inputs: list[ArraySpec], outputs: list[ArraySpec]) -> list[ArraySpec]:
    """The native FMU's arrays: the design's parameters, then the slave's inputs, outputs."""
    Ad, Bd, Qd, P0, q0, Rd, Mm, h = kf
    return [
        ArraySpec("Ad", Ad.shape, "parameter", "the model sampled at h: s+ = Ad s + Bd u",
                  start=Ad),
        ArraySpec("Bd", Bd.shape, "parameter", "the input's effect over one step", start=Bd),
        ArraySpec("Qd", Qd.shape, "parameter", "process noise covariance over one step",
                  start=Qd),
        ArraySpec("P0", P0.shape, "parameter", "the filter's start covariance (prior at t = 0)",
                  start=P0),
        ArraySpec("q0", q0.shape, "parameter", "the filter's start estimate", start=q0),
        ArraySpec("Rd", Rd.shape, "parameter", "measurement noise covariance per sample",
                  start=Rd),
        ArraySpec("Mm", Mm.shape, "parameter", "the measurement matrix: meas = Mm s + noise",
                  start=Mm),
        ArraySpec("h", (), "parameter", "the sample period the design is for", start=h,
                  unit="s"),
        *inputs, *outputs]


def _vr(specs: list[ArraySpec], name: str) -> int:
    vr = 0
    for s in specs:
        if s.name == name:
            return vr
        vr += len(element_names(s.name, s.shape))
    raise KeyError(name)


def tv_components(kind: str, components: list[Any], fmu: Path | str, out_dir: Path | str,
                  T: float, platforms: Sequence[str] | None = None
                  ) -> tuple[Path, dict[str, tuple[tuple[ArraySpec, ...], dict[str, float]]]]:
    """The native filter FMU for the estimator components of ``kind`` of a system, and per
    component its native interface and parameter values (those that differ from the first
    component's, the FMU's start values).

    Raises
    ------
    NativeBuildError
        No compiler, or the compiler failed.
    ModelError
        If a component's filter does not have the first one's shape.
    """
    first = components[0]
    base, inputs, outputs = _design(kind, Path(fmu), first.parameters)
    specs = tv_specs(base, inputs, outputs)
    model = native_model(kind)
    meas, est = inputs[0].name, outputs[0].name
    extra = (f"#define NY {base[5].shape[0]}", f"#define VR_MEAS {_vr(specs, meas)}",
             f"#define VR_EST {_vr(specs, est)}")
    kf8 = (*base[:5], np.zeros(7), 0.0, base[7], base[0].shape[0])   # _header's tuple
    path = compile_fmu(
        model, TVKF_C, MULTIRATE_H, lambda g: _header(specs, kf8, g, extra),
        lambda g: arrays_model_description(
            specs, model, g, "Time-varying Kalman filter from P0 (kalman-tv; native C build "
            "of the design, no Python)", TVKF_C, T=T, h=base[7]), out_dir, platforms)
    out = {}
    for c in components:
        kf = base if c is first else _design(kind, Path(fmu), c.parameters)[0]
        if any(a.shape != b.shape for a, b in zip(kf[:7], base[:7])):
            raise ModelError(f"{c.name}: its filter does not have the shape of {first.name}'s")
        out[c.name] = (tuple(specs), _changed(kf, base))
    return path, out


def _changed(kf: tuple, base: tuple) -> dict[str, float]:
    return changed_starts(tv_specs(kf, [], []), tv_specs(base, [], []))
