"""Write the ``.rrd`` in a child process that imports Rerun while the parent simulates.

Importing rerun-sdk and pyarrow takes about 0.5 s, as long as a third of the paper run's
loop. :class:`BackgroundWriter` starts ``python -m orchestrator.recording.background`` at
once (for ``run`` and ``compare`` at the very start of the command, :func:`prestart`);
the child imports :func:`orchestrator.recording.whole.write_rrd` (and with it Rerun)
on the other core, then waits for length-prefixed pickled frames on its standard input
(a private pipe between two processes of this program). Either :meth:`write` sends the
whole traces in one frame and waits for the child's one-line JSON answer, the figures
``write_rrd`` returns; or :meth:`stream` returns a :class:`ChildStream` whose ``send``
passes each chunk of a run to the child as it comes (the child writes it to the file at
once, :class:`~orchestrator.recording.stream.RrdStream`) and whose ``close`` answers the
figures. If the child fails, the error names the last line it reported; when no child
could be started, or the traces are too large to send in one frame (:data:`MAX_PIPE_BYTES`,
large fleets: stream them instead), the writing happens in this process. So does a writer
taken where the writer module, and with it Rerun, is already imported (a notebook, a host
program, the test suite running commands in process): a child would only pay that import a
second time.
"""
from __future__ import annotations

import json
import os
import pickle
import struct
import subprocess
import sys
import threading
from collections import deque
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import IO, Any

__all__ = ["BackgroundWriter", "ChildStream", "MAX_PIPE_BYTES", "prestart"]

#: traces larger than this are written in the parent (large fleets: no second copy)
MAX_PIPE_BYTES = 200_000_000


class BackgroundWriter:
    """A child process ready to write one ``.rrd``; use once, then it exits."""

    def __init__(self, child: bool = True) -> None:
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        self.proc: subprocess.Popen | None = None
        self._stream: Any = None                    # the stream handed out, if any
        if not child:                               # write in this process
            return
        try:
            self.proc = subprocess.Popen(
                [sys.executable, "-m", "orchestrator.recording.background"],
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                env=env, start_new_session=True)    # Ctrl-C stops the parent's runs only
        except OSError:
            self.proc = None

    @classmethod
    def take(cls) -> BackgroundWriter:
        """The writer :func:`prestart` started (once), else a new one: one that writes in
        this process when Rerun's writer is imported here already, else a child."""
        global _PRESTARTED
        writer, _PRESTARTED = _PRESTARTED, None
        if writer is not None:
            return writer
        return cls(child=f"{__package__}.writer" not in sys.modules)

    def write(self, path: Path | str, runs: dict[str, dict[str, Any]], h: float,
              **kwargs: Any) -> dict[str, Any]:
        """``write_rrd(path, runs, h, **kwargs)`` in the child.

        Written here instead if there is no child or the traces are too large to send
        (:data:`MAX_PIPE_BYTES`).

        Parameters
        ----------
        path : Path or str
            Output .rrd file.
        runs : dict[str, dict[str, Any]]
            Method name -> traces (arrays of shape (steps, dim)).
        h : float
            Sampling period, s.
        **kwargs : Any
            The other keyword arguments of
            :func:`~orchestrator.recording.whole.write_rrd`.

        Returns
        -------
        dict[str, Any]
            The figures ``write_rrd`` returns (``rrd_s``, ``signals``, ``bytes``).

        Raises
        ------
        RuntimeError
            If the child fails (naming the last line it reported).
        ValueError
            If ``write_rrd`` refuses the arguments (when written here).
        """
        size = sum(getattr(a, "nbytes", 0) for tr in runs.values() for a in tr.values())
        if self.proc is None or size > MAX_PIPE_BYTES:
            self.close()
            from .whole import write_rrd
            return write_rrd(Path(path), runs, h, **kwargs)
        out, err = self.proc.communicate(_frame(("write", str(path), runs, float(h), kwargs)))
        if self.proc.returncode != 0:
            lines = err.decode("utf-8", "replace").strip().splitlines()
            raise RuntimeError(f"writing {path} failed: "
                               f"{lines[-1] if lines else f'exit status {self.proc.returncode}'}")
        return json.loads(out.decode())

    def stream(self, path: Path | str, methods: Sequence[str], h: float,
               resume: tuple[bytes, Path | str] | None = None, **kwargs: Any) -> Any:
        """An ``RrdStream(path, methods, h, **kwargs)`` in the child: a :class:`ChildStream`
        with the same ``send``, ``close`` and ``abort``; an
        :class:`~orchestrator.recording.stream.RrdStream` in this process if there is no
        child. Use once; :meth:`close` (the ``with`` block's end) aborts a stream not closed.

        Parameters
        ----------
        path : Path or str
            Output .rrd file.
        methods : Sequence[str]
            The methods that will be sent.
        h : float
            Step, s.
        resume : (bytes, Path), optional
            Go on from a checkpoint: the state
            :meth:`~orchestrator.recording.stream.RrdStream.checkpoint` returned and the
            folder of its segments (``methods``, ``h`` and ``kwargs`` are then the state's).
        **kwargs : Any
            The other keyword arguments of
            :class:`~orchestrator.recording.stream.RrdStream`.

        Returns
        -------
        ChildStream or RrdStream
            ``send(method, k0, traces)``, ``checkpoint(folder) -> bytes``,
            ``close(last_step=None) -> dict``, ``abort()``.
        """
        if self.proc is None:
            self.close()
            from .stream import RrdStream
            self._stream = (RrdStream(path, methods, h, **kwargs) if resume is None else
                            RrdStream.resumed(resume[0], resume[1], path,
                                              kwargs.get("live")))
        else:
            proc, self.proc = self.proc, None
            self._stream = ChildStream(proc, path, methods, h, kwargs, resume)
        return self._stream

    def close(self) -> None:
        """Stop the child if it is still waiting (nothing to write after all), and abort a
        stream handed out and not closed."""
        stream, self._stream = self._stream, None
        if stream is not None:
            stream.abort()
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        self.proc = None

    def __enter__(self) -> BackgroundWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


