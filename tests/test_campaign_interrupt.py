"""Ctrl-C in a campaign as a terminal sends it: SIGINT to the whole process group, the
command and its local Dask workers alike. The command stops with its one clean line and
no traceback from a worker (they used to print asyncio's KeyboardInterrupt traceback,
about 30 lines each), keeps every finished row, and the same command then finishes the
rest."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from support.campaign import RESUME, rows
from support.outputs import working


def _campaign(*args, **kw) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "orchestrator", "campaign", *map(str, args)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)


@pytest.mark.slow
def test_ctrl_c_stops_a_campaign_without_a_worker_traceback_and_it_resumes(tmp_path):
    spec = tmp_path / "spec.toml"
    spec.write_text(RESUME)
    out = tmp_path / "out"
    proc = _campaign(spec, "--workers", "2", "--out", out, start_new_session=True)
    try:
        deadline = time.monotonic() + 180
        parts = lambda: working(out) / "parts"                        # noqa: E731
        while len(list(parts().glob("*.json")) if parts().exists() else []) < 2:
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline
            time.sleep(0.05)
        os.killpg(proc.pid, signal.SIGINT)             # Ctrl-C: the group, workers too
        _, stderr = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr, stderr
    line = [s for s in stderr.splitlines() if "interrupted" in s]
    assert len(line) == 1 and line[0].startswith("auv-cosim campaign: interrupted by SIGINT: ")
    assert "rerun the same command to finish" in line[0]
    kept = len(rows(out))
    assert 2 <= kept < 12, "the campaign was not stopped mid-way"
    again = _campaign(spec, "--workers", "2", "--out", out)
    stdout, stderr = again.communicate(timeout=180)
    assert again.returncode == 0, stderr
    assert f"{kept} already done, {12 - kept} to run" in stdout
    table = rows(out)
    assert len(table) == 12 and all(r["status"] == "ok" for r in table)
    assert len({(r["point"], r["seed"]) for r in table}) == 12          # no run twice
