"""The .rrd written by a child process (orchestrator/recording/background.py): the same
series as written in process, read back from the file; a failure in the child reaches the
parent as one line naming it; a writer that is never used leaves no process behind."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from orchestrator.recording import read_rrd_scalars
from orchestrator.recording.background import BackgroundWriter
from support.recording import H, expected_series, make_runs


def test_child_writes_the_same_series(tmp_path):
    runs = make_runs()
    with BackgroundWriter() as w:
        assert w.proc is not None and w.proc.poll() is None       # a real child, waiting
        info = w.write(tmp_path / "bg.rrd", runs, H, recording_name="background")
        assert w.proc.returncode == 0
    assert info["bytes"] == (tmp_path / "bg.rrd").stat().st_size > 0
    got = read_rrd_scalars(tmp_path / "bg.rrd")
    want = expected_series(runs)
    assert set(got) == set(want)
    for name, values in want.items():
        steps, t_ns, v = got[name]
        assert np.array_equal(steps, np.arange(len(values)))
        assert np.array_equal(v, values), name


def test_a_failure_in_the_child_is_one_line(tmp_path):
    runs = make_runs()
    first = next(iter(runs.values()))
    first["x"] = first["x"][:-3]                       # one trace shorter than the others
    with BackgroundWriter() as w, pytest.raises(RuntimeError) as exc:
        w.write(tmp_path / "bad.rrd", runs, H, recording_name="bad")
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith(f"writing {tmp_path / 'bad.rrd'} failed: ")
    assert "same number of steps" in msg
    assert not (tmp_path / "bad.rrd").exists()


def test_an_unused_writer_stops_its_child():
    w = BackgroundWriter()
    proc = w.proc
    w.close()
    assert proc.poll() is not None and w.proc is None


def test_a_prestarted_writer_is_taken_once_and_writes(tmp_path):
    """prestart() (run and compare call it before importing the command line) starts one
    child; the first take() gets that child, the next a new one; the prestarted child
    writes the same series."""
    from orchestrator.recording import background
    background.prestart()
    first = background._PRESTARTED
    assert first is not None and first.proc.poll() is None
    background.prestart()                                   # idempotent: still one child
    assert background._PRESTARTED is first
    with BackgroundWriter.take() as w:
        assert w is first and background._PRESTARTED is None
        runs = make_runs()
        w.write(tmp_path / "pre.rrd", runs, H, recording_name="prestarted")
    with BackgroundWriter.take() as other:
        assert other is not first
        # this process imported the writer (read_rrd_scalars' module did): no second child
        assert "orchestrator.recording.writer" in sys.modules and other.proc is None
        other.write(tmp_path / "here.rrd", runs, H, recording_name="here")
    assert set(read_rrd_scalars(tmp_path / "pre.rrd")) == set(expected_series(runs))
    assert set(read_rrd_scalars(tmp_path / "here.rrd")) == set(expected_series(runs))


def test_a_writer_is_a_child_while_rerun_is_not_imported(tmp_path):
    """A fresh interpreter (as the command line is) takes a child writer; once the writer
    module is imported, take() writes in process."""
    code = ("import sys\n"
            "from orchestrator.recording.background import BackgroundWriter\n"
            "w = BackgroundWriter.take(); print(w.proc is not None, 'rerun' in sys.modules)\n"
            "w.close()\n"
            "import orchestrator.recording.writer\n"
            "w = BackgroundWriter.take(); print(w.proc is not None)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=Path(__file__).parents[1]).stdout.split()
    assert out == ["True", "False", "False"]
