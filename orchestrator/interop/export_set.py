"""What an exporter writes, with no scenario in it: the system, its FMUs, the FMUs shipped
beside it for a host's own vehicle stack, and per signal element its unit and vehicle.

:func:`export_set` makes one from a scenario (the one place an export meets a scenario:
its system, its FMUs built, its vehicle models' units); the writers
(:func:`orchestrator.interop.osp.write_osp`, :func:`orchestrator.interop.ssp.write_ssp`)
take an :class:`ExportSet` only, so another tool's system and FMUs export the same way.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from fmu_common.interface import ArraySpec

from ..cosim.system import SystemDescription
from ..scenario import Scenario
from .common import check_system

__all__ = ["ExportSet", "SignalElement", "export_set", "signal_layout"]


@dataclass(frozen=True)
class SignalElement:
    """One element of an input or output array: its unit and vehicle."""

    unit: str            #: "" when the quantity has no unit
    vehicle: int | None  #: 1-based vehicle, None outside a fleet
    component: str       #: e.g. "n", "v_e", "X_d"


@dataclass(frozen=True)
class ExportSet:
    """The module docstring's bundle."""

    system: SystemDescription
    #: FMU key -> its .fmu: the system's components' and those shipped beside it
    fmus: Mapping[str, Path]
    #: the FMUs shipped beside the system (a host's own vehicle stack: AuvGuidance,
    #: AuvAutopilot), FMU key -> their interfaces
    beside: Mapping[str, tuple[ArraySpec, ...]]
    #: signal (array) name -> per element its unit and vehicle (:func:`signal_layout`)
    elements: Mapping[str, list[SignalElement]]


def signal_layout(sc: Scenario, system: SystemDescription) -> dict[str, list[SignalElement]]:
    """Per element of each input and output array of the system's FMUs: its unit and
    vehicle (fleets of vehicle models with units), else unit-less elements."""
    sizes = {spec.name: spec.size for comp in system.components for spec in comp.interface
             if spec.causality in ("input", "output")}
    plain = {s: [SignalElement("", None, str(i + 1)) for i in range(n)]
             for s, n in sizes.items()}
    if sc.fleet is None:
        return plain
    models = sc.fleet.models
    per = {"x": ("state_names", "state_units"), "u": ("input_names", "input_units"),
           "w": ("disturbance_names", "disturbance_units"),
           "y": ("output_names", "output_units")}
    per.update({"xhat": per["x"], "what": per["w"], "e": per["y"], "ybar": per["y"]})
    out = dict(plain)
    for sig, (nattr, uattr) in per.items():
        elems = [SignalElement(u, i, nm) for i, mdl in enumerate(models, start=1)
                 for nm, u in zip(getattr(mdl, nattr), getattr(mdl, uattr))]
        if len(elems) == sizes.get(sig):      # else: keep the unit-less layout
            out[sig] = elems
    return out


def export_set(sc: Scenario, fmu_dir: Path | str, *, system: SystemDescription | None = None,
               fmus: Mapping[str, Path] | None = None) -> ExportSet:
    """The scenario's export: its system (default :func:`orchestrator.running.
    scenario_system`), checked before anything is built, and its FMUs (built into
    ``fmu_dir`` unless given), with those beside it and the signals' units.

    Raises
    ------
    ExportError
        If the wiring does not match the FMUs' interfaces (naming every problem).
    """
    from ..cosim.build import FMU_KINDS, GUIDANCE_KINDS, interface_of
    from ..running.fmus import guidance_configs
    from ..running.systems import build, scenario_system
    system = system or scenario_system(sc)
    check_system(system)            # nothing is built or written for a bad wiring
    fmus = dict(fmus) if fmus is not None else build(sc, Path(fmu_dir))
    configs = guidance_configs(sc)
    in_system = {c.fmu for c in system.components}
    beside = {k: tuple(interface_of(FMU_KINDS[k], configs[k])) for k in GUIDANCE_KINDS
              if k in fmus and k in configs and k not in in_system}
    return ExportSet(system, fmus, beside, signal_layout(sc, system))
