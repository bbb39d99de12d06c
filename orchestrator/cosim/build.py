"""Build the three FMUs with pythonfmu and make their modelDescription.xml complete.

pythonfmu writes no units, no InitialUnknowns and no output dependencies; this module
adds them from the same interface tables the slaves register their variables from
(``fmu_common.interface.ArraySpec``), so ``fmpy validate`` reports no problem and a host
knows which outputs feed through from which inputs.
"""
from __future__ import annotations

import hashlib
import importlib
import io
import json
import os
import shutil
import sys
import tempfile
import time
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fmu_common.cache import fmu_cache_dir
from fmu_common.interface import ArraySpec

from ..atomic import copy_atomically
from .model_description import format_value, patch_model_description

__all__ = ["FMU_KINDS", "GUIDANCE_KINDS", "STACKED_KINDS", "FmuKind", "build_fmus", "build_key",
           "cached_fmu", "fmu_cache_dir", "fmu_config", "interface_of",
           "variables_markdown"]

ROOT = Path(__file__).resolve().parent.parent.parent


@dataclass(frozen=True)
class FmuKind:
    """Where a slave lives and what it ships."""

    model: str                      #: model identifier (= slave class name)
    module: str                     #: importable slave module
    packages: tuple[str, ...]       #: project packages copied into resources/
    config_file: str
    variable_step: bool             #: canHandleVariableCommunicationStepSize
    #: not built here: the user's own FMU (its configuration's ``fmu.path``), copied
    external: bool = False

    @property
    def script(self) -> Path:
        """Path of the slave's source file."""
        return ROOT / (self.module.replace(".", "/") + ".py")


#: the project packages copied into a slave's resources/, by the package of its module
SLAVE_PACKAGES = {"plant_model": ("plant_model", "fmu_common"),
                  "estimator_fmu": ("estimator_fmu", "plant_model", "fmu_common"),
                  "controller_fmu": ("controller_fmu", "plant_model", "fmu_common")}


def _built(key: str, model: str, module: str, variable_step: bool) -> tuple[str, FmuKind]:
    """An FMU built here: ``key`` -> its kind, the packages its module's package needs
    (:data:`SLAVE_PACKAGES`), its configuration ``auv_<key>_config.json``."""
    return key, FmuKind(model, module, SLAVE_PACKAGES[module.split(".")[0]],
                        f"auv_{key}_config.json", variable_step)


FMU_KINDS: dict[str, FmuKind] = dict([
    _built("plant", "AuvPlant", "plant_model.auv_plant_slave", False),
    _built("estimator", "AuvEstimator", "estimator_fmu.auv_estimator_slave", False),
    _built("controller", "AuvController", "controller_fmu.auv_controller_slave", True),
    # the per-vehicle deployment (orchestrator.cosim.per_vehicle)
    _built("vehicle", "AuvVehicle", "plant_model.auv_vehicle_slave", False),
    _built("remus6dof", "AuvRemus6dof", "plant_model.remus100.auv_remus6dof_slave", False),
    # the same vehicle driven by actuator commands (remus100-6dof-guided: AuvGuidance ->
    # AuvAutopilot -> it; orchestrator.cosim.guided)
    _built("remus6dof_actuated", "AuvRemus6dofActuated",
           "plant_model.remus100.auv_remus6dof_actuated_slave", False),
    _built("leader", "AuvLeader", "plant_model.auv_leader_slave", False),
    _built("vehicle_estimator", "AuvVehicleEstimator",
           "estimator_fmu.auv_vehicle_estimator_slave", False),
    _built("vehicle_controller", "AuvVehicleController",
           "controller_fmu.auv_vehicle_controller_slave", False),
    _built("central_controller", "AuvCentralController",
           "controller_fmu.auv_central_controller_slave", True),
    # one vehicle's acoustic inbox (plant_model.acoustic: links, inbox)
    _built("network", "AuvNetwork", "plant_model.acoustic.auv_network_slave", False),
    # the guidance interface (docs/guidance.md): beside the system for a host's own
    # vehicle, and in it for remus100-6dof-guided vehicles
    _built("guidance", "AuvGuidance", "controller_fmu.auv_guidance_slave", True),
    _built("autopilot", "AuvAutopilot", "plant_model.remus100.auv_autopilot_slave", True),
    # a vehicle the user brings as an FMU (model "fmu"): its file, its interface through
    # the port map (plant_model.vehicle_fmu.VehicleFmuPorts)
    ("vehicle_fmu", FmuKind("VehicleFmuPorts", "plant_model.vehicle_fmu", (), "", False,
                            external=True)),
])

