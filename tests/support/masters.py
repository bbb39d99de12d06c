"""The paper's loop on both kinds of FMU, for the tests of the masters: pythonfmu FMUs
run by the Python master, native FMUs (when a C compiler is here) by the compiled one."""
from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import pytest

from orchestrator.interop.native import native_system
from orchestrator.running import build, scenario_system
from orchestrator.scenario import load_scenario


def paper_systems(folder: Path, T: float) -> tuple[Any, Any, dict, Any]:
    """(scenario, system, FMUs, native system or None) of the paper's loop over T s."""
    sc = load_scenario("paper").with_run(T=T)
    system, fmus = scenario_system(sc), build(sc, folder / "py")
    native = (native_system(system, fmus, folder / "native")
              if shutil.which("cc") is not None else None)
    return sc, system, fmus, native


def on_master(paper: tuple, master: str) -> tuple[Any, dict]:
    """(system, FMUs) the ``master`` runs: the pythonfmu ones for ``python``, the native
    ones for ``native`` (the test is skipped without a C compiler)."""
    _, system, fmus, native = paper
    if master == "native":
        if native is None:
            pytest.skip("no C compiler (cc) for the native FMUs and the compiled master")
        return native.system, native.fmus
    return system, fmus
