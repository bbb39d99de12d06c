"""The file-system steps of a staged output folder (:func:`orchestrator.outputs.staged_output`
is the one user of this module): the hidden names beside a destination, the swap of a
complete staging folder into place, the recovery of a swap a crash cut, and the pruning
of what killed processes left.

Every hidden name of a destination ``<parent>/<name>`` is made from one tag
(:func:`tag`, the name itself, shortened with a hash when long) and lives in ``<parent>``
(the same file system, so every step is a ``rename``):

- ``.<tag>.lock``: the lock of the destination (never removed: removing it would race);
- ``.<tag>.staging-<pid>-<token>`` (``.<tag>.staging-campaign-<pid>-<token>`` for a
  campaign): the folder a command writes into;
- ``.<tag>.old-<token>``: the earlier folder between the swap and its deletion.

The swap (:func:`swap_in`) is one ``renameat2(RENAME_EXCHANGE)`` where the kernel and the
file system have it (no moment without a folder under the final name); elsewhere two
renames, the earlier folder first renamed to ``.<tag>.old-<token>``. A crash between the
two leaves no folder under the final name and the earlier one under its old- name:
:func:`recover` renames it back, so the destination then holds the earlier result, whole.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import errno
import hashlib
import os
import secrets
import shutil
from collections.abc import Iterable
from pathlib import Path

__all__ = ["CAMPAIGN", "KEPT_KINDS", "RUN", "exchange", "link_tree", "lock_file", "new_staging",
           "old_name",
           "prune", "recover", "remove_tree", "stale_of", "swap_in", "tag"]

#: the kind tag of a campaign's staging folders (kept for its next run: it resumes them)
CAMPAIGN = "campaign"
#: the kind tag of a checkpointed run's staging folders (kept: ``run --resume`` reads them)
RUN = "run"
#: the kinds of staging folder :func:`prune` leaves to the next command into their own
#: destination, and the file that makes one worth keeping (None: always kept)
KEPT_KINDS = {CAMPAIGN: None, RUN: "checkpoint/run.pkl"}

_RENAME_EXCHANGE = 2
_AT_FDCWD = -100
_libc = None


def tag(name: str) -> str:
    """The part of a destination's hidden names that names it: ``name``, or when long its
    first 100 characters and a hash (a file name has at most 255 bytes)."""
    if len(name.encode()) <= 180:
        return name
    return f"{name[:100]}~{hashlib.sha256(name.encode()).hexdigest()[:12]}"


def lock_file(target: Path) -> Path:
    """``<parent>/.<tag>.lock``: the lock of the destination ``target``."""
    return target.parent / f".{tag(target.name)}.lock"


def new_staging(target: Path, kind: str = "") -> Path:
    """Create and return a new, empty staging folder of ``target`` (mode 0755 less umask)."""
    prefix = f"{kind}-" if kind else ""
    path = target.parent / (f".{tag(target.name)}.staging-{prefix}{os.getpid()}-"
                            f"{secrets.token_hex(4)}")
    path.mkdir()
    return path


def old_name(target: Path) -> Path:
    """A fresh ``.<tag>.old-<token>`` beside ``target``."""
    return target.parent / f".{tag(target.name)}.old-{secrets.token_hex(4)}"


def stale_of(target: Path, *, kinds: Iterable[str] | None = None) -> list[Path]:
    """The staging folders of ``target`` (oldest first; only of ``kinds`` if given, ``""``
    for the plain ones). Stale only when the caller holds the destination's lock."""
    prefix = f".{tag(target.name)}.staging-"
    found = [p for p in target.parent.glob(f"{glob_escape(prefix)}*") if p.is_dir()
             and not p.is_symlink()]
    if kinds is not None:
        wanted = set(kinds)
        found = [p for p in found if _kind(p.name[len(prefix):]) in wanted]
    return sorted(found, key=lambda p: p.stat().st_mtime)


def _kind(rest: str) -> str:
    head = rest.split("-", 1)[0]
    return "" if head.isdigit() else head


def glob_escape(text: str) -> str:
    """``text`` with the glob metacharacters escaped."""
    return "".join(f"[{c}]" if c in "*?[" else c for c in text)


