"""Output folders: safe file names, one writer at a time, and a result that replaces the
earlier one only when it is complete.

- :func:`file_stem` turns a scenario name into a file name that stays inside the folder
  (no separators, no ``..``, no control characters);
- :func:`output_folder` holds an exclusive lock on a destination for the whole command
  (``fcntl.flock`` on ``.<name>.lock`` beside it, in its parent: the folder itself is
  swapped): a second command into the same folder is refused in one line naming the
  process that holds it. The kernel releases the lock when its holder exits or is killed;
- :func:`staged_output`, the context manager every command that writes a folder uses
  (``run``, ``compare``, ``envelope``, ``campaign``, ``plot``, ``build``, ``export``):
  the command writes into a private staging folder beside the destination
  (``.<name>.staging-<pid>-<token>``, same file system) and :meth:`Staging.finish` swaps it
  in whole (:mod:`orchestrator.swap`). A refused, failed or interrupted command leaves the
  earlier result byte for byte as it was and says so in one line.

What a staged command keeps:

- the destination records what kind of run wrote it (``.auv-cosim-run.json``: command,
  scenario, deployment, architecture, links, vehicle models, FMU kind, and the names it
  wrote); another kind of run is refused in one line unless ``--force``;
- the earlier result's own files (the names it recorded) are replaced as a whole: nothing
  of another scenario's build or run is left beside the new files; any other file or
  folder (a user's notes) is carried over into the new result (hard links, no copy);
- completed: the staging folder replaces the destination;
- failed, or stopped before it produced anything: the staging folder is deleted, the
  destination is untouched;
- interrupted with a partial result: with no earlier result the partial (marked
  interrupted) becomes the destination; with an earlier result that stays and the partial
  goes to ``<name>.interrupted`` beside it (an older one there is replaced). A resumable
  command (``campaign``) replaces an earlier result that was itself unfinished;
- killed (SIGKILL): the staging folder stays behind, hidden; the next command into the
  same parent folder deletes it (its lock is free; a campaign's is resumed by the next
  campaign into its destination, or deleted by another command there).
"""
from __future__ import annotations

import fcntl
import json
import os
import re
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from . import swap

__all__ = ["LOCK_NAME", "RUN_MARKER", "OutputFolderError", "Staging", "check_claim",
           "file_stem", "lock_path", "make_folder", "output_folder", "staged_output"]

#: the lock file inside an output folder of earlier versions (marks a folder as ours)
LOCK_NAME = ".auv-cosim.lock"

#: what kind of run wrote an output folder, and the names it wrote
RUN_MARKER = ".auv-cosim-run.json"
#: the suffix of the sibling that keeps an interrupted partial result beside an earlier one
INTERRUPTED = ".interrupted"
#: names and suffixes of what earlier versions wrote (folders without a list of names)
_LEGACY_NAMES = {"summary.json", "figures", "fmus", "points", "crosscheck", "parts",
                 "campaign.json", "README.md"}
_LEGACY_SUFFIXES = {".rrd", ".fmu", ".ssp", ".xml", ".parquet", ".svg", ".png", ".pdf"}

#: what other commands write into a run's folder and goes with the run: ``plot``'s default
#: ``figures`` (and its lock); a new run into the folder replaces them with the earlier run
DERIVED = {"figures"}

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



def _target(out: Path) -> Path:
    """The real folder ``out`` names (symlinks resolved: a symlinked destination keeps its
    link, the folder it points to is swapped)."""
    return Path(os.path.realpath(out))


def lock_path(out: Path | str) -> Path:
    """``<parent>/.<name>.lock``: the file :func:`output_folder` locks for ``out``."""
    return swap.lock_file(_target(Path(out)))


def _check_destination(out: Path, target: Path) -> None:
    """One-line refusals before anything is created: a file in the way, the working
    folder (or a folder holding it), a folder that cannot be replaced."""
    if target.exists() and not target.is_dir():
        raise OutputFolderError(f"output folder {out} is a file")
    if target == target.parent:
        raise OutputFolderError(f"output folder {out} is the root of the file system; "
                                "choose another --out")
    here = Path(os.path.realpath(os.getcwd()))
    if here == target or target in here.parents:
        raise OutputFolderError(f"output folder {out} holds the working folder (it is "
                                "replaced whole when the command completes); choose "
                                "another --out")
    if target.is_dir() and not os.access(target, os.W_OK | os.X_OK):
        raise OutputFolderError(f"cannot write into the output folder {out}: permission "
                                "denied (choose another --out)")


