"""FMU files unzipped once per content and reused by every later run.

A run used to unzip each FMU into a temporary folder and delete it at the end: for the
paper run's three pythonfmu FMUs (60 files each) that was about 0.2 s of a 1 s command,
and the same again for every run of a test suite, a campaign worker or a compare. Here
each FMU file is unzipped once into ``<FMU cache>/unpacked/<digest>/`` (the digest is the
SHA-256 of the file's bytes, so a changed FMU never meets a stale folder), into a private
folder first and renamed into place, so concurrent processes each see a whole folder or
none. A folder is touched when used; folders unused for :data:`UNPACKED_MAX_AGE_S` are
removed when a new one is made (an unpacked FMU is about 1 MB, three times its zip).

Nothing writes into an unpacked folder: the FMUs read their resources and the master
loads their libraries, which stay valid even if a folder were deleted under a running
process (Linux keeps a mapped file until it is unmapped).
"""
from __future__ import annotations

import hashlib
import os
import re
import shutil
import tempfile
import time
import uuid
from pathlib import Path

__all__ = ["UNPACKED_MAX_AGE_S", "unpacked_fmu"]

#: an unpacked FMU folder unused this long (s) is removed when a new one is made
UNPACKED_MAX_AGE_S = 2 * 86400.0


def _digest(path: Path) -> str:
    """SHA-256 of a file's bytes (hex, first 32 digits)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()[:32]


def _prune(root: Path, keep: Path, max_age_s: float = UNPACKED_MAX_AGE_S) -> None:
    """Remove unpacked folders (and abandoned private ones) unused for ``max_age_s``.

    Each is first renamed to a private name (one atomic step), then deleted: no process
    finds a half-deleted folder under its final name, and a deletion cut short leaves a
    private folder that the next pruning removes."""
    now = time.time()
    for d in root.iterdir():
        try:
            if d == keep or now - d.stat().st_mtime <= max_age_s:
                continue
            if not d.name.startswith("."):
                trash = root / f".trash-{uuid.uuid4().hex}"
                os.rename(d, trash)
                d = trash
            shutil.rmtree(d, ignore_errors=True)
        except OSError:
            pass


def unpacked_fmu(fmu: Path | str, root: Path) -> Path:
    """The folder holding the FMU file ``fmu`` unzipped, made under ``root`` if missing.

    Parameters
    ----------
    fmu : Path or str
        The .fmu file.
    root : Path
        The folder of unpacked FMUs (created if missing); it must be a path pythonfmu can
        read (:func:`orchestrator.cosim.instance.pythonfmu_can_load_from`).

    Returns
    -------
    Path
        ``root/<model>-<digest>``: the FMU's files (modelDescription.xml, binaries/,
        resources/ ...).

    Raises
    ------
    OSError
        If the folder cannot be made (the caller unzips into a temporary folder then).
    """
    from fmpy import extract

    fmu = Path(fmu)
    stem = re.sub(r"[^A-Za-z0-9_-]", "_", fmu.stem)  # a path pythonfmu 0.7 can read
    folder = root / f"{stem}-{_digest(fmu)}"
    if (folder / "modelDescription.xml").exists():
        os.utime(folder)                          # used now: kept by the pruning
        return folder
    root.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=".unzip-", dir=root))
    try:
        extract(str(fmu), unzipdir=str(work))
        try:
            os.rename(work, folder)               # whole, or another process was first
        except OSError:
            if not (folder / "modelDescription.xml").exists():
                raise
    finally:
        shutil.rmtree(work, ignore_errors=True)
    _prune(root, keep=folder)
    return folder
