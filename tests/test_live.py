"""``--live``: a run streamed to a Rerun viewer as it goes (orchestrator/recording/live.py and
RrdStream's ``live``). A real headless viewer (Rerun's own, ``ViewerClient.spawn(headless=True)``,
rendering with a software Vulkan driver) is started by the test and its URL handed to a real
``auv-cosim run``: the viewer holds the run's recording (its entities, its timelines up to the
last step), shows the traces (a screenshot with far more coloured pixels than the empty viewer's)
under the run's layout; the .rrd equals a run's without ``--live``. A viewer that cannot be
reached is refused in one line naming its URL, before anything runs; one that goes away during
the run does not stop it."""
from __future__ import annotations

import json
import socket
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from rerun.chunk import RrdReader
from test_recording_stream import assert_same_files

from orchestrator.recording import read_rrd_scalars
from orchestrator.recording.live import LiveViewerError, check_viewer, live_chunk_steps
from orchestrator.recording.stream import RrdStream
from support.recording import H, make_runs

RERUN = Path(sys.executable).with_name("rerun")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def nowhere() -> str:
    """A viewer URL nothing listens at."""
    return f"rerun+http://127.0.0.1:{free_port()}/proxy"


@pytest.fixture
def viewer():
    """A real headless Rerun viewer on a free port (skips where it cannot render: no Vulkan
    driver; .ci/run installs Mesa's lavapipe)."""
    import rerun.experimental as rx
    try:
        v = rx.ViewerClient.spawn(headless=True, port=free_port(), hide_welcome_screen=True,
                                  executable_path=str(RERUN) if RERUN.exists() else None)
        v.get_state()
    except Exception as exc:                    # no graphics adapter, no binary
        pytest.skip(f"no headless Rerun viewer here: {str(exc).splitlines()[0]}")
    try:
        yield v
    finally:
        with warnings.catch_warnings():         # a test may have quit it already
            warnings.simplefilter("ignore")
            v.quit()


def coloured_pixels(viewer, path: Path) -> int:
    """Pixels of a screenshot of the viewer that are strongly coloured (the traces: the
    interface itself is grey, but for two small warnings)."""
    from PIL import Image
    viewer.save_screenshot(str(path))
    for _ in range(100):                        # written by the viewer, a moment later
        if path.exists() and path.stat().st_size:
            break
        time.sleep(0.05)
    time.sleep(0.3)
    img = np.asarray(Image.open(path).convert("RGB")).astype(int)
    return int(((img.max(axis=2) - img.min(axis=2)) > 60).sum())


def recording_of(viewer, timeout: float = 20.0, last_step: int | None = None):
    """The viewer's one recording, once its ``step`` timeline reaches ``last_step``."""
    deadline = time.monotonic() + timeout
    while True:
        recs = [r for r in viewer.get_state().recordings if r.store_id.startswith("Recording:")]
        steps = {t.name: t.end for r in recs for t in r.timelines}
        if recs and (last_step is None or steps.get("step") == last_step):
            assert len(recs) == 1, recs
            return recs[0]
        assert time.monotonic() < deadline, (recs, steps)
        time.sleep(0.2)


def entities(viewer, store_id) -> set[str]:
    schema = viewer.get_recording_schema(store_id, paths_only=True, max_entities=10000)
    return {e.entity_path for e in schema.entities}


# -- where the viewer is ---------------------------------------------------------------------

def test_a_viewer_that_cannot_be_reached_is_refused_in_one_line():
    url = nowhere()
    with pytest.raises(LiveViewerError) as err:
        check_viewer(url)
    assert url in str(err.value) and "\n" not in str(err.value)
    for bad in ("http://127.0.0.1:9876/proxy", "rerun+http://127.0.0.1:9876/", "9876"):
        with pytest.raises(LiveViewerError, match="not a Rerun viewer's URL"):
            check_viewer(bad)