@contextmanager
def output_folder(out: Path | str, command: str) -> Iterator[Path]:
    """Hold the destination ``out`` for ``command`` until the block ends: an exclusive
    lock on ``.<name>.lock`` in its parent (created with its parents); ``out`` itself is
    neither created nor changed.

    Parameters
    ----------
    out : Path or str
        The destination folder.
    command : str
        What is writing (for the message a second writer gets), e.g. ``"run"``.

    Yields
    ------
    Path
        ``out``.

    Raises
    ------
    OutputFolderError
        If another process holds it, or its parent cannot be written (one line, naming it).
    """
    out = Path(out)
    target = _target(out)
    _check_destination(out, target)
    try:
        make_folder(target.parent)
    except OutputFolderError as exc:
        reason = ("is under a file" if "file" in str(exc) else "cannot be created: "
                  "permission denied (choose another --out)")
        raise OutputFolderError(f"output folder {out} {reason}") from None
    lock = swap.lock_file(target)
    try:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
    except PermissionError:
        raise OutputFolderError(f"cannot write into the output folder {out}: permission "
                                "denied (choose another --out)") from None
    except OSError as exc:
        raise OutputFolderError(f"cannot write into the output folder {out}: "
                                f"{exc.strerror}") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise OutputFolderError(
                f"output folder {out} is in use by {_holder(lock)}; wait for it to finish "
                "or choose another --out") from None
        stamp = time.strftime("%Y-%m-%d %H:%M:%S")
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"auv-cosim {command} (pid {os.getpid()}, since {stamp})\n"
                  .encode(), 0)
        yield out
    finally:
        os.close(fd)           # releases the lock; the file stays (removing it would race)


def _describe(identity: Mapping[str, str]) -> str:
    return ", ".join(f"{k} {v}" for k, v in identity.items())