#: the guidance interface: built beside a scenario's system for a host's own vehicle stack,
#: and per vehicle in it for a model whose ``stack`` names them
GUIDANCE_KINDS = ("guidance", "autopilot")

#: the FMUs of the stacked deployment (one plant, one estimator, one controller)
STACKED_KINDS = ("plant", "estimator", "controller")


def fmu_config(system_mapping: dict[str, Any], dims: dict[str, int], h: float, T: float,
               seed: int, estimator: str, tracking: str = "lq",
               fleet: dict[str, Any] | None = None) -> dict[str, Any]:
    """The JSON configuration an FMU is built with (dimensions and start values).

    For a fleet the FMUs get the fleet parameter interface (plant_model.fleet_parameters)
    and the stacked matrices are not shipped (they are rebuilt from the fleet spec).

    Parameters
    ----------
    system_mapping : dict[str, Any]
        :meth:`LinearSystem.to_mapping` of the system.
    dims : dict[str, int]
        The sizes n, m, r, p, l.
    h : float
        Communication step (sample period), s.
    T : float
        Stop time of the default experiment, s.
    seed : int
        Seed of the plant's noise.
    estimator : str
        The estimator (estimator_fmu.registry; the estimator FMU's ``mode`` parameter).
    tracking : str, optional
        Controller law ('lq' or 'regulator').
    fleet : dict[str, Any] or None, optional
        The resolved fleet spec, or None for a single system.

    Returns
    -------
    dict[str, Any]
        Keys system, dims, h, T, seed, estimator, tracking, fleet (JSON-ready).
    """
    if fleet is not None:
        system_mapping = {"noise_convention": system_mapping.get("noise_convention", "intensity")}
    return {"system": system_mapping, "dims": dims, "h": float(h), "T": float(T),
            "seed": int(seed), "estimator": estimator, "tracking": tracking, "fleet": fleet}


def interface_of(kind: FmuKind, config: dict[str, Any]) -> list[ArraySpec]:
    """The slave's interface table for ``config`` (parameters, inputs, outputs in order).

    Parameters
    ----------
    kind : FmuKind
        Which slave.
    config : dict[str, Any]
        The FMU's configuration (:func:`fmu_config`).

    Returns
    -------
    list[ArraySpec]
        The slave's arrays, parameters first, then inputs, then outputs.
    """
    module = importlib.import_module(kind.module)
    cls = getattr(module, kind.model)
    order = {"parameter": 0, "input": 1, "output": 2}
    return sorted(cls.interface(config), key=lambda s: order[s.causality])


def _rewrite_zip(path: Path, replacements: dict[str, bytes]) -> None:
    buf = io.BytesIO()
    with zipfile.ZipFile(path) as zin, zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.infolist():
            data = replacements.get(item.filename, None)
            zout.writestr(item.filename, data if data is not None else zin.read(item.filename))
    path.write_bytes(buf.getvalue())


