"""``auv-cosim export native``: the scenario's designed FMUs as native (C) FMUs, with an
OSP system and an SSP archive that wire them.

For every component of the scenario's system (:func:`orchestrator.running.scenario_system`:
the stacked plant, estimator and controller, or per vehicle its vehicle, estimator and
controller and the leader) the pythonfmu slave is set up once in this process and its linear
form taken (:func:`orchestrator.cosim.native.form_of`). One native FMU is built per kind,
with the first component's values as start values; every other component of the kind gets
its own values as a parameter set in the OSP and SSP files. The wiring is the pythonfmu
system's: the native FMUs have the same inputs and outputs. What is not linear stays
pythonfmu and needs Python: an acoustic network, the nonlinear vehicle (remus100-6dof),
and the vehicle and estimator FMUs with navigation sensors (their schedule, dropouts and
time-varying filter).
"""
from __future__ import annotations

import dataclasses
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from fmu_common.native_form import NativeForm

from ..cosim.native import (
    NATIVE_KINDS,
    build_native_fmu,
    form_of,
    native_model,
    native_parameters,
    native_specs,
)
from ..cosim.system import SystemDescription
from ..outputs import file_stem
from ..scenario import Scenario
from .common import ExportError

__all__ = ["NativeSystem", "export_native", "native_system"]


@dataclasses.dataclass(frozen=True)
class NativeSystem:
    """A system whose linear components are native FMUs."""

    system: SystemDescription            #: the same wiring, native interfaces and parameters
    fmus: dict[str, Path]                #: FMU key -> .fmu (native, or pythonfmu: network)
    forms: dict[str, NativeForm]         #: component -> its linear form


def native_system(system: SystemDescription, fmus: Mapping[str, Path], out_dir: Path | str,
                  kinds: tuple[str, ...] = NATIVE_KINDS) -> NativeSystem:
    """Build native FMUs for the components of ``kinds`` and the system that uses them.

    Parameters
    ----------
    system : SystemDescription
        The pythonfmu system.
    fmus : Mapping[str, Path]
        Its built pythonfmu FMUs (FMU key -> path).
    out_dir : Path or str
        Where the native FMUs go.
    kinds : tuple[str, ...], optional
        The FMU kinds to replace (default: every linear one).

    Returns
    -------
    NativeSystem
        The system with native components; the other components as they were.

    Raises
    ------
    ExportError
        If two components of one kind have forms of different shapes (one line each).
    """
    forms: dict[str, NativeForm] = {}
    for kind in dict.fromkeys(c.fmu for c in system.components if c.fmu in kinds):
        try:
            forms.update({c.name: form_of(c.fmu, Path(fmus[c.fmu]), c.parameters)
                          for c in system.components if c.fmu == kind})
        except NotImplementedError:         # not linear in this system (navigation sensors):
            continue                        # its pythonfmu FMU stays
    # a static law works at any step; its h is the system's, for the default experiment
    forms = {k: dataclasses.replace(f, h=system.h) if f.static else f for k, f in forms.items()}
    base: dict[str, NativeForm] = {}
    for c in system.components:
        if c.name in forms:
            base.setdefault(c.fmu, forms[c.name])
    problems = [f"{c.name}: its {c.fmu} form does not have the shape of "
                f"{next(d.name for d in system.components if d.fmu == c.fmu)}'s"
                for c in system.components if c.name in forms
                and _shape(forms[c.name]) != _shape(base[c.fmu])]
    if problems:
        raise ExportError(problems)
    built = {k: build_native_fmu(f, native_model(k), out_dir, system.T, system.h)
             for k, f in base.items()}
    comps = tuple(dataclasses.replace(c, interface=tuple(native_specs(forms[c.name])),
                                      parameters=native_parameters(forms[c.name], base[c.fmu]))
                  if c.name in forms else c for c in system.components)
    # a connection that carries data only for some value of a replaced component's
    # parameter (the truth in mode "ideal"): the native form has that value built in
    conns = tuple(dataclasses.replace(c, when=None) if c.when and c.when[0] in forms
                  and system.active(c) else c for c in system.connections)
    paths = {k: Path(v) for k, v in fmus.items()}
    paths.update(built)
    return NativeSystem(system=dataclasses.replace(system, components=comps, connections=conns),
                        fmus=paths, forms=forms)


def _shape(f: NativeForm) -> tuple[Any, ...]:
    # the noise streams are built in, but for the key of a single keyed one (a parameter)
    streams = tuple((None if f.stream is not None else k, c) for k, c in f.noise_streams)
    return (f.nq, f.nu, f.ny, f.nxi, f.stream is not None, streams,
            tuple((r.key, r.name, r.value.shape) for r in f.roles))


def export_native(sc: Scenario, out_dir: Path | str) -> dict[str, Path]:
    """Native FMUs of the scenario's design, an OSP system and an SSP archive in ``out_dir``.

    Parameters
    ----------
    sc : Scenario
        The scenario (its deployment, estimator, tracking law, architecture and seed).
    out_dir : Path or str
        Destination folder.

    Returns
    -------
    dict[str, Path]
        FMU key -> .fmu, ``"system"`` -> OspSystemStructure.xml, ``"ssp"`` -> the archive.
    """
    from ..running import build, scenario_system
    from .osp import export_osp
    from .ssp import export_ssp

    out = Path(out_dir)
    system = scenario_system(sc)
    with tempfile.TemporaryDirectory(prefix="auv_native_py_") as tmp:
        py = build(sc, Path(tmp))
        ns = native_system(system, py, out)
        kept = {k: p for k, p in ns.fmus.items() if k not in NATIVE_KINDS}
        for k, p in kept.items():                  # the network's pythonfmu FMUs, if any
            target = out / Path(p).name
            target.write_bytes(Path(p).read_bytes())
            ns.fmus[k] = target
        paths = export_osp(sc, out, system=ns.system, fmus=ns.fmus)
        paths["ssp"] = export_ssp(sc, out / f"{file_stem(sc.name)}-native.ssp",
                                  fmus=ns.fmus, system=ns.system)
    return paths