def _record(folder: Path) -> dict[str, Any] | None:
    try:
        previous = json.loads((folder / RUN_MARKER).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return previous if isinstance(previous, dict) else None


def earlier_outputs(folder: Path) -> set[str]:
    """The names in ``folder`` an earlier command wrote: those its record lists; in a
    folder of an earlier version (a record without names, or its lock file) the names
    such versions wrote (``summary.json``, recordings, figures, FMUs, per-plant and
    per-point subfolders, a campaign's tables); none in a folder auv-cosim did not write.
    What other commands derived from the run (:data:`DERIVED`: ``plot``'s ``figures``) goes
    with it."""
    if not folder.is_dir():
        return set()
    names = {p.name for p in folder.iterdir()}
    record = _record(folder)
    if record is not None and isinstance(record.get("outputs"), list):
        derived = {n for n in names if n in DERIVED or (n.startswith(".") and n.endswith(".lock")
                                                        and n[1:-5] in DERIVED)}
        return names & ({str(n) for n in record["outputs"]} | {RUN_MARKER, LOCK_NAME} | derived)
    if record is None and LOCK_NAME not in names:
        return set()
    return {n for n in names if n in _LEGACY_NAMES or Path(n).suffix in _LEGACY_SUFFIXES
            or n in (RUN_MARKER, LOCK_NAME) or (folder / n / "summary.json").exists()}


def check_claim(out: Path, identity: Mapping[str, str], force: bool | None = False) -> None:
    """Refuse to replace another kind of run's result in ``out`` (its record names it)
    unless ``force``; ``force=None``: the command has no ``--force``.

    Raises
    ------
    OutputFolderError
        Naming both runs (one line).
    """
    previous = _record(_target(out))
    if previous is None:
        return       # nothing recorded (an earlier version's folder): replaced
    previous.pop("outputs", None)
    if previous != dict(identity) and not force:
        hint = "" if force is None else ", or add --force to replace it"
        raise OutputFolderError(
            f"output folder {out} holds a run of {_describe(previous)}, not of "
            f"{_describe(identity)}; it is kept as it was: choose another --out{hint}")


@dataclass
class Staging:
    """A command's private folder (:func:`staged_output`): write into :attr:`path`, then
    :meth:`finish`.

    Attributes
    ----------
    out : Path
        The destination as the user gave it (what messages name).
    path : Path
        The staging folder: where the command writes.
    earlier : bool
        The destination held an earlier result.
    final : Path or None
        Where the result went (``out`` or ``<out>.interrupted``), once finished.
    note : str
        The line to add to the command's last message (e.g. the earlier result kept).
    """

    out: Path
    path: Path
    command: str
    identity: dict[str, str]
    earlier: bool
    carried: set[str]
    replaceable: Callable[[Path], bool] | None = None
    final: Path | None = None
    note: str = ""
    _target: Path = field(default=Path(), repr=False)

    def destination(self, complete: bool = True) -> Path:
        """Where :meth:`finish` puts the result (as the user names it): ``out``, or, for a
        partial result beside an earlier one, ``<out>.interrupted``."""
        if complete or not self.earlier or (self.replaceable is not None
                                            and self.replaceable(self._target)):
            return self.out
        return self.out.with_name(self.out.name + INTERRUPTED)

    def shown(self, path: Path | str, complete: bool = True) -> Path:
        """``path`` under the staging folder as it is named after :meth:`finish`."""
        return Path(self.relocate(str(path), complete))

    def relocate(self, value: Any, complete: bool = True) -> Any:
        """``value`` (strings, lists, dicts) with the staging folder's path replaced by the
        destination's (:meth:`destination`)."""
        old, new = str(self.path), str(self.final or self.destination(complete))
        if isinstance(value, str):
            return value.replace(old, new)
        if isinstance(value, list):
            return [self.relocate(v, complete) for v in value]
        if isinstance(value, dict):
            return {k: self.relocate(v, complete) for k, v in value.items()}
        return value

    def finish(self, complete: bool = True) -> Path:
        """Swap the staging folder in (module docstring): ``complete``, or a partial result
        (interrupted); returns where it went (as the user names it) and sets :attr:`note`."""
        from .atomic import write_text_atomically
        shown = self.destination(complete)
        old, new = json.dumps(str(self.path))[1:-1], json.dumps(str(shown))[1:-1]
        for p in self.path.rglob("*.json"):          # summaries naming their own files
            if p.name in ("summary.json", "campaign.json") and not p.is_symlink():
                text = p.read_text(encoding="utf-8")
                if old in text:
                    write_text_atomically(p, text.replace(old, new))
        names = sorted(p.name for p in self.path.iterdir()
                       if p.name not in self.carried | {RUN_MARKER})
        write_text_atomically(self.path / RUN_MARKER,
                              json.dumps({**self.identity, "outputs": names}, indent=1) + "\n")
        target = _target(shown)
        swap.swap_in(self.path, target)
        if target == self._target:
            swap.remove_tree(self._target.with_name(self._target.name + INTERRUPTED))
        else:
            self.note = (f"the earlier result in {self.out} is kept as it was; this run's "
                         f"partial result is in {shown}")
        self.final = shown
        return shown


@contextmanager
def staged_output(out: Path | str, command: str, *, identity: Mapping[str, str] | None = None,
                  force: bool | None = False, kind: str = "",
                  replaceable: Callable[[Path], bool] | None = None,
                  resume: tuple[str, ...] = ()) -> Iterator[Staging]:
    """Hold ``out`` (:func:`output_folder`) and give the command a staging folder beside it
    (module docstring); a block left without :meth:`Staging.finish` finishes complete, a
    block left by an exception deletes the staging folder and, when ``out`` held an
    earlier result, adds a note to the exception saying it was kept.

    Parameters
    ----------
    out : Path or str
        The destination folder.
    command : str
        The command (messages, the lock, the record).
    identity : Mapping[str, str], optional
        What kind of run this is (:func:`check_claim`; default ``{"command": command}``).
    force : bool or None
        Replace another kind of run's result; None: the command has no ``--force``.
    kind : str
        The staging folder's kind (:data:`orchestrator.swap.CAMPAIGN` keeps it for a
        resume after a kill).
    replaceable : callable, optional
        Says whether an earlier result is unfinished (a partial result then replaces it).
    resume : tuple[str, ...]
        Subfolders whose files are gathered into the new staging folder from the
        destination, ``<out>.interrupted`` and the staging folders of killed commands of
        the same ``kind`` (a campaign's ``parts``).

    Yields
    ------
    Staging
    """
    out = Path(out)
    identity = dict(identity or {"command": command})
    with output_folder(out, command):
        target = _target(out)
        swap.recover(target)
        check_claim(out, identity, force)
        stale = swap.stale_of(target)
        staging = swap.new_staging(target, kind)
        try:
            earlier = earlier_outputs(target)
            carried = set()
            if target.is_dir():
                for p in target.iterdir():
                    if p.name not in earlier:
                        swap.link_tree(p, staging / p.name)
                        carried.add(p.name)
            sources = [target, target.with_name(target.name + INTERRUPTED)]
            for name in resume:
                (staging / name).mkdir(exist_ok=True)
                for src in sources + [s for s in stale if kind and f"-{kind}-" in s.name]:
                    if (src / name).is_dir():
                        for f in (src / name).iterdir():
                            if f.is_file() and not f.name.startswith(".") \
                                    and not (staging / name / f.name).exists():
                                swap.link_tree(f, staging / name / f.name)
        except BaseException:
            swap.remove_tree(staging)
            raise
        for s in stale:
            swap.remove_tree(s)
        swap.prune(target.parent, keep=[staging])
        st = Staging(out, staging, command, identity, bool(earlier), carried, replaceable,
                     _target=target)
        try:
            yield st
        except BaseException as exc:
            if st.final is None:
                swap.remove_tree(staging)
                if st.earlier and hasattr(exc, "add_note"):
                    exc.add_note(f"auv-cosim {command}: kept the earlier result in {out} "
                                 f"(this {command} "
                                 f"{'was stopped' if _stopped(exc) else 'failed'})")
            raise
        if st.final is None:
            try:
                st.finish()
            except BaseException:
                swap.remove_tree(staging)
                raise


def _stopped(exc: BaseException) -> bool:
    from .interrupt import Interrupted
    return isinstance(exc, (KeyboardInterrupt, Interrupted))
