"""Synthetic runs and fleet layouts for the tests of :mod:`orchestrator.recording`, the entity
paths they should land on, and the two recordings several test modules read back: a paper-layout
file of two methods (:func:`write_paper_recording`) and a fleet file of three vehicles
(:func:`write_fleet_recording`, once per stride of :data:`FLEET_STRIDES`)."""
from __future__ import annotations

import numpy as np

from orchestrator.recording import FleetLayout, write_rrd

# ---------------------------------------------------------------------------------------------
# Paper (per-component) layout: two methods, random traces of every key
# ---------------------------------------------------------------------------------------------

H = 0.01
H_NS = 10_000_000
STEPS = 317
DIMS = {"x": 3, "w": 1, "z": 2, "e": 2, "u": 2, "xhat": 3, "what": 1, "zhat": 2, "y": 2, "ybar": 1}
METHODS = ("kalman", "classical")

# trace key -> entity path template, as tabulated in the orchestrator.recording docstring
LAYOUT = {
    "e": "error/{i}/{m}",
    "x": "state/{i}/{m}/true",
    "xhat": "state/{i}/{m}/estimate",
    "u": "control/{i}/{m}",
    "w": "disturbance/{i}/{m}/true",
    "what": "disturbance/{i}/{m}/estimate",
    "z": "reference/{i}/{m}/true",
    "zhat": "reference/{i}/{m}/estimate",
    "y": "measurement/y/{i}/{m}",
    "ybar": "measurement/ybar/{i}/{m}",
}


def make_runs(methods=METHODS, steps=STEPS, dims=DIMS, seed=1234):
    rng = np.random.default_rng(seed)
    return {
        m: {k: rng.standard_normal((steps, d)) * 10.0 ** rng.integers(-6, 6) for k, d in dims.items()}
        for m in methods
    }


def expected_series(runs):
    out = {}
    for m, traces in runs.items():
        for key, template in LAYOUT.items():
            for i in range(1, traces[key].shape[1] + 1):
                out[template.format(i=i, m=m)] = traces[key][:, i - 1]
    return out


def write_paper_recording(tmp_path_factory):
    """The two-method paper-layout file: (path, runs, info returned by write_rrd)."""
    runs = make_runs()
    path = tmp_path_factory.mktemp("rrd") / "two_methods.rrd"
    info = write_rrd(path, runs, H, recording_name="synthetic round trip")
    return path, runs, info


# ---------------------------------------------------------------------------------------------
# Fleet of N vehicles: per-vehicle series, 3D scene, fleet blueprint
# ---------------------------------------------------------------------------------------------

N_VEH = 3
FLEET_STEPS = 263          # not a multiple of the trail stride: the last step closes the trail
FLEET_H = 0.1
FLEET_H_NS = 100_000_000
TRAIL_S = 5.0              # 50 steps
TRAIL_SAMPLE_S = 0.5       # 5 steps
FLEET_METHODS = ("kalman", "classical")
FLEET_DIMS = {"x": 6 * N_VEH, "w": 3 * N_VEH, "z": 2, "e": 3 * N_VEH, "u": 3 * N_VEH,
              "xhat": 6 * N_VEH, "what": 3 * N_VEH, "zhat": 2, "y": 4, "ybar": 2}
EDGES = ((1, 2), (2, 3), (3, 1), (1, 3))
PINNED = (1, 3)
STATE_NAMES = ("north", "east", "down", "u", "v", "r")
CURRENT_NAMES = ("n", "e", "d")


def make_fleet(n=N_VEH, edges=EDGES, pinned=PINNED, **changes):
    """Vehicle i owns the 6-block of x (positions first), 3 errors, 3 controls, and the current
    components i-1, i-1+n, i-1+2n of w (interleaved, to exercise the index arrays)."""
    fields = {
        "position_index": np.arange(6 * n).reshape(n, 6)[:, :3],
        "error_index": np.arange(3 * n).reshape(n, 3),
        "control_index": np.arange(3 * n).reshape(n, 3),
        "error_names": ("north", "east", "down"),
        "control_names": ("X_n", "X_e", "X_d"),
        "leader_output": np.array([[1.0, 0.0], [0.0, 1.0], [0.25, -0.5]]),
        "offsets": np.array([[10.0 * i, -5.0 * i, 1.0 + i] for i in range(n)]),
        "edges": edges,
        "pinned": pinned,
        "state_index": np.arange(6 * n).reshape(n, 6),
        "state_names": STATE_NAMES,
        "disturbance_index": np.arange(3 * n).reshape(3, n).T,
        "disturbance_names": CURRENT_NAMES,
    }
    fields.update(changes)
    return FleetLayout(**fields)


def make_fleet_runs(methods=FLEET_METHODS, steps=FLEET_STEPS, n=N_VEH, seed=99):
    """Vehicles drifting around a moving leader (metres, non-round values), random other traces."""
    rng = np.random.default_rng(seed)
    t = np.arange(steps)[:, None] * FLEET_H
    dims = dict(FLEET_DIMS, x=6 * n, w=3 * n, xhat=6 * n, what=3 * n)
    runs = {}
    for m in methods:
        traces = {k: rng.standard_normal((steps, d)) for k, d in dims.items() if k not in ("x", "e", "u")}
        traces["e"] = rng.standard_normal((steps, 3 * n))
        traces["u"] = rng.standard_normal((steps, 3 * n)) * 100.0
        traces["z"] = np.hstack([3.0 * t + 0.1, 500.0 + 0.5 * np.sin(t)])
        x = rng.standard_normal((steps, 6 * n))
        x[:, 0::6] += 3.0 * t + rng.uniform(-50, 50, n)   # north
        x[:, 1::6] += 500.0 + rng.uniform(-50, 50, n)    # east
        x[:, 2::6] += 20.0 + rng.uniform(0, 5, n)        # down
        traces["x"] = x
        runs[m] = traces
    return runs


def recorded_steps(stride, steps=FLEET_STEPS):
    return np.arange(0, steps, stride)


def leader_position(run, fleet):
    """(steps, 3): z @ leader_output.T, summed as the writer does (row by row the same
    whatever the chunks; a BLAS product's last bits are not)."""
    from orchestrator.recording.scene import leader_position as position
    return position(run["z"], np.asarray(fleet.leader_output, dtype=float))


#: strides of the fleet recording, and their test ids
FLEET_STRIDES = [1, 3]
FLEET_STRIDE_IDS = ["stride1", "stride3"]


def write_fleet_recording(tmp_path_factory, stride):
    """The fleet file at ``stride``: (path, runs, fleet, info returned by write_rrd, stride)."""
    runs = make_fleet_runs()
    fleet = make_fleet()
    path = tmp_path_factory.mktemp("rrd") / f"fleet_stride{stride}.rrd"
    info = write_rrd(path, runs, FLEET_H, recording_name="fleet round trip", fleet=fleet,
                     trail_seconds=TRAIL_S, trail_sample_seconds=TRAIL_SAMPLE_S, stride=stride)
    return path, runs, fleet, info, stride
