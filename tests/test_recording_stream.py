"""The .rrd written chunk by chunk (orchestrator/recording/stream.py): the same traces sent in one
chunk or in seven uneven ones give the same file contents (every entity, every value, the
static styles and the blueprint), for the paper layout and a fleet with links and actuators;
an interrupted run records what was sent; the final name holds a whole file or the earlier
one, never a half-written one."""
from __future__ import annotations

from collections import defaultdict

import numpy as np
import pyarrow as pa
import pytest
from rerun.chunk import RrdReader

from orchestrator.recording import read_rrd_scalars, read_rrd_series, write_rrd
from orchestrator.recording.stream import RrdStream
from support.recording import (
    FLEET_H,
    FLEET_STEPS,
    METHODS,
    N_VEH,
    STEPS,
    TRAIL_S,
    TRAIL_SAMPLE_S,
    H,
    expected_series,
    make_fleet,
    make_fleet_runs,
    make_runs,
)
from support.rrd_readback import read_rrd_blueprint_tree, read_rrd_view_properties

#: seven uneven chunks (cut points), none on a multiple of the strides tried
PAPER_CUTS = (1, 2, 40, 41, 150, 299)
FLEET_CUTS = (7, 8, 61, 100, 101, 200)
LINKS = ["1 -> 2", "2 -> 3", "3 -> 1", "leader -> 1"]


def contents(path):
    """Everything of the recording in a .rrd (the blueprint aside): temporal data as
    (entity, column) -> rows sorted by step, each (step, sim_time, value); static data as
    (entity, column) -> its last value. Recording properties (ids, start time) are left out."""
    temporal, static = defaultdict(list), {}
    for chunk in RrdReader(path).stream():
        entity = chunk.entity_path
        if entity.startswith("/__properties"):
            continue
        batch = chunk.to_record_batch()
        cols = [c for c in batch.schema.names if ":" in c and not c.startswith("rerun.")]
        if chunk.is_static:
            for c in cols:
                static[(entity, c)] = batch.column(c).to_pylist()[-1]
            continue
        step = batch.column("step").to_pylist()
        sim = batch.column("sim_time").cast(pa.int64()).to_pylist()
        for c in cols:
            for row in zip(step, sim, batch.column(c).to_pylist()):
                temporal[(entity, c)].append(row)
    return {k: sorted(v, key=lambda r: r[0]) for k, v in temporal.items()}, static


def send_in_chunks(path, runs, h, cuts, chunk_rows=1, **kwargs):
    """``runs`` sent in the chunks ``cuts`` makes; written as each is sent (chunk_rows=1) or
    gathered into blocks of ``chunk_rows`` recorded rows."""
    with RrdStream(path, list(runs), h, chunk_rows=chunk_rows, **kwargs) as stream:
        for method, traces in runs.items():
            steps = next(iter(traces.values())).shape[0]
            bounds = [0, *[c for c in cuts if c < steps], steps]
            for a, b in zip(bounds[:-1], bounds[1:]):
                stream.send(method, a, {k: v[a:b] for k, v in traces.items()})
        return stream.close()


def assert_same_files(one, many):
    t1, s1 = contents(one)
    t2, s2 = contents(many)
    assert set(t1) == set(t2) and set(s1) == set(s2)
    for key in t1:
        assert t1[key] == t2[key], key
    for key in s1:
        assert s1[key] == s2[key], key
    assert read_rrd_blueprint_tree(one) == read_rrd_blueprint_tree(many)
    assert read_rrd_view_properties(one) == read_rrd_view_properties(many)


def fleet_runs_with_links_and_actuators():
    runs = make_fleet_runs()
    rng = np.random.default_rng(5)
    for traces in runs.values():
        steps = traces["x"].shape[0]
        traces["link_age"] = rng.uniform(0, 10, (steps, len(LINKS)))
        for key in ("link_delivered", "link_lost", "link_in_flight"):
            traces[key] = np.cumsum(rng.integers(0, 2, (steps, len(LINKS))), axis=0) * 1.0
        traces["rpm"] = rng.uniform(0, 1500, (steps, N_VEH))
        traces["rudder"] = rng.uniform(-0.2, 0.2, (steps, N_VEH))
        traces["stern"] = rng.uniform(-0.2, 0.2, (steps, N_VEH))
        traces["saturated"] = (rng.uniform(0, 1, (steps, N_VEH)) > 0.9) * 1.0
        traces["attitude"] = rng.uniform(-0.3, 0.3, (steps, 3 * N_VEH))
    return runs


