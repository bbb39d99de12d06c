"""What makes a run distinct, as a default output folder name and as the identity an output
folder records (:func:`orchestrator.outputs.check_claim`): the scenario, the deployment
and architecture, acoustic links, nonlinear vehicle models and the FMU kind; and a
campaign's default folder (:func:`campaign_out`), its name cleaned the same way.

A scenario file of the user's whose ``name`` is a built-in scenario's (a copy of
``formation-4.toml`` that kept ``name = "formation-4"``) never shares the built-in's
default folders nor its identity: its folder name is ``<name>_from-<file stem>``
(``out/formation-4_from-my-copy_compare``) and its identity's scenario says the file
(:func:`scenario_label`)."""
from __future__ import annotations

from pathlib import Path

from ..outputs import file_stem
from ..scenario import Scenario

__all__ = ["campaign_out", "default_export_out", "default_out", "run_identity", "run_tags",
           "scenario_label"]


def _shadowing_file(sc: Scenario) -> Path | None:
    """The user's scenario file of ``sc`` when its name is a built-in scenario's."""
    from ..scenario import SCENARIO_DIR, builtin_scenarios
    path = Path(sc.source)
    if sc.name not in builtin_scenarios() or not path.is_file():
        return None
    return None if path.resolve().parent == SCENARIO_DIR else path


def scenario_label(sc: Scenario) -> str:
    """The scenario's name in folder names: :func:`orchestrator.outputs.file_stem` of its
    name, ``<name>_from-<file stem>`` for a user's file named like a built-in."""
    shadow = _shadowing_file(sc)
    stem = file_stem(sc.name)
    return stem if shadow is None else f"{stem}_from-{file_stem(shadow.stem)}"


def run_tags(sc: Scenario) -> list[str]:
    """The parts of a folder name that tell this run's system apart: ``per-vehicle-<arch>``,
    ``links``, the nonlinear vehicle models, ``native``; none for the stacked pythonfmu loop
    over perfect links with linear vehicles (the paper's folders keep their names)."""
    tags = []
    if sc.deployment != "stacked":
        tags.append(f"{sc.deployment}-{sc.architecture}")
    if sc.network is not None:
        tags.append("links")
    models = sorted({sc.fleet.vehicles[i - 1].model
                     for i in sc.nonlinear_vehicles}) if sc.fleet is not None else []
    tags += models
    if sc.fmus != "python":
        tags.append(sc.fmus)
    return tags


def default_out(sc: Scenario, *tail: str) -> Path:
    """``out/<scenario>[_<tags>]_<tail>``, e.g. ``out/paper_kalman_seed0`` or
    ``out/formation-4_per-vehicle-distributed_links_native_compare``."""
    return Path("out") / "_".join([scenario_label(sc), *run_tags(sc), *tail])


def default_export_out(sc: Scenario, fmt: str) -> Path:
    """``export``'s default folder, ``out/<scenario>_<format>`` (:func:`scenario_label`)."""
    return Path("out") / f"{scenario_label(sc)}_{fmt}"


def campaign_out(name: str) -> Path:
    """``out/campaign_<name>``, the name cleaned as every default folder's
    (:func:`orchestrator.outputs.file_stem`: ``x/../../../escaped`` ->
    ``out/campaign_x_.._.._.._escaped``, one folder): a campaign never writes outside
    ``out/`` by default."""
    return Path("out") / f"campaign_{file_stem(name, 'campaign')}"


def run_identity(sc: Scenario, command: str) -> dict[str, str]:
    """What an output folder records about the run that writes it."""
    models = sorted(set(sc.fleet.model_names)) if sc.fleet is not None else []
    shadow = _shadowing_file(sc)
    name = sc.name if shadow is None else f"{sc.name} (file {shadow.resolve()})"
    return {"command": command, "scenario": name, "deployment": sc.deployment,
            "architecture": sc.architecture if sc.deployment != "stacked" else "-",
            "links": "yes" if sc.network is not None else "no",
            "vehicles": ",".join(m for m in models if m) or "-", "fmus": sc.fmus}
