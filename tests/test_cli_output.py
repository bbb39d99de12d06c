"""What a user sees of a run's output: no progress-bar carriage returns when the output is
redirected, figures printed with their significant digits, and a last line naming a viewer
command that exists in this environment."""
from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_redirected_output_has_no_carriage_returns_and_a_working_viewer_line(tmp_path):
    log, err = tmp_path / "out.log", tmp_path / "err.log"
    with open(log, "w") as out, open(err, "w") as e:
        r = subprocess.run([sys.executable, "-m", "orchestrator", "compare", "--T", "20",
                            "--seeds", "0-1", "--out", str(tmp_path / "o")],
                           stdout=out, stderr=e, timeout=300, cwd=tmp_path,
                           env=dict(os.environ, PATH="/usr/bin:/bin", PYTHONPATH=str(ROOT)))
    assert r.returncode == 0, err.read_text()
    text = log.read_bytes() + err.read_bytes()
    assert b"\r" not in text
    lines = log.read_text().strip().splitlines()
    assert any(re.match(r"\s+kalman seed 1: cost rate", line) for line in lines)
    assert lines[-1].startswith("open it with: ")
    command = shlex.split(lines[-1][len("open it with: "):])
    exe = shutil.which(command[0], path="/usr/bin:/bin") or command[0]
    assert Path(exe).is_file() and os.access(exe, os.X_OK), command   # not "rerun" off PATH
    assert command[1] == str(tmp_path / "o" / "paper.rrd")


def test_the_table_keeps_significant_digits(tmp_path, capsys):
    from orchestrator.cli import main
    assert main(["compare", "--T", "20", "--seeds", "0-1", "--quiet", "--out",
                 str(tmp_path / "o")]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines()
            if line.strip().startswith(("kalman", "classical", "ideal"))]
    assert len(rows) == 3
    for row in rows:
        fields = row.split()
        mean, std, pred = fields[1], fields[2], fields[3]
        assert len(mean.replace(".", "").lstrip("0")) >= 4, row     # 4 significant digits
        assert "." in std and len(std.replace(".", "").lstrip("0")) >= 3, row
        assert "." in pred, row                                      # 4.000, not 4
        assert all("." in x for x in re.findall(r"[\d.]+/[\d.]+", row)[0].split("/")), row
