"""The 3D scene of one fleet run under ``world/{method}``, written chunk by chunk as the run goes
(:class:`WorldStream`): one partition per recorded sample, no per-step logs.

What is recorded does not depend on how the run is cut into chunks: every sample is chosen by
its global step (recorded steps k % stride == 0, edges k % scene_stride == 0, trail samples
k % trail_stride == 0, plus the last recorded step for the edges and trails), the number beside
a vehicle waits for the next recorded sample (its direction is the central difference of the
positions around it, as ``np.gradient`` over the whole run), and the leader's whole path (a
static line strip) is kept at the recorded steps, thinned by powers of two past
:data:`PATH_POINTS` points so that it stays bounded.
"""
from __future__ import annotations

import numpy as np
import rerun as rr

from plant_model.remus100.rigid_body import quaternion_xyzw

from .layout import _SIM_TIME, _STEP, _Fleet, _lighter, _vehicle_colors

__all__ = ["PATH_POINTS", "WorldStream", "leader_position", "time_columns"]

#: the hull drawn in the 3D view: the REMUS 100's 1.6 m x 0.19 m spheroid, 3 times enlarged
#: to be seen at formation scale (m, body axes x forward, y starboard, z down)
_HULL_HALF_SIZES = (2.4, 0.285, 0.285)
#: distance (m) of a vehicle's number from the vehicle, to starboard of its course
_LABEL_OFFSET = 4.0
#: the most points kept of the leader's whole path (beyond: every 2nd, 4th, ... recorded one)
PATH_POINTS = 1 << 17


def time_columns(k: np.ndarray, h_ns: int) -> list[rr.TimeColumn]:
    """The ``step`` and ``sim_time`` (integer nanoseconds) columns of the steps ``k``."""
    return [rr.TimeColumn(_STEP, sequence=k),
            rr.TimeColumn(_SIM_TIME, duration=(k * h_ns).astype("timedelta64[ns]"))]


def leader_position(z: np.ndarray, leader_output: np.ndarray) -> np.ndarray:
    """(rows, 3) leader positions ``z @ leader_output.T``, summed column by column so that a
    row's value does not depend on the other rows (a BLAS product's last bits do: on how
    many rows it is given, that is on the chunks)."""
    lead = z[:, 0, None] * leader_output[:, 0]
    for j in range(1, z.shape[1]):
        lead = lead + z[:, j, None] * leader_output[:, j]
    return lead


def _label_positions(pos: np.ndarray, vel: np.ndarray) -> np.ndarray:
    """(rows, N, 3) positions of the vehicles' numbers: ``_LABEL_OFFSET`` m to starboard of
    each vehicle's horizontal course ``vel`` (east when it does not move), so the number sits
    off its own trail."""
    right = np.stack([-vel[..., 1], vel[..., 0], np.zeros(vel.shape[:-1])], axis=-1)
    norm = np.linalg.norm(right, axis=-1, keepdims=True)
    east = np.broadcast_to(np.array([0.0, 1.0, 0.0]), right.shape)
    unit = np.where(norm > 1e-9, right / np.maximum(norm, 1e-12), east)
    return pos + _LABEL_OFFSET * unit