def test_live_chunks_are_a_fifth_of_a_second_of_wall_clock():
    assert live_chunk_steps(0.01, 1.0, 16384) == 16         # 20 steps -> 16 (0.16 s)
    assert live_chunk_steps(0.01, 10.0, 16384) == 128       # 200 -> 128
    assert live_chunk_steps(0.01, 1e6, 16384) == 16384      # never more than the system's
    assert live_chunk_steps(0.01, 0.001, 16384) == 1
    assert live_chunk_steps(0.01, None, 4096) == 4096       # as fast as it can: unchanged


@pytest.mark.slow
def test_run_with_an_unreachable_viewer_is_refused_before_anything_runs(tmp_path):
    url = nowhere()
    out = tmp_path / "run"
    p = subprocess.run([sys.executable, "-m", "orchestrator", "run", "--T", "1", "--out",
                        str(out), "--live", url], capture_output=True, text=True, timeout=120)
    assert p.returncode == 2, p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and url in lines[0] and "no Rerun viewer answers" in lines[0], lines
    assert not out.exists() and not list(tmp_path.iterdir())


# -- the stream ------------------------------------------------------------------------------

def has_footer(path: Path) -> bool:
    """The .rrd has Rerun's footer (its manifest): no 'legacy format' warning on opening."""
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        RrdReader(path).recordings()
    return not any("no footer" in str(w.message) for w in said)


def send(stream, runs, every=50, pause=0.0, between=None):
    for i, (m, tr) in enumerate(runs.items()):
        n = len(next(iter(tr.values())))
        for a in range(0, n, every):
            stream.send(m, a, {k: x[a:a + every] for k, x in tr.items()})
            time.sleep(pause)
        if between is not None and i == 0:
            between()
    return stream.close()


@pytest.mark.slow
def test_stream_shows_the_layout_first_then_the_traces_and_writes_the_same_file(viewer,
                                                                               tmp_path):
    runs = make_runs()
    blank = coloured_pixels(viewer, tmp_path / "blank.png")
    seen = {}

    def midway():                               # the first method sent, the second to come
        rec = recording_of(viewer, last_step=len(runs["kalman"]["x"]) - 1)
        seen["entities"] = entities(viewer, rec.store_id)
        seen["views"] = {v.name for v in viewer.get_state().views}
        seen["pixels"] = coloured_pixels(viewer, tmp_path / "mid.png")

    with RrdStream(tmp_path / "live.rrd", list(runs), H, recording_name="t", chunk_rows=1,
                   live=viewer.url) as stream:
        opened_without_footer = not stream.footer and stream.footer_at_close
        send(stream, runs, between=midway)
    with RrdStream(tmp_path / "file.rrd", list(runs), H, recording_name="t",
                   chunk_rows=1) as stream:
        send(stream, runs)
    assert_same_files(tmp_path / "file.rrd", tmp_path / "live.rrd")
    # written without a footer as it went (the manifest of its 1-row chunks would grow
    # without bound), given one at the close, its chunks compacted
    assert opened_without_footer and has_footer(tmp_path / "live.rrd")
    # midway: the live layout (the paper's views) and the first method's traces
    assert {"error-1 (dimensionless)", "control-2 (dimensionless)"} <= seen["views"]
    assert {"/error/1/kalman", "/state/3/kalman/estimate", "/legend"} <= seen["entities"]
    assert not any("/classical" in e for e in seen["entities"])
    assert seen["pixels"] > blank + 10000, (blank, seen["pixels"])   # traces drawn
    # at the close: every method, the final blueprint made the active one (its y ranges)
    rec = recording_of(viewer)
    assert "/error/1/classical" in entities(viewer, rec.store_id)
    deadline = time.monotonic() + 10
    while "ScalarAxis" not in json.dumps(viewer.get_blueprint(store_id=rec.store_id).blueprint):
        assert time.monotonic() < deadline, "the final blueprint did not become the active one"
        time.sleep(0.2)


