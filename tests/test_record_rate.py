"""``--record-hz``: the .rrd holds every stride-th step (read back), the statistics every
step (the same figures as a run recorded at every step)."""
from __future__ import annotations

import json

import numpy as np

from orchestrator.cli import main
from orchestrator.recording import read_rrd_scalars


def test_record_hz_thins_the_recording_not_the_statistics(tmp_path):
    every, thin = tmp_path / "every", tmp_path / "thin"
    assert main(["run", "--T", "20", "--quiet", "--out", str(every)]) == 0
    assert main(["run", "--T", "20", "--quiet", "--out", str(thin), "--record-hz", "10"]) == 0
    a = json.loads((every / "summary.json").read_text())
    b = json.loads((thin / "summary.json").read_text())
    assert b["rrd"]["recorded_every_steps"] == 10 and a["rrd"]["recorded_every_steps"] == 1
    assert a["methods"]["kalman"]["cost_rate"] == b["methods"]["kalman"]["cost_rate"]
    k_all, _, e_all = read_rrd_scalars(every / "paper.rrd")["error/1/kalman"]
    k, _, e = read_rrd_scalars(thin / "paper.rrd")["error/1/kalman"]
    assert np.array_equal(k, np.arange(0, 2000, 10))
    assert np.array_equal(e, e_all[::10])
    assert (thin / "paper.rrd").stat().st_size < (every / "paper.rrd").stat().st_size / 2
