"""The README's tour: every ``.venv/bin/auv-cosim ...`` line parses, and runs as typed.

The tour's commands are read from the README itself: each fenced ``sh`` block of
``.venv/bin/auv-cosim`` lines in the section "A tour", followed by a ``text`` block with
what they printed. Every command must be accepted by the command line's parser. The
short ones (the paper with a ``--T`` of at most 100 s, ``plot`` of such a run, the
exports of the paper) run here in a temporary folder; the long ones (fleets, campaigns,
minutes of runs) are parsed only, to keep the suite within its time. Each run must exit 0
and leave the files its printed output names (``out/...`` paths, and the files an export
lists in its folder).
"""
from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

from orchestrator.cli.parser import build_parser

ROOT = Path(__file__).resolve().parent.parent
PREFIX = ".venv/bin/auv-cosim"
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)
OUT_PATH = re.compile(r"(?<![\w/.-])out/[\w./-]*[\w]")
LISTED = re.compile(r" in (out/[\w./-]*\w): (.*)")
FILE_NAME = re.compile(r"[\w.-]+\.(?:xml|fmu|ssp)\b")
FAST_T = 100.0   # s: a paper run or compare of at most this horizon takes a few seconds


@dataclass
class Step:
    commands: list[list[str]]    # argument lists, without the program
    printed: str                 # the text block after them ("" if none)

    def expected_files(self) -> set[str]:
        """The files and folders the printed output says were written."""
        found = set(OUT_PATH.findall(self.printed))
        for line in self.printed.splitlines():
            m = LISTED.search(line)
            if m:
                found.update(f"{m.group(1)}/{name}" for name in FILE_NAME.findall(m.group(2)))
        return found


def tour_steps() -> list[Step]:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    start = text.index("\n## A tour")
    end = text.find("\n## ", start + 1)
    blocks = FENCE.findall(text[start:end if end > 0 else None])
    steps = []
    for i, (lang, body) in enumerate(blocks):
        lines = [ln for ln in body.replace("\\\n", " ").splitlines() if ln.strip()]
        if lang != "sh" or not lines or not all(ln.startswith(PREFIX) for ln in lines):
            continue
        printed = blocks[i + 1][1] if i + 1 < len(blocks) and blocks[i + 1][0] == "text" else ""
        steps.append(Step([shlex.split(ln, comments=True)[1:] for ln in lines], printed))
    return steps


STEPS = tour_steps()
COMMANDS = [argv for step in STEPS for argv in step.commands]


def _option(argv: list[str], name: str) -> str | None:
    return argv[argv.index(name) + 1] if name in argv else None


def is_fast(argv: list[str], fast_outputs: set[str]) -> bool:
    """A command of a few seconds: the paper over a short horizon, a plot of such a run,
    an export of the paper."""
    command = argv[0]
    paper = _option(argv, "--scenario") in (None, "paper")
    if command in ("run", "compare"):
        T = _option(argv, "--T")
        return paper and T is not None and float(T) <= FAST_T
    if command == "plot":
        return argv[1] in fast_outputs
    if command == "export":
        return paper and (argv[1] != "native" or _c_compiler())
    return False


def _c_compiler() -> bool:
    return bool(os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc"))


def test_the_readme_has_a_tour_of_commands():
    assert len(STEPS) >= 8 and len(COMMANDS) >= 10
    subcommands = {argv[0] for argv in COMMANDS}
    assert {"run", "compare", "plot", "campaign", "export"} <= subcommands
    for step in STEPS:
        assert step.printed, f"no printed output after {step.commands}"


@pytest.mark.parametrize("argv", COMMANDS, ids=shlex.join)
def test_every_tour_command_parses(argv):
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:      # argparse reports the error on stderr and exits 2
        pytest.fail(f"auv-cosim {shlex.join(argv)}: the parser refused it (exit {e.code})")
    assert args.command == argv[0]


def _run_in(folder: Path, argv: list[str]) -> None:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    proc = subprocess.run([sys.executable, "-m", "orchestrator", *argv], cwd=folder, env=env,
                          capture_output=True, text=True, timeout=1800)
    assert proc.returncode == 0, (f"auv-cosim {shlex.join(argv)} exited {proc.returncode}:\n"
                                  f"{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}")


def _workspace(tmp_path: Path) -> Path:
    # the tour is typed in the clone's folder: its files (docs/examples/sweep.toml) are there
    (tmp_path / "docs").symlink_to(ROOT / "docs", target_is_directory=True)
    return tmp_path


def _check_files(folder: Path, step: Step) -> None:
    missing = sorted(f for f in step.expected_files() if not (folder / f).exists())
    assert not missing, f"{step.commands}: the README says it wrote {missing}, which are not there"


@pytest.mark.slow
def test_the_fast_tour_commands_run_and_write_what_the_readme_says(tmp_path):
    folder = _workspace(tmp_path)
    fast_outputs: set[str] = set()
    ran = 0
    for step in STEPS:
        if not all(is_fast(argv, fast_outputs) for argv in step.commands):
            continue
        for argv in step.commands:
            _run_in(folder, argv)
            ran += 1
        _check_files(folder, step)
        # a folder written here may be plotted by a later fast step
        fast_outputs.update(str(Path(p).parent) for p in step.expected_files()
                            if p.endswith("summary.json"))
    assert ran >= 3, "the README's tour has no short command left to run here"