@pytest.mark.slow
def test_a_viewer_that_goes_away_does_not_stop_the_run(viewer, tmp_path, capfd):
    runs = make_runs()
    with RrdStream(tmp_path / "live.rrd", list(runs), H, recording_name="t", chunk_rows=1,
                   live=viewer.url) as stream:
        send(stream, runs, between=viewer.quit)
    with RrdStream(tmp_path / "file.rrd", list(runs), H, recording_name="t",
                   chunk_rows=1) as stream:
        send(stream, runs)
    assert_same_files(tmp_path / "file.rrd", tmp_path / "live.rrd")
    said = [ln for ln in capfd.readouterr().err.splitlines() if ln.startswith("live viewer")]
    assert len(said) == 1 and viewer.url in said[0] and "the run goes on" in said[0], said


# -- real runs -------------------------------------------------------------------------------

def same_series(a_path: Path, b_path: Path) -> int:
    """Assert that two .rrd files hold the same scalar series, bit for bit; their last step."""
    a, b = read_rrd_scalars(a_path), read_rrd_scalars(b_path)
    assert sorted(a) == sorted(b)
    for key in a:
        for x, y in zip(a[key], b[key]):
            np.testing.assert_array_equal(x, y, err_msg=key)
    return int(max(a[k][0][-1] for k in a))


def run_cli(*args: str) -> subprocess.CompletedProcess:
    p = subprocess.run([sys.executable, "-m", "orchestrator", "run", "--quiet", *args],
                       capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    return p


@pytest.mark.slow
@pytest.mark.parametrize("args, entity", [
    (["--T", "5"], "/error/1/kalman"),
    (["--scenario", "formation-4", "--deployment", "per-vehicle", "--fmus", "native",
      "--master", "native", "--T", "20"], "/vehicles/1/error"),
], ids=["paper", "per-vehicle-native"])
def test_a_run_streams_its_traces_to_the_viewer_and_writes_the_same_rrd(viewer, tmp_path,
                                                                       args, entity):
    blank = coloured_pixels(viewer, tmp_path / "blank.png")
    run_cli(*args, "--out", str(tmp_path / "live"), "--live", viewer.url)
    run_cli(*args, "--out", str(tmp_path / "file"))
    summary = json.loads((tmp_path / "live" / "summary.json").read_text())
    if "--master" in args:
        assert set(summary["master"].values()) == {"native"}, summary["master"]
    live, = (tmp_path / "live").glob("*.rrd")
    file, = (tmp_path / "file").glob("*.rrd")
    rec = recording_of(viewer, last_step=same_series(live, file))
    assert any(e.startswith(entity) for e in entities(viewer, rec.store_id))
    assert coloured_pixels(viewer, tmp_path / "end.png") > blank + 10000   # ten times blank


@pytest.mark.slow
def test_a_resumed_run_streams_the_recording_so_far_and_the_rest(viewer, tmp_path):
    """``run --resume OUT --live URL``: the viewer gets the recording of the killed run (its
    segments, replayed) and then the rows to come; the file is the uninterrupted run's."""
    from support.resume import killed_after_a_checkpoint
    args = ["--scenario", "formation-4-links", "--T", "200", "--fmus", "native",
            "--realtime", "50"]                 # paced: killed mid-run, after a chunk
    out = tmp_path / "killed"
    step = killed_after_a_checkpoint(out, args, seed=5)
    assert step > 0
    resumed = subprocess.run([sys.executable, "-m", "orchestrator", "run", "--resume",
                              str(out), "--live", viewer.url], capture_output=True,
                             text=True, timeout=600)
    assert resumed.returncode == 0, resumed.stderr
    run_cli("--scenario", "formation-4-links", "--T", "200", "--fmus", "native", "--out",
            str(tmp_path / "whole"))
    rec = recording_of(viewer, last_step=same_series(
        tmp_path / "whole" / "formation-4-links.rrd", out / "formation-4-links.rrd"))
    first = {t.name: t.start for t in rec.timelines}
    assert first["step"] == 0, first                # the steps before the kill, replayed
    assert any(e.startswith("/vehicles/1/error") for e in entities(viewer, rec.store_id))