class WorldStream:
    """The 3D scene of one run, written as its chunks arrive (module docstring).

    Parameters
    ----------
    rec : rr.RecordingStream
        The open recording (static styles are logged here once, at the first chunk).
    method : str
        The run's method name.
    fleet : _Fleet
        The validated fleet layout.
    h_ns : int
        Step, ns.
    stride, scene_stride, trail_stride : int
        Steps between recorded samples, 3D edge samples and trail samples (the last two
        multiples of ``stride``).
    """

    def __init__(self, rec: rr.RecordingStream, method: str, fleet: _Fleet, h_ns: int,
                 stride: int, scene_stride: int, trail_stride: int) -> None:
        self.rec, self.fleet, self.h_ns = rec, fleet, h_ns
        self.stride, self.scene_stride, self.trail_stride = stride, scene_stride, trail_stride
        self.root = f"world/{method}"
        self.colors = _vehicle_colors(fleet.n)
        self._styled = False
        self._last: tuple[int, np.ndarray, np.ndarray] | None = None   # (k, pos, leader)
        self._last_edge = -1                      # step of the last edge row written
        self._trail: tuple[int, np.ndarray] | None = None              # last trail sample
        self._label_prev: np.ndarray | None = None                     # (N, 3)
        self._label_pending: tuple[int, np.ndarray] | None = None      # (k, (N, 3))
        self._path: list[np.ndarray] = []          # float32 (rows, 3) pieces, thinned
        self._path_ks: list[np.ndarray] = []
        self._path_every = 1                       # keep recorded samples j % every == 0

    def _styles(self, attitude: bool) -> None:
        rec, root, colors, n = self.rec, self.root, self.colors, self.fleet.n
        rec.log(root, rr.ViewCoordinates.FRD, static=True)
        rec.log(f"{root}/vehicles", rr.Points3D.from_fields(
            radii=[1.0], colors=colors, labels=[str(i) for i in range(1, n + 1)],
            show_labels=False), static=True)
        # the numbers beside the vehicles, off their own trails and edges: to starboard
        rec.log(f"{root}/labels", rr.Points3D.from_fields(
            radii=[0.05], colors=[_lighter(tuple(int(v) for v in c), 0.45) for c in colors],
            labels=[str(i) for i in range(1, n + 1)], show_labels=True),
            static=True)
        if attitude:                     # the nonlinear vehicle: an oriented hull
            rec.log(f"{root}/hulls", rr.Ellipsoids3D.from_fields(
                half_sizes=[_HULL_HALF_SIZES] * n, colors=colors, fill_mode="solid"),
                static=True)
        rec.log(f"{root}/leader", rr.Points3D.from_fields(
            radii=[1.5], colors=[(255, 215, 0)]), static=True)
        rec.log(f"{root}/targets", rr.Points3D.from_fields(
            radii=[0.7], colors=[tuple(_lighter(tuple(int(v) for v in c), 0.55))
                                 for c in colors],
            show_labels=False), static=True)
        n_edges, n_pinned = self.fleet.edges.shape[0], self.fleet.pinned.shape[0]
        if n_edges + n_pinned:
            rec.log(f"{root}/edges", rr.LineStrips3D.from_fields(
                radii=[0.15], colors=[(160, 160, 160)] * n_edges + [(255, 215, 0)] * n_pinned),
                static=True)
        rec.log(f"{root}/trails", rr.LineStrips3D.from_fields(radii=[0.2]), static=True)

    def _points(self, entity: str, ks: np.ndarray, positions: np.ndarray) -> None:
        """One partition of ``positions`` (rows, m, 3) per step of ``ks``."""
        rows, m = positions.shape[:2]
        self.rec.send_columns(entity, indexes=time_columns(ks, self.h_ns),
                              columns=rr.Points3D.columns(
                                  positions=positions.reshape(rows * m, 3).astype(np.float32)
                              ).partition(np.full(rows, m)))

    def send(self, ks: np.ndarray, traces: dict[str, np.ndarray]) -> None:
        """The recorded steps ``ks`` (increasing multiples of ``stride``, after those sent
        before) and the traces' rows at those steps: ``x``, ``z``, ``attitude`` if the vehicle
        has one."""
        fleet, n = self.fleet, self.fleet.n
        if not self._styled:
            self._styles("attitude" in traces)
            self._styled = True
        if ks.size == 0:
            return
        pos = traces["x"][:, fleet.position_index]                          # (rows, N, 3)
        leader = leader_position(traces["z"], fleet.leader_output)          # (rows, 3)
        rows, root = ks.size, self.root
        self._points(f"{root}/vehicles", ks, pos)
        self._labels(ks, pos)
        if "attitude" in traces:
            att = traces["attitude"].reshape(rows * n, 3)
            self.rec.send_columns(f"{root}/hulls", indexes=time_columns(ks, self.h_ns),
                                  columns=rr.Ellipsoids3D.columns(
                                      centers=pos.reshape(rows * n, 3).astype(np.float32),
                                      quaternions=quaternion_xyzw(att).astype(np.float32)
                                  ).partition(np.full(rows, n)))
        self._points(f"{root}/leader", ks, leader[:, None, :])
        self._points(f"{root}/targets", ks, leader[:, None, :] + fleet.offsets[None, :, :])
        self._keep_path(ks, leader)
        on_edges = ks % self.scene_stride == 0
        if on_edges.any():
            self._edges(ks[on_edges], pos[on_edges], leader[on_edges])
        on_trail = ks % self.trail_stride == 0
        if on_trail.any():
            self._trails(ks[on_trail], pos[on_trail])
        self._last = (int(ks[-1]), pos[-1].copy(), leader[-1].copy())

    def _labels(self, ks: np.ndarray, pos: np.ndarray) -> None:
        """Write the numbers of every recorded sample but the newest, which waits for the next
        sample (or :meth:`close`): its course is the central difference around it."""
        steps = ks if self._label_pending is None else np.concatenate(
            [[self._label_pending[0]], ks])
        rows = pos if self._label_pending is None else np.concatenate(
            [self._label_pending[1][None], pos])
        if rows.shape[0] >= 2:
            window = rows if self._label_prev is None else np.concatenate(
                [self._label_prev[None], rows])
            vel = np.gradient(window, axis=0)[window.shape[0] - rows.shape[0]:]
            self._points(f"{self.root}/labels", steps[:-1],
                         _label_positions(rows[:-1], vel[:-1]))
            self._label_prev = rows[-2].copy()
        self._label_pending = (int(steps[-1]), rows[-1].copy())

    def _edges(self, es: np.ndarray, pos: np.ndarray, leader: np.ndarray) -> None:
        fleet = self.fleet
        n_edges, n_pinned = fleet.edges.shape[0], fleet.pinned.shape[0]
        n_seg = n_edges + n_pinned
        if not n_seg:
            return
        e_rows = es.size
        seg = np.empty((e_rows, n_seg, 2, 3), dtype=np.float32)
        seg[:, :n_edges, 0] = pos[:, fleet.edges[:, 0]]
        seg[:, :n_edges, 1] = pos[:, fleet.edges[:, 1]]
        seg[:, n_edges:, 0] = leader[:, None, :]
        seg[:, n_edges:, 1] = pos[:, fleet.pinned]
        self.rec.send_columns(f"{self.root}/edges", indexes=time_columns(es, self.h_ns),
                              columns=rr.LineStrips3D.columns(
                                  strips=seg.reshape(e_rows * n_seg, 2, 3)
                              ).partition(np.full(e_rows, n_seg)))
        self._last_edge = int(es[-1])

    def _trails(self, ts: np.ndarray, pos: np.ndarray) -> None:
        """One segment per vehicle from the previous trail sample to each of ``ts``."""
        if self._trail is not None:
            ts = np.concatenate([[self._trail[0]], ts])
            pos = np.concatenate([self._trail[1][None], pos])
        self._trail = (int(ts[-1]), pos[-1].copy())
        if ts.size < 2:
            return
        n, t_rows = self.fleet.n, ts.size - 1
        seg = np.empty((t_rows, n, 2, 3), dtype=np.float32)
        seg[:, :, 0] = pos[:-1]
        seg[:, :, 1] = pos[1:]
        self.rec.send_columns(f"{self.root}/trails", indexes=time_columns(ts[1:], self.h_ns),
                              columns=rr.LineStrips3D.columns(
                                  strips=seg.reshape(t_rows * n, 2, 3),
                                  colors=np.tile(self.colors, (t_rows, 1)),
                              ).partition(np.full(t_rows, n)))

    def _keep_path(self, ks: np.ndarray, leader: np.ndarray) -> None:
        """Keep the leader at recorded samples j = k / stride with j % every == 0, doubling
        ``every`` while more than :data:`PATH_POINTS` are kept (the same points whatever the
        chunks)."""
        keep = (ks // self.stride) % self._path_every == 0
        self._path.append(leader[keep].astype(np.float32))
        self._path_ks.append(ks[keep])
        while sum(p.shape[0] for p in self._path) > PATH_POINTS:
            self._path_every *= 2
            ks_all = np.concatenate(self._path_ks)
            keep = (ks_all // self.stride) % self._path_every == 0
            self._path = [np.concatenate(self._path)[keep]]
            self._path_ks = [ks_all[keep]]

    def close(self) -> None:
        """The rows that wait for the end of the run: the edges and the trail at the last
        recorded step, the last number, and the leader's whole path (static)."""
        if self._last is None:
            return
        k, pos, leader = self._last
        if self._last_edge != k:
            self._edges(np.array([k], dtype=np.int64), pos[None], leader[None])
        if self._trail is not None and self._trail[0] != k:
            self._trails(np.array([k], dtype=np.int64), pos[None])
        if self._label_pending is not None:
            kp, p = self._label_pending
            window = p[None] if self._label_prev is None else np.stack([self._label_prev, p])
            vel = (np.zeros_like(window) if window.shape[0] < 2
                   else np.gradient(window, axis=0))[-1:]
            self._points(f"{self.root}/labels", np.array([kp], dtype=np.int64),
                         _label_positions(p[None], vel))
            self._label_pending = None
        self.rec.log(f"{self.root}/leader_path", rr.LineStrips3D(
            [np.concatenate(self._path)], radii=[0.12], colors=[(230, 190, 0)]), static=True)
