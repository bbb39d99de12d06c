"""``auv-cosim export native``: the scenario's designed FMUs as native (C) FMUs, with an
OSP system and an SSP archive that wire them.

For every component of the scenario's system (:func:`orchestrator.running.scenario_system`:
the stacked plant, estimator and controller, or per vehicle its vehicle, estimator and
controller and the leader) the pythonfmu slave is set up once in this process and its linear
form taken (:func:`orchestrator.cosim.native.form_of`). One native FMU is built per kind,
with the first component's values as start values; every other component of the kind gets
its own values as a parameter set in the OSP and SSP files. The wiring is the pythonfmu
system's: the native FMUs have the same inputs and outputs. An acoustic network ships as
``AuvNetworkNative`` (its own C model with the pythonfmu FMU's variables,
:mod:`orchestrator.cosim.native_network`); with navigation sensors the estimator ships
as the native multi-rate filter (:mod:`orchestrator.cosim.native_multirate`). The
nonlinear REMUS 100 vehicles (remus100-6dof, remus100-6dof-guided) are native with a C
model of their own (:mod:`orchestrator.cosim.native_remus`). What stays pythonfmu and
needs Python: the linear vehicle FMU with navigation sensors (its report schedule and
dropouts). For REMUS 100 scenarios the guidance interface ships beside the system as
native FMUs too (``AuvGuidanceNative``, ``AuvAutopilotNative``: a C model each with the
pythonfmu FMU's interface, :mod:`orchestrator.cosim.native_guidance`, docs/guidance.md).
"""
from __future__ import annotations

import tempfile
from collections.abc import Sequence
from pathlib import Path

from ..cosim.native import NativeSystem, native_system
from ..outputs import file_stem
from ..scenario import Scenario

__all__ = ["NativeSystem", "export_native", "native_system"]  # the last two: cosim.native


def export_native(sc: Scenario, out_dir: Path | str,
                  platforms: Sequence[str] | None = None) -> dict[str, Path]:
    """Native FMUs of the scenario's design, an OSP system and an SSP archive in ``out_dir``.

    Parameters
    ----------
    sc : Scenario
        The scenario (its deployment, estimator, tracking law, architecture and seed).
    out_dir : Path or str
        Destination folder.
    platforms : Sequence[str] or None, optional
        The platforms the native FMUs carry binaries for
        (:func:`orchestrator.cosim.native_build.compile_fmu`); default the host's.

    Returns
    -------
    dict[str, Path]
        FMU key -> .fmu, ``"system"`` -> OspSystemStructure.xml, ``"ssp"`` -> the archive.
    """
    from ..running.systems import build, scenario_system
    from .export_set import export_set
    from .osp import write_osp
    from .ssp import write_ssp

    out = Path(out_dir)
    system = scenario_system(sc)
    with tempfile.TemporaryDirectory(prefix="auv_native_py_") as tmp:
        py = build(sc, Path(tmp))
        ns = native_system(system, py, out, platforms=platforms)
        kept = {k: p for k, p in ns.fmus.items() if k not in ns.native_keys}
        for k, p in kept.items():                  # the pythonfmu FMUs left, if any
            target = out / Path(p).name
            target.write_bytes(Path(p).read_bytes())
            ns.fmus[k] = target
        export = export_set(sc, out, system=ns.system, fmus=ns.fmus)
        paths = write_osp(export, out)
        paths["ssp"] = write_ssp(export, out / f"{file_stem(sc.name)}-native.ssp")
    return paths
