"""Checkpoints of a long run, and resuming one after a kill (``run --checkpoint-every S``,
``run --resume OUT``).

Between two chunks of steps (:class:`~orchestrator.cosim.master.TraceSink`), at most every
``S`` seconds of wall-clock time, a run writes ``checkpoint/run.pkl`` into its output
folder, atomically (a temporary sibling renamed into place: a kill at any moment leaves
the previous checkpoint or the new one, never half of one). It holds what the run needs to
go on exactly where it stood:

- the scenario and the command's options (method, seed, predictions, master);
- the master's :class:`~orchestrator.cosim.master.MasterState`: the next step, every FMU's
  serialized state (fmi2SerializeFMUstate: their noise generators included), Jacobi's next
  row;
- the statistics accumulated so far (:class:`~orchestrator.running.statistics.RunStatistics`)
  and what the recorder kept (:class:`~orchestrator.running.statistics.RunRecorder`);
- the seconds the loop took so far.

``--resume OUT`` reads it from ``OUT`` (or from the hidden staging folder a killed run left
beside ``OUT``, :mod:`orchestrator.outputs`), instantiates the same FMUs, sets their saved
states and runs the remaining chunks: the traces, the .rrd and the summary's figures equal
an uninterrupted run's bit for bit (the chunks, and with them the statistics' sums, fall on
the same grid, :func:`orchestrator.running.statistics.chunk_steps`).

When: ``--checkpoint-every S`` (wall-clock seconds); by default :data:`DEFAULT_EVERY_S`, so
a run that takes less than that never writes one (a short run loses little when killed)
and a long run loses at most about that much; 0 turns them off. A run whose FMUs cannot
serialize their state (a user's vehicle FMU that says so) runs without checkpoints, and
says so.
"""
from __future__ import annotations

import pickle
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..atomic import write_bytes_atomically
from ..cosim.master import MasterState

if TYPE_CHECKING:
    from ..scenario import Scenario
    from .statistics import RunRecorder

__all__ = ["CHECKPOINT_DIR", "CHECKPOINT_FILE", "DEFAULT_EVERY_S", "CheckpointError",
           "RunCheckpoint", "Saver", "find_checkpoint", "read_checkpoint"]

#: the folder of a run's output that holds its checkpoint
CHECKPOINT_DIR = "checkpoint"
#: the checkpoint file in it
CHECKPOINT_FILE = "run.pkl"
#: wall-clock seconds between two checkpoints by default
DEFAULT_EVERY_S = 60.0
#: the layout of :class:`RunCheckpoint` (a checkpoint of another layout is refused)
FORMAT = 1


class CheckpointError(RuntimeError):
    """A checkpoint that cannot be used (none found, unreadable, another version)."""


@dataclass
class RunCheckpoint:
    """What a resumed run needs (module docstring)."""

    scenario: Scenario
    options: dict[str, Any]                  #: simulate's options (predict, master, ...)
    method: str                              #: the method's name
    seed: int
    master: MasterState                      #: the step and every FMU's state
    recorder: RunRecorder                    #: statistics so far, what it kept
    loop_s: float                            #: seconds in the loop so far
    saved_at: float = field(default_factory=time.time)     #: wall clock, s since the epoch
    format: int = FORMAT
    versions: dict[str, str] = field(default_factory=dict)  #: the packages that wrote it


class Saver:
    """The master's :class:`~orchestrator.cosim.master.Checkpoints` of one run: due once
    ``every_s`` wall-clock seconds passed since the run began or the last checkpoint;
    ``save`` writes ``<folder>/checkpoint/run.pkl`` atomically.

    Parameters
    ----------
    folder : Path
        The run's output folder.
    every_s : float
        Seconds between checkpoints (> 0).
    make : callable
        ``make(state)``: the :class:`RunCheckpoint` of the run at that master state.
    """

    def __init__(self, folder: Path, every_s: float,
                 make: Callable[[MasterState], RunCheckpoint]):
        self.path = Path(folder) / CHECKPOINT_DIR / CHECKPOINT_FILE
        self.every_s, self.make = float(every_s), make
        self.last = time.monotonic()
        self.count = 0                               #: checkpoints written
        self.seconds = 0.0                           #: spent writing them
        self.step = 0                                #: the step of the last one

    def due(self, step: int) -> bool:
        """Whether ``every_s`` seconds passed since the last checkpoint."""
        return time.monotonic() - self.last >= self.every_s

    def save(self, state: MasterState) -> None:
        """Write the checkpoint at ``state`` (atomically)."""
        t0 = time.perf_counter()
        data = pickle.dumps(self.make(state), protocol=pickle.HIGHEST_PROTOCOL)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        write_bytes_atomically(self.path, data)
        self.count += 1
        self.step = state.step
        self.seconds += time.perf_counter() - t0
        self.last = time.monotonic()


def find_checkpoint(out: Path) -> Path:
    """The newest checkpoint of the run whose output folder is ``out``: in ``out``, in
    ``<out>.interrupted``, or in a staging folder a killed run left beside it.

    Raises
    ------
    CheckpointError
        If there is none, naming where it looked.
    """
    from ..swap import stale_of
    out = Path(out)
    places = [out, out.with_name(out.name + ".interrupted")]
    if out.parent.is_dir():
        places += stale_of(out)
    found = [p / CHECKPOINT_DIR / CHECKPOINT_FILE for p in places
             if (p / CHECKPOINT_DIR / CHECKPOINT_FILE).is_file()]
    if not found:
        raise CheckpointError(f"--resume {out}: no checkpoint there (looked for "
                              f"{CHECKPOINT_DIR}/{CHECKPOINT_FILE} in {out}, "
                              f"{places[1].name} and the folders a killed run leaves beside "
                              "it); a run writes one every --checkpoint-every seconds")
    return max(found, key=lambda p: p.stat().st_mtime)


def read_checkpoint(path: Path) -> RunCheckpoint:
    """The checkpoint in ``path``.

    Raises
    ------
    CheckpointError
        If it cannot be read or is of another format, in one line.
    """
    try:
        ck = pickle.loads(Path(path).read_bytes())
    except Exception as exc:                    # truncated, or not ours
        raise CheckpointError(f"{path}: not a readable checkpoint ({type(exc).__name__}: "
                              f"{exc})") from None
    if not isinstance(ck, RunCheckpoint) or ck.format != FORMAT:
        raise CheckpointError(f"{path}: a checkpoint of another version of auv-cosim; "
                              "run the scenario again")
    return ck