#: the writer started by :func:`prestart`, not yet taken
_PRESTARTED: BackgroundWriter | None = None


def prestart() -> None:
    """Start the child now, before the command imports its modules (about 0.5 s of the
    paper run): the child's Rerun import then overlaps the parent's imports as well as
    its simulation. The next :meth:`BackgroundWriter.take` gets it; if nothing takes it,
    the child reads an empty input when this process exits and ends."""
    global _PRESTARTED
    if _PRESTARTED is None:
        _PRESTARTED = BackgroundWriter()


class ChildStream:
    """The parent's end of an :class:`~orchestrator.recording.stream.RrdStream` in the
    child: each call is a frame on the child's standard input. A failure in the child
    (which then removes its temporary file and exits) is raised as RuntimeError, naming
    the last line it reported, by the next call; so is a chunk the child refuses."""

    def __init__(self, proc: subprocess.Popen, path: Path | str, methods: Sequence[str],
                 h: float, kwargs: dict[str, Any],
                 resume: tuple[bytes, Path | str] | None = None) -> None:
        self.proc: subprocess.Popen | None = proc
        self.path = Path(path)
        self._lines: deque[bytes] = deque(maxlen=100)
        self._spec: Any = None                  # the child's, its first answer (_ready)
        self._links: dict[str, list[str]] = {}
        self._drain = threading.Thread(target=self._drain_stderr, args=(proc.stderr,),
                                       daemon=True)
        self._drain.start()
        if resume is None:
            self._put(("open", str(path), list(methods), float(h), kwargs))
        else:
            self._put(("resume", str(path), resume[0], str(resume[1]), kwargs.get("live")))

    def _drain_stderr(self, err: IO[bytes]) -> None:
        """Keep the child's last lines of standard error (and never let the pipe fill)."""
        for line in iter(err.readline, b""):
            self._lines.append(line)

    def _failure(self) -> RuntimeError:
        assert self.proc is not None
        self.proc.wait()
        self._drain.join(timeout=5.0)
        self.proc = None
        lines = [ln.decode("utf-8", "replace").strip() for ln in self._lines]
        lines = [ln for ln in lines if ln]
        return RuntimeError(f"writing {self.path} failed: "
                            f"{lines[-1] if lines else 'the writer process ended'}")

    def _put(self, message: tuple) -> None:
        if self.proc is None:
            raise RuntimeError(f"writing {self.path}: the stream is closed")
        try:
            assert self.proc.stdin is not None
            self.proc.stdin.write(_frame(message))
            self.proc.stdin.flush()
        except (BrokenPipeError, ConnectionResetError):
            raise self._failure() from None

    def _ready(self) -> tuple[Any, dict[str, list[str]]]:
        """The child stream's :class:`~.chunks.ChunkSpec` and links, its first answer."""
        if self._spec is None:
            assert self.proc is not None and self.proc.stdout is not None
            reply = _read_frame(self.proc.stdout)
            if reply is None:
                raise self._failure()
            self._spec, self._links = reply[1], dict(reply[2])
        return self._spec, self._links

    def send(self, method: str, k0: int, traces: Mapping[str, Any],
             links: Sequence[str] | None = None) -> None:
        """:meth:`~orchestrator.recording.stream.RrdStream.send` in the child: the chunk is
        reduced here to what the file keeps (:func:`~.chunks.digest`: the recorded rows of
        the recorded outputs, the extremes of every step) and that is copied into the pipe
        (the caller may reuse its arrays at once). A bad chunk raises ValueError here."""
        if self.proc is None:
            raise RuntimeError(f"writing {self.path}: the stream is closed")
        from .chunks import digest
        spec, known = self._ready()
        chunk = digest(spec, method, int(k0), traces, links is not None or method in known)
        if chunk is None:
            return
        if links is not None:
            known.setdefault(method, list(links))
        self._put(("take", chunk, None if links is None else list(links)))

    def checkpoint(self, folder: Path | str) -> bytes:
        """:meth:`~orchestrator.recording.stream.RrdStream.checkpoint` in the child: its
        state, answered as a frame on its standard output."""
        self._ready()
        self._put(("checkpoint", str(folder)))
        assert self.proc is not None and self.proc.stdout is not None
        reply = _read_frame(self.proc.stdout)
        if reply is None:
            raise self._failure()
        return reply[1]

    def close(self, last_step: int | None = None) -> dict[str, Any]:
        """:meth:`~orchestrator.recording.stream.RrdStream.close` in the child; its figures."""
        self._ready()
        self._put(("close", last_step))
        assert self.proc is not None and self.proc.stdin is not None
        self.proc.stdin.close()
        out = self.proc.stdout.read() if self.proc.stdout is not None else b""
        if self.proc.wait() != 0:
            raise self._failure()
        self._drain.join(timeout=5.0)
        self.proc = None
        return json.loads(out.decode())

    def abort(self) -> None:
        """Stop the child and remove its temporary file; nothing after close."""
        proc, self.proc = self.proc, None
        if proc is None:
            return
        try:
            proc.stdin.close()                  # the child aborts at the end of its input
            proc.wait(timeout=10.0)
        except (OSError, subprocess.TimeoutExpired):
            proc.kill()
            proc.wait()
        self.path.with_name(f".{self.path.name}.{proc.pid}.part").unlink(missing_ok=True)

    def __enter__(self) -> ChildStream:
        return self

    def __exit__(self, *exc: object) -> None:
        self.abort()


