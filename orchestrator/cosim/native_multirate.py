"""The native (C) multi-rate navigation filter: a vehicle estimator with ``[sensors]``.

With navigation sensors (acoustic fixes, DVL, depth at their own rates, with dropouts) a
vehicle's estimator is a time-varying Kalman filter (:class:`estimator_fmu.multirate.
MultiRateKalman`): its gain follows the covariance, and the covariance follows which
reports arrived, so it has no fixed linear form (:mod:`fmu_common.native_form`; a periodic
switching form would fit only a schedule without dropouts). Its native FMU
(``AuvVehicleEstimatorNative`` of a sensors run) is a C model of its own,
fmu_common/native/multirate_fmu.c, that runs the filter itself from the design the
pythonfmu slave makes (as the linear native FMUs take their designed matrices):

- parameters ``Ad``, ``Bd``, ``Qd`` (the vehicle sampled at h), ``P0`` (the filter's start
  covariance), ``q0``, ``Rd`` (the 7 report variances: fix, DVL, depth), ``current_max``
  and ``h``; the slave's inputs (``nav``, ``x``, ``w``, ``u``) and outputs (``xhat``,
  ``what``, fed through from the measurements), names and order unchanged;
- the same filter step by step, equal to the pythonfmu one to rounding (C sums in order and
  solves by Gaussian elimination, numpy by BLAS and LAPACK).
"""
from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from fmu_common.interface import ArraySpec, element_names
from plant_model.linalg_checks import ModelError

from .native_build import NATIVE_DIR, arrays_model_description, compile_fmu, native_model

__all__ = ["MULTIRATE_C", "multirate_specs", "native_multirate_fmu", "template_filter"]

MULTIRATE_C = (NATIVE_DIR / "fmu_core.c", NATIVE_DIR / "multirate_fmu.c")
MULTIRATE_H = (NATIVE_DIR / "fmu_core.h", NATIVE_DIR / "multirate_model.h",
               NATIVE_DIR / "named_reals.h", NATIVE_DIR / "kalman_core.h")
#: the time-varying Kalman filter from P0 (kalman-tv): the same state and Kalman core
TVKF_C = (NATIVE_DIR / "fmu_core.c", NATIVE_DIR / "tvkf_fmu.c")
KIND = "vehicle_estimator"


def template_filter(fmu: Path, parameters: Mapping[str, Any]) -> tuple[Any, list[ArraySpec],
                                                                        list[ArraySpec]]:
    """The MultiRateKalman of a component (its slave set up in this process with the
    component's parameter values), and the slave's input and output arrays.

    Raises
    ------
    ModelError
        If the component's estimator is not the multi-rate filter (no [sensors], or mode
        ideal: a linear form).
    """
    from estimator_fmu.multirate import MultiRateKalman

    from .native_template import component_slave
    with component_slave(KIND, fmu, parameters) as slave:
        est = slave.estimator
        if not isinstance(est, MultiRateKalman):
            raise ModelError("this vehicle estimator is linear: it has a native form")
        inputs, outputs = slave.io_specs()
        kf = (est.Ad.copy(), est.Bd.copy(), est.Qd.copy(), est.P0.copy(), est.q0.copy(),
              np.diag(est.R).copy(), est.current_max, float(slave.par["h"]), est._w.start)
    return kf, list(inputs), list(outputs)


def multirate_specs(kf: tuple, inputs: list[ArraySpec], outputs: list[ArraySpec]
                    ) -> list[ArraySpec]:
    """The native FMU's arrays: the design's parameters, then the slave's inputs, outputs."""
    Ad, Bd, Qd, P0, q0, Rd, cmax, h, _ = kf
    return [
        ArraySpec("Ad", Ad.shape, "parameter", "the vehicle [x; w] sampled at h: s+ = Ad s + "
                  "Bd u", start=Ad),
        ArraySpec("Bd", Bd.shape, "parameter", "the force's effect over one step", start=Bd),
        ArraySpec("Qd", Qd.shape, "parameter", "process noise covariance over one step",
                  start=Qd),
        ArraySpec("P0", P0.shape, "parameter", "the filter's start covariance (prior at t = 0)",
                  start=P0),
        ArraySpec("q0", q0.shape, "parameter", "the filter's start estimate [x0; w0]",
                  start=q0),
        ArraySpec("Rd", (7,), "parameter", "variances of the reports [fix (3), dvl (3), "
                  "depth]", start=Rd),
        ArraySpec("current_max", (), "parameter", "the largest current the filter believes, "
                  "per axis", start=float(cmax), unit="m/s", min=0.0),
        ArraySpec("h", (), "parameter", "the sample period the design is for", start=h,
                  unit="s"),
        *inputs, *outputs]


def native_parameters(kf: tuple, base: tuple) -> dict[str, float]:
    """A component's parameter values (FMI names) that differ from the FMU's start values."""
    return changed_starts(multirate_specs(kf, [], []), multirate_specs(base, [], []))


def changed_starts(specs: list[ArraySpec], ref: list[ArraySpec]) -> dict[str, float]:
    """The parameter values (FMI names) of ``specs`` that differ from those of ``ref`` (the
    same arrays: one component's design against the FMU's start values)."""
    out = {}
    for s, r in zip(specs, ref):
        for nm, v, w in zip(element_names(s.name, s.shape), np.ravel(s.start),
                            np.ravel(r.start)):
            if v != w:
                out[nm] = float(v)
    return out