def build_fmu(kind: FmuKind, config: dict[str, Any], out_dir: Path) -> Path:
    """Build one FMU into ``out_dir`` and patch its model description.

    Parameters
    ----------
    kind : FmuKind
        Which slave.
    config : dict[str, Any]
        The FMU's configuration (:func:`fmu_config`), shipped in resources/.
    out_dir : Path
        Destination folder (created if missing).

    Returns
    -------
    Path
        The .fmu file.
    """
    from pythonfmu.builder import FmuBuilder

    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="auv_build_") as tmp:
        tmp_path = Path(tmp)
        cfg_path = tmp_path / kind.config_file
        cfg_path.write_text(json.dumps(config, indent=1))
        staged = []
        for pkg in kind.packages:      # copy without caches so the FMU holds sources only
            dst = tmp_path / pkg
            shutil.copytree(ROOT / pkg, dst, ignore=shutil.ignore_patterns(
                "__pycache__", "*.pyc", "auv_*_slave.py"))
            staged.append(dst)
        script = kind.script
        # the slave script itself goes to the root of resources/ (a unique module name)
        script_root = tmp_path / "script"
        script_root.mkdir()
        shutil.copy2(script, script_root / script.name)
        sys.path.insert(0, str(ROOT))
        try:
            fmu = FmuBuilder.build_FMU(
                script_root / script.name, dest=out_dir,
                project_files=[*staged, cfg_path],
                canHandleVariableCommunicationStepSize=kind.variable_step,
                # FMU state: the slaves save and restore everything that evolves and
                # serialize it with a self-describing header (fmu_common.fmu_state)
                canGetAndSetFMUstate=True,
                canSerializeFMUstate=True,
            )
        finally:
            sys.modules.pop(script.stem, None)
    fmu = Path(fmu)
    with zipfile.ZipFile(fmu) as z:
        xml = z.read("modelDescription.xml")
    specs = interface_of(kind, config)
    _rewrite_zip(fmu, {"modelDescription.xml": patch_model_description(
        xml, specs, T=config["T"], h=config["h"])})
    return fmu


def build_key(kind: FmuKind, config: dict[str, Any]) -> str:
    """SHA-256 of everything that goes into an FMU.

    The configuration, the kind, every source file it ships, this build code (with the
    modelDescription completion, :mod:`.model_description`) and the pythonfmu version.

    Parameters
    ----------
    kind : FmuKind
        Which slave.
    config : dict[str, Any]
        The FMU's configuration.

    Returns
    -------
    str
        The hex digest.
    """
    from importlib.metadata import version

    h = hashlib.sha256()
    h.update(json.dumps(config, sort_keys=True).encode())
    h.update(repr(kind).encode())
    h.update(version("pythonfmu").encode())
    here = Path(__file__)
    files = [here, here.with_name("model_description.py")] + sorted(
        f for pkg in kind.packages for f in (ROOT / pkg).rglob("*.py")
        if "__pycache__" not in f.parts)
    for f in files:
        h.update(str(f.relative_to(ROOT)).encode())
        h.update(f.read_bytes())
    return h.hexdigest()


def prune_cache(cache: Path, max_age_s: float = 30 * 86400.0) -> None:
    """Remove the built FMUs and the native libraries and FMUs (``native/``) of the cache
    not used (read) for ``max_age_s``."""
    now = time.time()
    for f in [*cache.glob("*.fmu"), *cache.glob("native/*.fmu"), *cache.glob("native/*.so")]:
        try:
            if now - f.stat().st_atime > max_age_s:
                f.unlink()
        except OSError:
            pass


def cached_fmu(kind: FmuKind, config: dict[str, Any], cache: Path | None = None) -> Path:
    """The FMU of ``kind`` for ``config`` from the cache, built there first if missing.

    The build happens in a private folder and lands under its final name by one rename,
    so two processes building the same FMU at once both get a whole one.

    Parameters
    ----------
    kind, config
        As :func:`build_key`.
    cache : Path or None, optional
        The cache folder; default :func:`fmu_cache_dir`.

    Returns
    -------
    Path
        ``<cache>/<Model>-<key>.fmu``.
    """
    cache = Path(cache) if cache is not None else fmu_cache_dir()
    path = cache / f"{kind.model}-{build_key(kind, config)[:32]}.fmu"
    if path.exists():
        return path
    cache.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=".build-", dir=cache))
    try:
        os.replace(build_fmu(kind, config, work), path)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    prune_cache(cache)
    return path


