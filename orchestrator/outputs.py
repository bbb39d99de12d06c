"""Output folders: safe file names, one writer at a time, refused early when unwritable.

- :func:`file_stem` turns a scenario name into a file name that stays inside the folder
  (no separators, no ``..``, no control characters);
- :func:`output_folder` creates ``--out``, checks it can be written, and holds an exclusive
  lock on it (``fcntl.flock`` on ``<out>/.auv-cosim.lock``) for the whole command: a second
  ``run``, ``compare``, ``build`` or ``export`` into the same folder is refused in one line
  naming the process that holds it. The lock goes with the process (the kernel releases it
  when the holder exits or is killed), so a crashed run never leaves the folder locked;
- :func:`claim_folder` keeps runs from mixing: the folder records what kind of run wrote it
  (``.auv-cosim-run.json``: command, scenario, deployment, architecture, links, vehicle
  models, FMU kind); another kind of run is refused in one line unless ``--force``, and the
  outputs of the run it replaces (summary, recording, figures, FMUs, per-plant and
  per-point subfolders) are removed before it writes.
"""
from __future__ import annotations

import errno
import fcntl
import json
import os
import re
import shutil
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

__all__ = ["LOCK_NAME", "RUN_MARKER", "OutputFolderError", "claim_folder", "file_stem",
           "make_folder", "output_folder"]

#: name of the lock file in an output folder
LOCK_NAME = ".auv-cosim.lock"

#: what kind of run wrote an output folder
RUN_MARKER = ".auv-cosim-run.json"
#: what a run writes into its folder (besides subfolders holding a summary.json)
RUN_OUTPUTS = ("summary.json", "figures", "fmus", "points")

_UNSAFE = re.compile(r"[^A-Za-z0-9._+-]+")


class OutputFolderError(RuntimeError):
    """An output folder that cannot be used: held by another process, or not writable."""


def file_stem(name: str, default: str = "scenario") -> str:
    """A file name made from ``name``: runs of characters other than letters, digits and
    ``. _ + -`` become ``_``, leading dots are dropped (no ``..``, no hidden file), at
    most 100 characters; ``default`` if nothing is left.

    Parameters
    ----------
    name : str
        A scenario (or vehicle) name, as the user wrote it.
    default : str
        The stem when ``name`` has no usable character.

    Returns
    -------
    str
        ``"../x"`` -> ``"_x"``, ``"a/b c"`` -> ``"a_b_c"``, ``"paper"`` -> ``"paper"``.
    """
    stem = _UNSAFE.sub("_", name).lstrip(".")[:100]
    return stem if stem.strip("_") else default


def _holder(lock_path: Path) -> str:
    try:
        text = lock_path.read_text(encoding="utf-8", errors="replace").strip()
    except OSError:
        return "another process"
    return text or "another process"


def make_folder(out: Path | str) -> Path:
    """Create ``out`` with its parents and check it can be written; one-line errors for a
    file in the way or no right.

    Parameters
    ----------
    out : Path or str
        The folder.

    Returns
    -------
    Path
        The folder.

    Raises
    ------
    OutputFolderError
        If it is a file, under a file, cannot be created or cannot be written.
    """
    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise OutputFolderError(f"output folder {out} is a file") from None
    except NotADirectoryError:
        raise OutputFolderError(f"output folder {out} is under a file") from None
    except PermissionError:
        raise OutputFolderError(f"cannot create the output folder {out}: permission "
                                "denied") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise OutputFolderError(f"cannot write into the output folder {out}: permission "
                                "denied (choose another --out)")
    return out


@contextmanager
def output_folder(out: Path | str, command: str) -> Iterator[Path]:
    """Create ``out`` and hold it for ``command`` until the block ends.

    Parameters
    ----------
    out : Path or str
        The output folder (created with its parents).
    command : str
        What is writing (for the message a second writer gets), e.g. ``"run"``.

    Yields
    ------
    Path
        The folder.

    Raises
    ------
    OutputFolderError
        If another process holds the folder, or it cannot be written (one line, naming it).
    """
    out = make_folder(out)
    lock_path = out / LOCK_NAME
    try:
        fd = os.open(lock_path, os.O_RDWR | os.O_CREAT, 0o644)
    except PermissionError:
        raise OutputFolderError(f"cannot write into the output folder {out}: permission "
                                "denied (choose another --out)") from None
    except OSError as exc:
        raise OutputFolderError(f"cannot write into the output folder {out}: "
                                f"{exc.strerror}") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise
            raise OutputFolderError(
                f"output folder {out} is in use by {_holder(lock_path)}; wait for it to "
                "finish or choose another --out") from None
        stamp = time.strftime("%Y-%m-%d %H:%M:%S")
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"auv-cosim {command} (pid {os.getpid()}, since {stamp})\n"
                  .encode(), 0)
        yield out
    finally:
        os.close(fd)           # releases the lock; the file stays (removing it would race)



def _describe(identity: Mapping[str, str]) -> str:
    return ", ".join(f"{k} {v}" for k, v in identity.items())


def claim_folder(out: Path, identity: Mapping[str, str], *, force: bool = False) -> None:
    """Make ``out`` (held with :func:`output_folder`) the folder of a run of ``identity``:
    refuse it if it holds another kind of run's outputs (unless ``force``), then remove the
    outputs of the run it replaces, so that no figure, recording or subfolder of an
    earlier run is left beside the new ones.

    Parameters
    ----------
    out : Path
        The output folder.
    identity : Mapping[str, str]
        What makes the run distinct (command, scenario, deployment, ...).
    force : bool, optional
        Replace another kind of run's outputs.

    Raises
    ------
    OutputFolderError
        Naming both runs, if the folder holds another kind of run and ``force`` is off.
    """
    marker = out / RUN_MARKER
    try:
        previous = json.loads(marker.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        previous = None
    subfolders = [p for p in out.iterdir() if p.is_dir() and (p / "summary.json").exists()]
    outputs = [p for p in out.iterdir() if p.name in RUN_OUTPUTS or p.suffix == ".rrd"]
    identity = dict(identity)
    # outputs without a record (written before folders recorded their run) are replaced
    if (outputs or subfolders) and isinstance(previous, dict) and previous != identity \
            and not force:
        raise OutputFolderError(
            f"output folder {out} holds a run of {_describe(previous)}, not of "
            f"{_describe(identity)}; choose another --out, or add --force to replace it")
    for p in outputs + subfolders:
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p)
        else:
            p.unlink(missing_ok=True)
    from .atomic import write_text_atomically
    write_text_atomically(marker, json.dumps(identity, indent=1) + "\n")