@pytest.mark.parametrize("stride,chunk_rows", [(1, 1), (3, 1), (3, 25)])
def test_paper_layout_one_chunk_or_seven(tmp_path, stride, chunk_rows):
    runs = make_runs()
    kw = dict(recording_name="chunks", stride=stride)
    one = write_rrd(tmp_path / "one.rrd", runs, H, **kw)
    many = send_in_chunks(tmp_path / "many.rrd", runs, H, PAPER_CUTS, chunk_rows, **kw)
    assert one["signals"] == many["signals"]
    assert_same_files(tmp_path / "one.rrd", tmp_path / "many.rrd")
    got = read_rrd_scalars(tmp_path / "many.rrd")
    for name, values in expected_series(runs).items():
        assert np.array_equal(got[name][0], np.arange(0, STEPS, stride))
        assert np.array_equal(got[name][2], values[::stride]), name


@pytest.mark.parametrize("stride,chunk_rows", [(1, 1), (3, 1), (3, 25)])
def test_fleet_with_links_one_chunk_or_seven(tmp_path, stride, chunk_rows):
    runs = fleet_runs_with_links_and_actuators()
    kw = dict(recording_name="chunks", fleet=make_fleet(), trail_seconds=TRAIL_S,
              trail_sample_seconds=TRAIL_SAMPLE_S, stride=stride,
              links={m: LINKS for m in runs})
    one = write_rrd(tmp_path / "one.rrd", runs, FLEET_H, **kw)
    many = send_in_chunks(tmp_path / "many.rrd", runs, FLEET_H, FLEET_CUTS, chunk_rows, **kw)
    assert one["signals"] == many["signals"]
    temporal, static = contents(tmp_path / "many.rrd")
    # the scene, links and actuators are there
    for entity in ("/world/kalman/labels", "/world/kalman/edges", "/world/kalman/trails",
                   "/world/classical/hulls", "/network/links/1-2/kalman",
                   "/vehicles/1/network/classical/age", "/vehicles/3/propeller/kalman",
                   "/limits/fins"):
        assert any(e == entity for e, _ in temporal), entity
    assert ("/world/kalman/leader_path", "LineStrips3D:strips") in static
    assert_same_files(tmp_path / "one.rrd", tmp_path / "many.rrd")


def test_one_step_chunks_give_the_same_file(tmp_path):
    """The extreme cut: one step per chunk (labels wait for the next sample, trails and
    edges close at the last recorded step)."""
    runs = {m: {k: v[:40] for k, v in tr.items()} for m, tr in make_fleet_runs().items()}
    kw = dict(recording_name="steps", fleet=make_fleet(), trail_seconds=TRAIL_S,
              trail_sample_seconds=TRAIL_SAMPLE_S, stride=3)
    write_rrd(tmp_path / "one.rrd", runs, FLEET_H, **kw)
    send_in_chunks(tmp_path / "many.rrd", runs, FLEET_H, tuple(range(1, 40)), **kw)
    assert_same_files(tmp_path / "one.rrd", tmp_path / "many.rrd")


def test_an_interrupted_run_records_what_was_sent(tmp_path):
    """The second method stops early: close() writes both, each as far as it was sent."""
    runs = make_fleet_runs()
    with RrdStream(tmp_path / "cut.rrd", list(runs), FLEET_H, recording_name="cut",
                   fleet=make_fleet(), stride=2, chunk_rows=10) as stream:
        stream.send("kalman", 0, runs["kalman"])
        stream.send("classical", 0, {k: v[:50] for k, v in runs["classical"].items()})
        stream.send("classical", 50, {k: v[50:77] for k, v in runs["classical"].items()})
        info = stream.close()
    assert info["bytes"] == (tmp_path / "cut.rrd").stat().st_size
    step, _, _ = read_rrd_series(tmp_path / "cut.rrd", "vehicles/1/error/kalman")
    assert np.array_equal(step, np.arange(0, FLEET_STEPS, 2))
    step, _, values = read_rrd_series(tmp_path / "cut.rrd", "vehicles/2/error/classical")
    assert np.array_equal(step, np.arange(0, 77, 2))
    assert np.array_equal(values, runs["classical"]["e"][0:77:2, 3:6])