def exchange(a: Path, b: Path) -> bool:
    """Swap the folders ``a`` and ``b`` in one step (``renameat2`` with
    ``RENAME_EXCHANGE``); False where the kernel, the C library or the file system cannot."""
    global _libc
    try:
        if _libc is None:
            _libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        fn = _libc.renameat2
    except (OSError, AttributeError):
        return False
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    if fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP, errno.EOPNOTSUPP):
        return False
    raise OSError(err, os.strerror(err), str(b))


def remove_tree(path: Path) -> None:
    """Delete a folder that no one uses: renamed to a hidden old- name first (a cut
    deletion never leaves a half-deleted folder under a name a user reads), then removed;
    a symlink or file is unlinked."""
    if not os.path.lexists(path):
        return
    if path.is_symlink() or not path.is_dir():
        path.unlink()
        return
    if ".old-" not in path.name and ".staging-" not in path.name:
        aside = old_name(path)
        os.rename(path, aside)
        path = aside
    shutil.rmtree(path, ignore_errors=True)


def swap_in(staging: Path, target: Path) -> None:
    """Put the complete folder ``staging`` under ``target``'s name; the earlier folder
    there (if any) is deleted (module docstring: the order of the steps)."""
    if not target.exists():
        os.rename(staging, target)
        return
    if exchange(staging, target):          # staging now holds the earlier folder
        remove_tree(staging)
        return
    aside = old_name(target)
    os.rename(target, aside)
    os.rename(staging, target)
    remove_tree(aside)


def recover(target: Path) -> None:
    """Undo a swap a crash cut (caller holds the lock): with no folder under ``target``'s
    name, the newest ``.<tag>.old-*`` goes back; every other old- folder is deleted."""
    olds = sorted(target.parent.glob(f"{glob_escape(f'.{tag(target.name)}.old-')}*"),
                  key=lambda p: p.stat().st_mtime)
    if olds and not os.path.lexists(target):
        os.rename(olds.pop(), target)
    for p in olds:
        shutil.rmtree(p, ignore_errors=True)


def _kept(folder: Path, kind: str) -> bool:
    """Whether a staging folder of ``kind`` is left to the next command into its own
    destination (:data:`KEPT_KINDS`: a run's only when it holds a checkpoint)."""
    if kind not in KEPT_KINDS:
        return False
    marker = KEPT_KINDS[kind]
    return marker is None or (folder / marker).is_file()


def prune(parent: Path, keep: Iterable[Path] = ()) -> None:
    """Delete the staging and old- folders in ``parent`` whose owner is gone: a folder's
    destination lock (``.<tag>.lock``) can be taken, so no process writes it. A campaign's
    or a checkpointed run's staging folder (:data:`KEPT_KINDS`) is left to the next command
    into its own destination (a campaign, ``run --resume``, resume it; any other command
    replaces it)."""
    import fcntl
    keep = {Path(p).name for p in keep}
    tags: dict[str, list[Path]] = {}
    for p in parent.glob(".*"):
        for sep in (".staging-", ".old-"):
            head, found, rest = p.name[1:].rpartition(sep)
            if found and head and p.name not in keep and p.is_dir() and not p.is_symlink():
                if not (sep == ".staging-" and _kept(p, _kind(rest))):
                    tags.setdefault(head, []).append(p)
                break
    for name, folders in tags.items():
        try:
            fd = os.open(parent / f".{name}.lock", os.O_RDWR)
        except OSError:
            continue                       # no lock file: not ours, or not readable
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            continue                       # its writer is alive
        try:
            target = parent / name
            if tag(name) == name:
                recover(target)            # the destination's own cut swap, first
            for p in folders:
                if p.exists():
                    shutil.rmtree(p, ignore_errors=True)
        finally:
            os.close(fd)


def link_tree(src: Path, dst: Path) -> None:
    """Copy ``src`` (a file or a folder) to ``dst`` with hard links where the file system
    allows (the bytes are not copied; ``src`` is left as it was), else by copying."""
    def _link(s: str, d: str) -> None:
        try:
            os.link(s, d)
        except OSError:
            shutil.copy2(s, d)
    if src.is_symlink():
        os.symlink(os.readlink(src), dst)
    elif src.is_dir():
        shutil.copytree(src, dst, symlinks=True, copy_function=_link)
    else:
        _link(str(src), str(dst))