def _header(specs: list[ArraySpec], kf: tuple, guid: str, extra: tuple[str, ...] = ()
            ) -> str:
    names, starts, causes = [], [], []
    for s in specs:
        st = np.ravel(s.start) if s.start is not None else np.zeros(s.size)
        for i, nm in enumerate(element_names(s.name, s.shape)):
            names.append(nm)
            starts.append(float(st[i]) if s.causality != "output" else 0.0)
            causes.append(s.causality)
    first: dict[str, int] = {}
    for vr, nm in enumerate(names):
        first.setdefault(re.sub(r"\[.*\]$", "", nm), vr)
    ns, m = kf[0].shape[0], kf[1].shape[1]
    return "\n".join([
        "/* generated by auv-cosim (orchestrator/cosim/native_multirate.py): see fmu_core.h",
        "   and multirate_fmu.c */",
        f'#define NATIVE_GUID "{guid}"',
        f"#define NPARR {causes.count('parameter')}", f"#define NIN {causes.count('input')}",
        f"#define NOUT {causes.count('output')}", f"#define NREAL {len(names)}",
        "#define NINT 0", f"#define STEP_VR {first['h']}", "#define START_AT_ZERO 1",
        f"#define NS {ns}", f"#define NX {kf[8]}", f"#define NU_ {m}", *extra,
        *(f"#define VR_{n} {vr}" for n, vr in first.items()),
        '#include "multirate_model.h"',
        "#ifdef NATIVE_MODEL_TABLES",
        "static const char *const REAL_NAMES[NREAL] = {",
        ",\n".join(f'    "{n}"' for n in names), "};",
        "static const double REAL_START[NREAL] = {",
        ",\n".join(f"    {v!r}" for v in starts), "};",
        "#endif", ""])


def _model_description(specs: list[ArraySpec], model: str, guid: str, T: float,
                       h: float) -> bytes:
    return arrays_model_description(
        specs, model, guid, "Navigation filter of one AUV: a multi-rate Kalman filter on "
        "[x; w] from acoustic fixes, DVL and depth with dropouts (native C build of the "
        "design, no Python)", MULTIRATE_C, T=T, h=h)


def native_multirate_fmu(fmu: Path | str, parameters: Mapping[str, Any], out_dir: Path | str,
                         T: float, platforms: Sequence[str] | None = None
                         ) -> tuple[Path, list[ArraySpec], tuple]:
    """The native multi-rate filter FMU of a vehicle estimator component.

    Parameters
    ----------
    fmu : Path or str
        The pythonfmu AuvVehicleEstimator FMU built with ``[sensors]``.
    parameters : Mapping[str, Any]
        The component's parameter values (its design: vehicle 1's in a fleet).
    out_dir : Path or str
        Destination folder; the FMU is ``AuvVehicleEstimatorNative.fmu``.
    T : float
        Stop time of the default experiment, s.
    platforms : Sequence[str] or None, optional
        The platforms it carries binaries for (:func:`compile_fmu`); default the host's.

    Returns
    -------
    tuple[Path, list[ArraySpec], tuple]
        The .fmu, its arrays, and the design (the start values).

    Raises
    ------
    NativeBuildError
        No compiler, or the compiler failed.
    ModelError
        If the estimator is not the multi-rate filter.
    """
    kf, inputs, outputs = template_filter(Path(fmu), parameters)
    specs = multirate_specs(kf, inputs, outputs)
    model = native_model(KIND)
    path = compile_fmu(model, MULTIRATE_C, MULTIRATE_H, lambda g: _header(specs, kf, g),
                       lambda g: _model_description(specs, model, g, T, kf[7]), out_dir,
                       platforms)
    return path, specs, kf


def multirate_components(components: list[Any], fmu: Path | str, out_dir: Path | str,
                         T: float, platforms: Sequence[str] | None = None
                         ) -> tuple[Path, dict[str, tuple[tuple[ArraySpec, ...],
                                                          dict[str, float]]]]:
    """The native filter FMU for the vehicle estimator components of a system, and per
    component its native interface and parameter values (those that differ from the first
    component's, which are the FMU's start values).

    Parameters
    ----------
    components : list[Component]
        The system's components of the vehicle estimator kind (all with [sensors]).
    fmu : Path or str
        Their pythonfmu FMU.
    out_dir : Path or str
        Destination folder.
    T : float
        Stop time of the default experiment, s.
    platforms : Sequence[str] or None, optional
        The platforms it carries binaries for (:func:`compile_fmu`); default the host's.

    Returns
    -------
    tuple[Path, dict[str, tuple[tuple[ArraySpec, ...], dict[str, float]]]]
        The .fmu, and component name -> (interface, parameters).
    """
    first = components[0]
    path, specs, base = native_multirate_fmu(fmu, first.parameters, out_dir, T, platforms)
    out = {}
    for c in components:
        kf = base if c is first else template_filter(Path(fmu), c.parameters)[0]
        if kf[0].shape != base[0].shape or kf[1].shape != base[1].shape:
            raise ModelError(f"{c.name}: its filter does not have the shape of {first.name}'s")
        out[c.name] = (tuple(specs), native_parameters(kf, base))
    return path, out
