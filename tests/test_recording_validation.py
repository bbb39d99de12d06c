"""Bad input to write_rrd is refused with a ValueError that names what is at fault, before any
file is written: malformed runs, the step h, stride and scene_stride, every field of a
FleetLayout (checked against every run), and the trail durations."""
from __future__ import annotations

import numpy as np
import pytest

from orchestrator.recording import read_rrd_series, write_rrd
from support.recording import FLEET_H, STATE_NAMES, STEPS, H, make_fleet, make_fleet_runs, make_runs


def test_different_step_counts_raise(tmp_path):
    runs = make_runs()
    runs["classical"]["u"] = runs["classical"]["u"][:-1]
    with pytest.raises(ValueError, match=r"'classical'.*'u'.*316 steps"):
        write_rrd(tmp_path / "bad.rrd", runs, H, recording_name="bad")

    runs = make_runs()
    runs["classical"] = make_runs(methods=("classical",), steps=STEPS + 5)["classical"]
    with pytest.raises(ValueError, match=r"'classical'.*'e'.*322 steps"):
        write_rrd(tmp_path / "bad2.rrd", runs, H, recording_name="bad")


def test_missing_key_raises(tmp_path):
    runs = make_runs()
    del runs["kalman"]["zhat"]
    with pytest.raises(ValueError, match=r"'kalman'.*missing.*'zhat'"):
        write_rrd(tmp_path / "bad.rrd", runs, H, recording_name="bad")
    assert not (tmp_path / "bad.rrd").exists()


@pytest.mark.parametrize("mutate, pattern", [
    (lambda r: r["kalman"].__setitem__("e", r["kalman"]["e"][:, 0]), r"'kalman'.*'e'.*shape"),
    (lambda r: r.__setitem__("a/b", r.pop("kalman")), r"'a/b'"),
])
def test_malformed_runs_raise(tmp_path, mutate, pattern):
    runs = make_runs()
    mutate(runs)
    with pytest.raises(ValueError, match=pattern):
        write_rrd(tmp_path / "bad.rrd", runs, H, recording_name="bad")


@pytest.mark.parametrize("h", [0.0, -0.01, float("nan"), 1e-12])
def test_bad_step_raises(tmp_path, h):
    with pytest.raises(ValueError, match="step h"):
        write_rrd(tmp_path / "bad.rrd", make_runs(steps=5), h, recording_name="bad")


@pytest.mark.parametrize("stride", [0, -1, 1.5, 2.0, True, "2", None])
@pytest.mark.parametrize("with_fleet", [False, True])
def test_bad_stride_raises(tmp_path, stride, with_fleet):
    kwargs = {"fleet": make_fleet()} if with_fleet else {}
    runs = make_fleet_runs(methods=("kalman",), steps=10)
    with pytest.raises(ValueError, match="stride must be a positive integer"):
        write_rrd(tmp_path / "bad.rrd", runs, FLEET_H, recording_name="bad", stride=stride, **kwargs)
    assert not (tmp_path / "bad.rrd").exists()


@pytest.mark.parametrize("stride, scene_stride, pattern", [
    (1, 0, "scene_stride must be a positive integer"),
    (1, 2.5, "scene_stride must be a positive integer"),
    (3, 4, r"scene_stride = 4 must be a multiple of stride = 3"),
])
def test_bad_scene_stride_raises(tmp_path, stride, scene_stride, pattern):
    runs = make_fleet_runs(methods=("kalman",), steps=10)
    with pytest.raises(ValueError, match=pattern):
        write_rrd(tmp_path / "bad.rrd", runs, FLEET_H, recording_name="bad", fleet=make_fleet(),
                  stride=stride, scene_stride=scene_stride)


def test_numpy_integer_stride_is_accepted(tmp_path):
    runs = make_fleet_runs(methods=("kalman",), steps=10)
    write_rrd(tmp_path / "ok.rrd", runs, FLEET_H, recording_name="ok", fleet=make_fleet(), stride=np.int64(3))
    assert np.array_equal(read_rrd_series(tmp_path / "ok.rrd", "leader/kalman")[0], [0, 3, 6, 9])


