"""Checkpoints and ``run --resume`` (orchestrator/running/checkpoint.py) with real
processes and real signals: a real ``auv-cosim run`` killed with SIGKILL at a random moment
after its first checkpoint is resumed by ``run --resume OUT``; its summary's figures and its
.rrd (read back) equal an uninterrupted run's, bit for bit. A resume where there is nothing
to resume, a damaged checkpoint and options that would change the run are refused in one
line."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from orchestrator.recording import read_rrd_scalars
from orchestrator.running.checkpoint import CHECKPOINT_DIR, CHECKPOINT_FILE
from support.outputs import staging_folders
from support.resume import killed_after_a_checkpoint

#: summary keys that say how (not what) a run ran
HOW = ("timing", "wall_s", "fmus", "checkpoints", "rrd", "source")


def _cli(*args: str, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "orchestrator", *args], capture_output=True,
                          text=True, timeout=600, **kw)


def _figures(out: Path) -> dict:
    summary = json.loads((out / "summary.json").read_text())
    return {k: v for k, v in summary.items() if k not in HOW}


def _same_rrd(a: Path, b: Path) -> None:
    sa, sb = read_rrd_scalars(a), read_rrd_scalars(b)
    assert sa.keys() == sb.keys() and sa
    for key in sa:
        for x, y in zip(sa[key], sb[key]):
            assert np.array_equal(np.asarray(x), np.asarray(y)), key


@pytest.mark.slow
@pytest.mark.parametrize("args", [
    pytest.param(["--T", "600"], id="stacked-python"),
    # the native FMUs and the compiled master are paced (--realtime) to be killed mid-run
    pytest.param(["--T", "600", "--fmus", "native", "--realtime", "200"],
                 id="stacked-native"),
    pytest.param(["--scenario", "formation-4-links", "--T", "200"],
                 id="per-vehicle-links-python"),
    pytest.param(["--scenario", "formation-4-links", "--T", "200", "--fmus", "native",
                  "--realtime", "50"], id="per-vehicle-links-native"),
])
def test_a_killed_run_resumes_to_the_uninterrupted_result(tmp_path, args):
    whole = tmp_path / "whole"
    fast = args[:args.index("--realtime")] if "--realtime" in args else args
    done = _cli("run", *fast, "--quiet", "--out", str(whole), "--checkpoint-every", "0")
    assert done.returncode == 0, done.stderr
    out = tmp_path / "killed"
    step = killed_after_a_checkpoint(out, args, seed=len(str(tmp_path)))
    assert step > 0
    resumed = _cli("run", "--resume", str(out))
    assert resumed.returncode == 0, resumed.stderr
    assert f"resuming at t = {step * 0.01:g} s" in resumed.stdout
    if "--fmus" in args:
        assert "FMUs: native" in resumed.stdout and "master: compiled" in resumed.stdout
    assert _figures(out) == _figures(whole)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["checkpoints"]["resumed_from_s"] == pytest.approx(step * 0.01)
    assert not (out / CHECKPOINT_DIR).exists()          # a finished run keeps none
    assert not staging_folders(out)                      # the killed run's folder is gone
    rrd = next(whole.glob("*.rrd")).name
    _same_rrd(whole / rrd, out / rrd)


def test_resume_without_a_checkpoint_is_one_line(tmp_path):
    res = _cli("run", "--resume", str(tmp_path / "nothing"))
    assert res.returncode != 0
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "no checkpoint there" in lines[0], res.stderr


def test_a_damaged_checkpoint_is_refused_in_one_line(tmp_path):
    out = tmp_path / "run"
    (out / CHECKPOINT_DIR).mkdir(parents=True)
    (out / CHECKPOINT_DIR / CHECKPOINT_FILE).write_bytes(b"\x80\x05 half a pickle")
    res = _cli("run", "--resume", str(out))
    lines = res.stderr.strip().splitlines()
    assert res.returncode != 0 and len(lines) == 1, res.stderr
    assert "not a readable checkpoint" in lines[0]


def test_options_that_would_change_a_resumed_run_are_refused(tmp_path):
    res = _cli("run", "--resume", str(tmp_path), "--T", "10", "--seed", "3")
    lines = res.stderr.strip().splitlines()
    assert res.returncode != 0 and len(lines) == 1, res.stderr
    assert "drop --seed, --T" in lines[0]
