"""Runs made once for the tests of the figures, and the figures built from a run folder."""
from __future__ import annotations

from pathlib import Path
from typing import Any

from orchestrator.cli import main
from orchestrator.plotting import build_figures, deterministic_style, load_run


def made_runs(base: Path, commands: dict[str, list[str]]) -> dict[str, Path]:
    """Each command (name -> its arguments) run quietly into ``base / name``."""
    for name, argv in commands.items():
        assert main([*argv, "--out", str(base / name), "--quiet"]) == 0
    return {name: base / name for name in commands}


def figures_of(folder: Path) -> dict[str, Any]:
    """The figures ``plot`` makes of a run folder, by name (the tests' fixed style)."""
    with deterministic_style():
        return {pf.name: pf for pf in build_figures(load_run(folder))}