def test_the_final_name_holds_a_whole_file_or_the_earlier_one(tmp_path):
    path = tmp_path / "run.rrd"
    path.write_bytes(b"earlier run")
    runs = make_runs()
    stream = RrdStream(path, list(runs), H, recording_name="atomic", chunk_rows=100)
    stream.send("kalman", 0, runs["kalman"])
    parts = [p for p in tmp_path.iterdir() if p.name.endswith(".part")]
    assert len(parts) == 1 and parts[0].stat().st_size > 0       # written as it goes
    assert path.read_bytes() == b"earlier run"
    stream.abort()
    assert [p.name for p in tmp_path.iterdir()] == ["run.rrd"]
    assert path.read_bytes() == b"earlier run"
    with RrdStream(path, list(runs), H, recording_name="atomic") as stream:
        for m in METHODS:
            stream.send(m, 0, runs[m])
        assert path.read_bytes() == b"earlier run"
        stream.close()
    assert [p.name for p in tmp_path.iterdir()] == ["run.rrd"]
    assert set(read_rrd_scalars(path)) == set(expected_series(runs))


def test_an_exception_in_a_with_block_leaves_no_file(tmp_path):
    runs = make_runs()
    with pytest.raises(KeyError), RrdStream(tmp_path / "x.rrd", list(runs), H,
                                            recording_name="x") as stream:
        stream.send("kalman", 0, runs["kalman"])
        raise KeyError("master failed")
    assert list(tmp_path.iterdir()) == []


def test_misuse_is_refused(tmp_path):
    runs = make_runs()
    chunk = {k: v[:10] for k, v in runs["kalman"].items()}
    with RrdStream(tmp_path / "x.rrd", list(runs), H, recording_name="x") as stream:
        with pytest.raises(ValueError, match="not one of"):
            stream.send("ideal", 0, chunk)
        stream.send("kalman", 0, chunk)
        with pytest.raises(ValueError, match="previous one ended at 9"):
            stream.send("kalman", 11, chunk)
        with pytest.raises(ValueError, match="trace columns"):
            stream.send("kalman", 10, {**chunk, "x": chunk["x"][:, :2]})
        with pytest.raises(ValueError, match="same number of steps"):
            stream.send("kalman", 10, {**chunk, "x": chunk["x"][:5]})
        stream.send("kalman", 10, chunk)                   # still usable
        stream.send("classical", 0, chunk)
        with pytest.raises(ValueError, match="was finished"):
            stream.send("kalman", 20, chunk)
        with pytest.raises(ValueError, match="last_step"):
            stream.close(last_step=5)
    assert list(tmp_path.iterdir()) == []                 # that close aborted
    with RrdStream(tmp_path / "y.rrd", list(runs), H, recording_name="y") as stream:
        with pytest.raises(ValueError, match="nothing to write"):
            stream.close()
    assert list(tmp_path.iterdir()) == []


def test_gathered_rows_are_copies(tmp_path):
    """Rows waiting to be written are the stream's own: a master that refills one buffer
    for every chunk records what it sent."""
    runs = make_runs()
    buf = {k: np.empty((10, v.shape[1])) for k, v in runs["kalman"].items()}
    with RrdStream(tmp_path / "buf.rrd", ["kalman"], H, recording_name="buf",
                   chunk_rows=1000) as stream:
        for k0 in range(0, 300, 10):
            for k, v in runs["kalman"].items():
                buf[k][:] = v[k0:k0 + 10]
            stream.send("kalman", k0, buf)
        stream.close()
    got = read_rrd_scalars(tmp_path / "buf.rrd")
    assert np.array_equal(got["error/1/kalman"][2], runs["kalman"]["e"][:300, 0])


