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


def _chunks(traces, cuts=(1, 100, 101, 250)):
    steps = next(iter(traces.values())).shape[0]
    bounds = [0, *[c for c in cuts if c < steps], steps]
    for a, b in zip(bounds[:-1], bounds[1:]):
        yield a, {k: v[a:b] for k, v in traces.items()}


def test_a_child_streams_the_same_file(tmp_path):
    """stream(): every chunk a frame to a real child, which writes it as it comes; the file
    equals the one written in process in one go, and the figures come back at close."""
    from test_recording_stream import contents

    from orchestrator.recording import write_rrd
    from support.rrd_readback import read_rrd_blueprint_tree
    runs = make_runs()
    write_rrd(tmp_path / "here.rrd", runs, H, recording_name="streamed", stride=2)
    with BackgroundWriter() as w:
        child = w.proc
        stream = w.stream(tmp_path / "bg.rrd", list(runs), H, recording_name="streamed",
                          stride=2)
        assert type(stream).__name__ == "ChildStream" and w.proc is None
        for m, traces in runs.items():
            for k0, chunk in _chunks(traces):
                stream.send(m, k0, chunk)
                parts = [p for p in tmp_path.iterdir() if p.name.endswith(".part")]
                assert not (tmp_path / "bg.rrd").exists() and len(parts) <= 1
        info = stream.close()
        assert child.returncode == 0
    assert info["bytes"] == (tmp_path / "bg.rrd").stat().st_size
    assert info["signals"] == sum(v.shape[1] for tr in runs.values() for v in tr.values())
    assert contents(tmp_path / "bg.rrd") == contents(tmp_path / "here.rrd")
    assert read_rrd_blueprint_tree(tmp_path / "bg.rrd") == read_rrd_blueprint_tree(
        tmp_path / "here.rrd")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bg.rrd", "here.rrd"]


def test_a_failure_in_a_streaming_child_is_one_line(tmp_path):
    """A chunk the child refuses ends it (its temporary file removed); the next call says
    why in one line; the earlier file under the final name stays."""
    (tmp_path / "bad.rrd").write_bytes(b"earlier")
    runs = make_runs()
    with BackgroundWriter() as w:
        child = w.proc
        stream = w.stream(tmp_path / "bad.rrd", list(runs), H, recording_name="bad")
        stream.send("kalman", 0, {k: v[:10] for k, v in runs["kalman"].items()})
        stream.send("kalman", 10, {k: v[10:20, :1] for k, v in runs["kalman"].items()})
        with pytest.raises(RuntimeError) as exc:
            for k0, chunk in _chunks({k: v[20:] for k, v in runs["kalman"].items()}):
                stream.send("kalman", 20 + k0, chunk)
            stream.close()
        assert child.poll() is not None
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith(f"writing {tmp_path / 'bad.rrd'} failed: ")
    assert "trace columns" in msg
    assert [p.name for p in tmp_path.iterdir()] == ["bad.rrd"]
    assert (tmp_path / "bad.rrd").read_bytes() == b"earlier"


def test_an_unclosed_stream_is_aborted_with_its_writer(tmp_path):
    runs = make_runs()
    with BackgroundWriter() as w:
        child = w.proc
        stream = w.stream(tmp_path / "cut.rrd", list(runs), H, recording_name="cut")
        stream.send("kalman", 0, runs["kalman"])
    assert child.poll() is not None and list(tmp_path.iterdir()) == []
    with pytest.raises(RuntimeError, match="closed"):
        stream.send("kalman", len(runs["kalman"]["x"]), runs["kalman"])


def test_without_a_child_the_stream_is_written_here(tmp_path):
    from orchestrator.recording.stream import RrdStream
    runs = make_runs()
    with BackgroundWriter(child=False) as w:
        stream = w.stream(tmp_path / "here.rrd", list(runs), H, recording_name="here")
        assert isinstance(stream, RrdStream)
        for m, traces in runs.items():
            for k0, chunk in _chunks(traces):
                stream.send(m, k0, chunk)
        info = stream.close()
    assert info["bytes"] == (tmp_path / "here.rrd").stat().st_size
    assert set(read_rrd_scalars(tmp_path / "here.rrd")) == set(expected_series(runs))