def build_fmus(config: dict[str, Any], out_dir: Path | str, *,
               cache: bool = True,
               kinds: dict[str, dict[str, Any]] | None = None) -> dict[str, Path]:
    """The plant, estimator and controller FMUs for one configuration, in ``out_dir``.

    Parameters
    ----------
    config : dict[str, Any]
        The FMUs' configuration (:func:`fmu_config`).
    out_dir : Path or str
        Destination folder (created if missing); each ``<Model>.fmu`` is written
        atomically.
    cache : bool, optional
        Take identical builds from :func:`fmu_cache_dir` (a rebuild costs about 0.1 s per
        FMU); False builds afresh (a new GUID).
    kinds : dict[str, dict[str, Any]] or None, optional
        Key of :data:`FMU_KINDS` -> its own configuration (the per-vehicle deployment);
        default the stacked FMUs (:data:`STACKED_KINDS`), all built with ``config``.

    Returns
    -------
    dict[str, Path]
        'plant', 'estimator', 'controller' (or the keys of ``kinds``) -> the .fmu path.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths: dict[str, Path] = {}
    todo = kinds if kinds is not None else dict.fromkeys(STACKED_KINDS, config)
    for name, cfg in todo.items():
        kind = FMU_KINDS[name]
        dst = out / f"{kind.model}.fmu"
        if kind.external:                   # the user's FMU, under its own name
            src = Path(cfg["fmu"]["path"])
            dst = out / src.name
            copy_atomically(src, dst)
        elif cache:
            copy_atomically(cached_fmu(kind, cfg), dst)
        else:
            with tempfile.TemporaryDirectory(prefix="auv_build_") as tmp:
                copy_atomically(build_fmu(kind, cfg, Path(tmp)), dst)
        paths[name] = dst
    return paths


def _start_text(spec: ArraySpec) -> str:
    if spec.causality == "output":
        return ""
    v = spec.start
    if spec.type == "String":
        return f"`{v}`"
    arr = np.asarray(v if v is not None else 0.0)
    if arr.ndim == 0:
        return format_value(arr.item())
    return "`" + json.dumps(arr.tolist()) + "`"


def variables_markdown(config: dict[str, Any],
                       kinds: dict[str, dict[str, Any]] | None = None) -> str:
    """A table per FMU: name, causality, variability, unit, start, description.

    Parameters
    ----------
    config : dict[str, Any]
        The FMUs' configuration.
    kinds : dict[str, dict[str, Any]] or None, optional
        Key of :data:`FMU_KINDS` -> its configuration; default the stacked FMUs
        (:data:`STACKED_KINDS`), all with ``config``.

    Returns
    -------
    str
        Markdown, one section per FMU.
    """
    lines = []
    todo = kinds if kinds is not None else dict.fromkeys(STACKED_KINDS, config)
    for key, cfg in todo.items():
        kind = FMU_KINDS[key]
        lines += [f"### {kind.model}.fmu ({key})", "",
                  "| name | causality | variability | unit | start | description |",
                  "|---|---|---|---|---|---|"]
        for spec in interface_of(kind, cfg):
            if spec.shape:
                idx = ",".join(f"{'ijk'[a]}" for a in range(len(spec.shape)))
                rng = ", ".join(f"{'ijk'[a]}=1..{n}" for a, n in enumerate(spec.shape))
                name = f"`{spec.name}[{idx}]` ({rng})"
            else:
                name = f"`{spec.name}`"
            desc = spec.description
            if spec.depends_on:
                desc += f"; direct feedthrough from {', '.join(spec.depends_on)}"
            lines.append(f"| {name} | {spec.causality} | {spec.fmi_variability} | "
                         f"{spec.unit or ''} | {_start_text(spec)} | {desc} |")
        lines.append("")
    return "\n".join(lines)