@pytest.mark.parametrize("changes, pattern", [
    ({"position_index": np.array([[0, 1, 2], [6, 7, 8], [12, 13, 18]])},
     r"position_index\[2, 2\] = 18 .*out of range.*'x'.*18 columns"),
    ({"position_index": np.array([[0, 1], [6, 7], [12, 13]])}, r"position_index must have shape \(N, 3\)"),
    ({"position_index": np.array([[0.0, 1, 2], [6, 7, 8], [12, 13, 14]])}, r"position_index must be an integer"),
    ({"error_index": np.array([[0, 1, 2], [3, 4, 5], [6, 7, 9]])}, r"error_index\[2, 2\] = 9 .*'e'"),
    ({"error_index": np.arange(6).reshape(2, 3)}, r"error_index has 2 rows"),
    ({"control_index": np.array([[-1, 1, 2], [3, 4, 5], [6, 7, 8]])}, r"control_index\[0, 0\] = -1 .*'u'"),
    ({"error_names": ("north", "east")}, r"error_names has 2 labels"),
    ({"control_names": ("X_n", "X/e", "X_d")}, r"control_names label 'X/e'"),
    ({"offsets": np.zeros((3, 2))}, r"offsets must have shape \(N, 3\) = \(3, 3\), got shape \(3, 2\)"),
    ({"offsets": np.zeros((2, 3))}, r"offsets must have shape"),
    ({"leader_output": np.eye(3)}, r"leader_output must have shape \(3, l\) = \(3, 2\)"),
    ({"edges": ((1, 2), (2, 4))}, r"edges\[1\] = \(2, 4\) names vehicle 4.*N = 3"),
    ({"edges": ((0, 1),)}, r"edges\[0\] = \(0, 1\) names vehicle 0"),
    ({"edges": ((1, 2, 3),)}, r"edges\[0\].*not a pair"),
    ({"edges": ((2, 2),)}, r"edges\[0\] = \(2, 2\) is a self-loop"),
    ({"pinned": (1, 7)}, r"pinned\[1\] names vehicle 7"),
    ({"state_index": np.arange(18).reshape(3, 6) + 1}, r"state_index\[2, 5\] = 18 .*'x'"),
    ({"state_index": np.arange(12).reshape(2, 6)}, r"state_index has 2 rows"),
    ({"state_index": np.arange(18.0).reshape(3, 6)}, r"state_index must be an integer"),
    ({"state_names": STATE_NAMES[:5]}, r"state_names has 5 labels.*state_index has 6"),
    ({"state_names": None}, r"state_names must be a tuple of strings"),
    ({"state_index": None}, r"state_names has 6 labels.*position_index has 3"),
    ({"disturbance_index": np.arange(9).reshape(3, 3) + 1}, r"disturbance_index\[2, 2\] = 9 .*'w'"),
    ({"disturbance_names": ("n", "n", "d")}, r"disturbance_names labels must be distinct"),
    ({"disturbance_index": None}, r"disturbance_names is given without fleet.disturbance_index"),
])
def test_bad_fleet_layout_raises(tmp_path, changes, pattern):
    runs = make_fleet_runs(methods=("kalman",), steps=10)
    with pytest.raises(ValueError, match=pattern):
        write_rrd(tmp_path / "bad.rrd", runs, FLEET_H, recording_name="bad", fleet=make_fleet(**changes))
    assert not (tmp_path / "bad.rrd").exists()


def test_fleet_checked_against_every_run(tmp_path):
    runs = make_fleet_runs(methods=("kalman", "classical"), steps=10)
    runs["classical"]["u"] = runs["classical"]["u"][:, :8]
    with pytest.raises(ValueError, match=r"control_index\[2, 2\] = 8 .*'classical' trace 'u'"):
        write_rrd(tmp_path / "bad.rrd", runs, FLEET_H, recording_name="bad", fleet=make_fleet())
    runs = make_fleet_runs(methods=("kalman", "classical"), steps=10)
    runs["kalman"]["xhat"] = runs["kalman"]["xhat"][:, :17]
    with pytest.raises(ValueError, match=r"state_index\[2, 5\] = 17 .*'kalman' trace 'xhat'"):
        write_rrd(tmp_path / "bad.rrd", runs, FLEET_H, recording_name="bad", fleet=make_fleet())
    runs = make_fleet_runs(methods=("kalman", "classical"), steps=10)
    runs["classical"]["what"] = runs["classical"]["what"][:, :8]
    with pytest.raises(ValueError, match=r"disturbance_index\[2, 2\] = 8 .*'classical' trace 'what'"):
        write_rrd(tmp_path / "bad.rrd", runs, FLEET_H, recording_name="bad", fleet=make_fleet())


@pytest.mark.parametrize("kwargs", [{"trail_seconds": 0.0}, {"trail_seconds": float("nan")},
                                    {"trail_sample_seconds": -1.0}])
def test_bad_trail_settings_raise(tmp_path, kwargs):
    runs = make_fleet_runs(methods=("kalman",), steps=10)
    with pytest.raises(ValueError, match=next(iter(kwargs))):
        write_rrd(tmp_path / "bad.rrd", runs, FLEET_H, recording_name="bad", fleet=make_fleet(), **kwargs)