def test_links_may_come_with_the_first_chunk(tmp_path):
    """A method's link names known only once it ran: given with its first chunk, the file
    is the one written with them given at the open."""
    runs = fleet_runs_with_links_and_actuators()
    kw = dict(recording_name="links", fleet=make_fleet(), trail_seconds=TRAIL_S,
              trail_sample_seconds=TRAIL_SAMPLE_S, stride=2)
    write_rrd(tmp_path / "one.rrd", runs, FLEET_H, links={m: LINKS for m in runs}, **kw)
    with RrdStream(tmp_path / "late.rrd", list(runs), FLEET_H, chunk_rows=1, **kw) as stream:
        for m, traces in runs.items():
            stream.send(m, 0, {k: v[:100] for k, v in traces.items()}, links=LINKS)
            with pytest.raises(ValueError, match="links"):
                stream.send(m, 100, {k: v[100:] for k, v in traces.items()}, links=LINKS[:2])
            stream.send(m, 100, {k: v[100:] for k, v in traces.items()})
        stream.close()
    assert_same_files(tmp_path / "one.rrd", tmp_path / "late.rrd")


@pytest.mark.parametrize("resume", [False, True], ids=["goes-on", "resumed"])
def test_checkpoint_segments_join_into_the_same_file(tmp_path, resume):
    """A fleet with links recorded with two checkpoints (each finishes a segment file):
    going on, or resumed from the second checkpoint's state in a new stream (what
    ``run --resume`` does after a kill: the rows after the checkpoint are sent again), the
    joined file holds what a stream without checkpoints writes, blueprint included."""
    runs = fleet_runs_with_links_and_actuators()
    kw = dict(recording_name="checkpoints", fleet=make_fleet(), trail_seconds=TRAIL_S,
              trail_sample_seconds=TRAIL_SAMPLE_S, stride=3, links={m: LINKS for m in runs})
    write_rrd(tmp_path / "one.rrd", runs, FLEET_H, **kw)
    (first, tr1), (second, tr2) = runs.items()
    folder = tmp_path / "checkpoint"
    stream = RrdStream(tmp_path / "segmented.rrd", list(runs), FLEET_H, chunk_rows=25, **kw)
    stream.send(first, 0, tr1)
    stream.checkpoint(folder)
    stream.send(second, 0, {k: v[:100] for k, v in tr2.items()})
    state = stream.checkpoint(folder)
    assert sorted(p.name for p in folder.iterdir()) == ["segment-0000.rrd",
                                                         "segment-0001.rrd"]
    if resume:
        stream.send(second, 100, {k: v[100:150] for k, v in tr2.items()})   # then killed
        stream.abort()
        stream = RrdStream.resumed(state, folder, tmp_path / "segmented.rrd")
    stream.send(second, 100, {k: v[100:] for k, v in tr2.items()})
    stream.close()
    assert_same_files(tmp_path / "one.rrd", tmp_path / "segmented.rrd")
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".part")]


def test_a_failed_join_keeps_every_segment(tmp_path):
    """A segment the join cannot read (here: damaged): the close says so in one line and
    the recording so far stays in the segment files, the last part with them."""
    runs = make_runs()
    (method, traces), = list(runs.items())[:1]
    folder = tmp_path / "checkpoint"
    stream = RrdStream(tmp_path / "run.rrd", [method], H, recording_name="join")
    stream.send(method, 0, {k: v[:100] for k, v in traces.items()})
    stream.checkpoint(folder)
    stream.send(method, 100, {k: v[100:] for k, v in traces.items()})
    (folder / "segment-0000.rrd").write_bytes(b"not a recording")
    with pytest.raises(RuntimeError, match="the recording is kept in 2 files"):
        stream.close()
    assert sorted(p.name for p in folder.iterdir()) == ["segment-0000.rrd",
                                                         "segment-0001.rrd"]
    assert not (tmp_path / "run.rrd").exists()
    steps = read_rrd_scalars(folder / "segment-0001.rrd")
    assert steps and all(k[0] >= 100 for k, _, _ in steps.values())
