"""A run watched live in a Rerun viewer (``--live``): where the viewer is, and what it
alone is sent.

:class:`~orchestrator.recording.stream.RrdStream` with ``live=URL`` writes its rows to
its file and, through Rerun's own gRPC sink (``RecordingStream.set_sinks(FileSink,
GrpcSink)``), to the viewer at ``URL`` as they are written. Before the first rows the
viewer gets a blueprint of its own, the run's layout with automatic y-axes and camera
(:func:`~orchestrator.recording.blueprint._blueprint` with ``fixed=False``: the data are
still to come), and the colour legend; at the close, the final blueprint (the file's, its
ranges known) is made the viewer's active one. Those go to the viewer alone, through a
second recording stream with the same application and recording id
(:class:`LiveViewer`): the file is the same with or without a viewer.

Where the viewer is: :func:`live_url` spawns one (Rerun's ``spawn``, the ``rerun`` of
this environment) or checks that the one at a URL answers, before the run starts; a
viewer that cannot be reached is refused in one line naming the URL
(:class:`LiveViewerError`).
"""
from __future__ import annotations

import socket
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any
from urllib.parse import urlsplit

if TYPE_CHECKING:
    import numpy as np
    import rerun as rr
    import rerun.blueprint as rrb


__all__ = ["DEFAULT_PORT", "LIVE_ROW_SECONDS", "SPAWN", "LiveViewer", "LiveViewerError",
           "check_viewer", "live_url", "spawn_viewer"]

#: ``--live`` without a URL: spawn a viewer
SPAWN = "spawn"
#: the port of a viewer ``--live`` spawns (Rerun's default)
DEFAULT_PORT = 9876
#: wall-clock seconds between two writes of rows to a live viewer (with ``--realtime``)
LIVE_ROW_SECONDS = 0.2
#: how long a viewer may take to accept a connection, s
_CONNECT_S = 2.0
#: how long the final blueprint may take to reach the viewer at the close, s
_FLUSH_S = 5.0
_SCHEMES = {"rerun": 443, "rerun+https": 443, "rerun+http": 80}


class LiveViewerError(ValueError):
    """A viewer that cannot be reached or a URL that is not a viewer's (one line)."""


def check_viewer(url: str, timeout: float = _CONNECT_S) -> str:
    """Check that a Rerun viewer's gRPC server answers at ``url``.

    Parameters
    ----------
    url : str
        ``rerun+http://HOST:PORT/proxy`` (or ``rerun+https://``, ``rerun://``: Rerun's
        forms; the path is ``/proxy``).
    timeout : float, optional
        Seconds to wait for the connection.

    Returns
    -------
    str
        ``url``.

    Raises
    ------
    LiveViewerError
        Not a viewer's URL, or nothing accepts a connection there (one line, naming it).
    """
    parts = urlsplit(url)
    if parts.scheme not in _SCHEMES or not parts.hostname or parts.path.rstrip("/") != "/proxy":
        raise LiveViewerError(f"--live {url}: not a Rerun viewer's URL (give "
                              f"rerun+http://HOST:PORT/proxy, e.g. "
                              f"rerun+http://127.0.0.1:{DEFAULT_PORT}/proxy)")
    try:
        port = parts.port or _SCHEMES[parts.scheme]
    except ValueError:
        raise LiveViewerError(f"--live {url}: not a port number") from None
    try:
        with socket.create_connection((parts.hostname, port), timeout=timeout):
            pass
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise LiveViewerError(f"--live: no Rerun viewer answers at {url} ({reason.lower()}); "
                              f"start one (rerun) or give --live alone to spawn one"
                              ) from None
    return url


def _rerun_executable() -> str | None:
    """The ``rerun`` beside this Python (a venv's), if there is one: a fresh shell may have
    none on its PATH."""
    exe = Path(sys.executable).with_name("rerun")
    return str(exe) if exe.exists() else None


def spawn_viewer(port: int = DEFAULT_PORT) -> str:
    """A Rerun viewer listening on ``port`` (Rerun's ``spawn``: it starts the ``rerun``
    beside this Python, or on the PATH, unless one already listens there), its URL.

    Raises
    ------
    LiveViewerError
        If no viewer could be started (one line).
    """
    import rerun as rr
    url = f"rerun+http://127.0.0.1:{port}/proxy"
    try:
        rr.spawn(port=port, connect=False, hide_welcome_screen=True,
                 executable_path=_rerun_executable())
    except Exception as exc:                # the binding's error: not found, cannot start
        raise LiveViewerError(f"--live: could not start a Rerun viewer on port {port}: "
                              f"{str(exc).splitlines()[0] if str(exc) else exc!r}") from None
    return check_viewer(url, timeout=10.0)