def _frame(message: tuple) -> bytes:
    """A message as one frame: its pickle's length (8 bytes, little-endian), the pickle."""
    data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    return struct.pack("<Q", len(data)) + data


def _read_frame(inp: IO[bytes]) -> tuple | None:
    """The next frame's message, None at the end of the input."""
    head = inp.read(8)
    if len(head) < 8:
        return None
    (size,) = struct.unpack("<Q", head)
    data = inp.read(size)
    if len(data) < size:
        return None
    return pickle.loads(data)


def _child() -> int:
    from .stream import RrdStream
    from .whole import write_rrd  # the import this process exists to pay

    inp = sys.stdin.buffer
    message = _read_frame(inp)
    if message is None:                      # the parent had nothing to write
        return 0
    if message[0] == "write":
        _, path, runs, h, kwargs = message
        info = write_rrd(Path(path), runs, h, **kwargs)
    else:
        if message[0] == "resume":
            _, path, state, folder, live = message
            opened = RrdStream.resumed(state, folder, path, live)
        else:
            _, path, methods, h, kwargs = message
            opened = RrdStream(path, methods, h, **kwargs)
        with opened as stream:                  # aborted unless closed
            sys.stdout.buffer.write(_frame(("spec", stream.spec, stream.links)))
            sys.stdout.buffer.flush()
            while True:
                message = _read_frame(inp)
                if message is None:          # the parent aborted or died
                    return 0
                if message[0] == "take":
                    stream.take(*message[1:])
                elif message[0] == "checkpoint":
                    sys.stdout.buffer.write(_frame(("state", stream.checkpoint(message[1]))))
                    sys.stdout.buffer.flush()
                else:
                    info = stream.close(message[1])
                    break
    sys.stdout.write(json.dumps(info, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(_child())
