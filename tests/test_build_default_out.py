"""``auv-cosim build`` never writes into the checkout's tracked tree: with no ``--out`` it
builds into ``out/<scenario>[_<system>]_fmus`` under the working folder, like the other
commands, with the README of that scenario's variables there, and the committed
``fmus/README.md`` (the paper scenario's) is left as it was."""
from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

import pytest

from orchestrator.cli.fmus import BUILD_TAIL
from orchestrator.cli.parser import build_parser
from orchestrator.running.naming import default_out
from orchestrator.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]


def _tree(folder: Path) -> dict[str, str]:
    """Every file under ``folder`` (relative name -> SHA-256 of its bytes)."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def test_the_default_build_folder_is_under_out():
    args = build_parser().parse_args(["build", "--scenario", "formation-4"])
    assert args.out is None                      # the command picks the folder
    assert default_out(load_scenario("formation-4"), BUILD_TAIL) == Path(
        "out/formation-4_fmus")


@pytest.mark.slow
def test_build_formation_4_with_the_default_out_leaves_fmus_readme_alone(tmp_path):
    """The real command, in a fresh working folder: everything lands in
    out/formation-4_fmus there; the checkout's fmus/ is byte for byte what it was."""
    before = _tree(ROOT / "fmus")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]))
    done = subprocess.run([sys.executable, "-m", "orchestrator", "build", "--scenario",
                           "formation-4"], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert _tree(ROOT / "fmus") == before
    out = tmp_path / "out" / "formation-4_fmus"
    assert [p.name for p in tmp_path.iterdir()] == ["out"]
    # beside the folder only its hidden lock (orchestrator/outputs.py: the folder is swapped)
    assert [p.name for p in (tmp_path / "out").iterdir() if not p.name.endswith(".lock")] \
        == ["formation-4_fmus"]
    assert sorted(p.name for p in out.glob("*.fmu")) == [
        "AuvAutopilot.fmu", "AuvController.fmu", "AuvEstimator.fmu", "AuvGuidance.fmu",
        "AuvPlant.fmu"]
    readme = (out / "README.md").read_text()
    assert "the built-in `formation-4` scenario" in readme
    assert (out / "crosscheck" / "AuvPlant" / "AuvPlant_ref.csv").is_file()
    assert "out/formation-4_fmus/AuvPlant.fmu" in done.stdout