def live_url(value: str | None) -> str | None:
    """The URL of ``--live``'s viewer: None without ``--live``; :data:`SPAWN` spawns one
    (:func:`spawn_viewer`); a URL is checked (:func:`check_viewer`). Raises
    :class:`LiveViewerError`."""
    if value is None:
        return None
    if value == SPAWN:
        return spawn_viewer()
    return check_viewer(value)


def live_chunk_steps(h: float, realtime: float | None, default: int) -> int:
    """Steps per chunk of a run watched live: with ``realtime``, the largest power of two
    within :data:`LIVE_ROW_SECONDS` of wall clock (at least 1, at most ``default``), so
    the viewer gets rows a few times a second; without, ``default`` (the run goes as fast
    as it can, and its chunks come as fast)."""
    if realtime is None:
        return default
    steps = max(1, int(LIVE_ROW_SECONDS * realtime / h))
    return max(1, min(default, 1 << (steps.bit_length() - 1)))


class LiveViewer:
    """What the live viewer alone gets (module docstring): a recording stream with the
    run's application and recording id, connected to the viewer only.

    Parameters
    ----------
    rec : rr.RecordingStream
        The run's recording (its ids).
    url : str
        The viewer.
    """

    def __init__(self, rec: rr.RecordingStream, url: str) -> None:
        import rerun as rr
        from rerun.recording_stream import get_application_id
        self.url = url
        self.rec = rr.RecordingStream(get_application_id(rec),
                                      recording_id=rec.get_recording_id())
        self.rec.connect_grpc(url)

    def start(self, blueprint: rrb.Blueprint, legend: str) -> None:
        """The live layout, made the active one, and the colour legend."""
        import rerun as rr

        from .blueprint import LEGEND_ENTITY
        self.rec.send_blueprint(blueprint, make_active=True, make_default=False)
        self.rec.log(LEGEND_ENTITY, rr.TextDocument(legend, media_type=rr.MediaType.MARKDOWN),
                     static=True)
        self.rec.flush(timeout_sec=0.0)

    def replay(self, files: list[Path]) -> None:
        """The recording so far, from its .rrd segment files (a resumed run: Rerun's own
        loader, into the viewer alone)."""
        for f in files:
            self.rec.log_file_from_path(f)
        self.rec.flush(timeout_sec=_FLUSH_S)

    def finish(self, blueprint: rrb.Blueprint) -> None:
        """The final blueprint, made the viewer's active one (the file's only the default:
        a viewer keeps the active one), then the connection closed."""
        try:
            self.rec.send_blueprint(blueprint, make_active=True, make_default=True)
            self.rec.flush(timeout_sec=_FLUSH_S)
        except Exception:                   # a viewer gone: the file is what matters
            pass
        self.rec.disconnect()


def start_live(stream: Any, method: str, clean: dict[str, np.ndarray]) -> LiveViewer:
    """Send the live viewer of ``stream`` its layout and legend, before the first rows
    (``clean``: the first chunk of the first method, the traces' dimensions and kinds).

    Parameters
    ----------
    stream : RrdStream
        Opened with ``live``; its first method's first chunk just validated.
    method : str
        That method.
    clean : dict[str, np.ndarray]
        Its traces.

    Returns
    -------
    LiveViewer
        For the final blueprint (:meth:`LiveViewer.finish`).
    """
    import numpy as np

    from .blueprint import _blueprint, _fleet_blueprint
    from .writer import _fleet_legend, _paper_legend
    viewer = LiveViewer(stream._rec, stream.live)
    runs = {m: clean for m in stream.methods}           # the layout of every method to come
    if stream._fleet is None:
        blueprint = _blueprint(runs, fixed=False, selection=stream.selection)
        legend = _paper_legend(stream.methods, stream.colors)
    else:
        fleet = stream._fleet
        links = {m: stream.links.get(m, stream.links.get(method)) for m in stream.methods
                 if stream.links.get(m, stream.links.get(method)) is not None}
        blueprint = _fleet_blueprint(stream.methods, fleet, stream.trail_ns, stream.trail_steps,
                                     runs, links=links or None, points=np.zeros((1, 3)),
                                     fixed=False, selection=stream.selection)
        legend = _fleet_legend(stream.methods, fleet,
                               "rpm" in clean and stream.selection.has("actuators"))
    viewer.start(blueprint, legend)
    return viewer

