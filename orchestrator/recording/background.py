"""Write the ``.rrd`` in a child process that imports Rerun while the parent simulates.

Importing rerun-sdk and pyarrow takes about 0.5 s, as long as a third of the paper run's
loop. :class:`BackgroundWriter` starts ``python -m orchestrator.recording.background`` at
once (for ``run`` and ``compare`` at the very start of the command, :func:`prestart`);
the child imports :func:`orchestrator.recording.writer.write_rrd` (and with it Rerun)
on the other core, then waits for the traces on its standard input. :meth:`write` sends
them (pickled: a private pipe between two processes of this program) and waits for the
child's one-line JSON answer, the figures ``write_rrd`` returns. If the child fails, the
error names what it reported; when no child could be started, or the traces are too large
to send (:data:`MAX_PIPE_BYTES`, large fleets), :meth:`BackgroundWriter.write` writes in
this process. So does a writer taken where the writer module, and with it Rerun, is
already imported (a notebook, a host program, the test suite running commands in
process): a child would only pay that import a second time.
"""
from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
from pathlib import Path
from typing import Any

__all__ = ["BackgroundWriter", "MAX_PIPE_BYTES", "prestart"]

#: traces larger than this are written in the parent (large fleets: no second copy)
MAX_PIPE_BYTES = 200_000_000


class BackgroundWriter:
    """A child process ready to write one ``.rrd``; use once, then it exits."""

    def __init__(self, child: bool = True) -> None:
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        self.proc: subprocess.Popen | None = None
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
            :func:`~orchestrator.recording.writer.write_rrd`.

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
            from .writer import write_rrd
            return write_rrd(Path(path), runs, h, **kwargs)
        payload = pickle.dumps((str(path), runs, float(h), kwargs),
                               protocol=pickle.HIGHEST_PROTOCOL)
        out, err = self.proc.communicate(payload)
        if self.proc.returncode != 0:
            lines = err.decode("utf-8", "replace").strip().splitlines()
            raise RuntimeError(f"writing {path} failed: "
                               f"{lines[-1] if lines else f'exit status {self.proc.returncode}'}")
        return json.loads(out.decode())

    def close(self) -> None:
        """Stop the child if it is still waiting (nothing to write after all)."""
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


def _child() -> int:
    from .writer import write_rrd  # the import this process exists to pay

    data = sys.stdin.buffer.read()
    if not data:                             # the parent had nothing to write
        return 0
    path, runs, h, kwargs = pickle.loads(data)
    info = write_rrd(Path(path), runs, h, **kwargs)
    sys.stdout.write(json.dumps(info, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(_child())
