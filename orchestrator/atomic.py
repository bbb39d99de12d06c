"""Files appear whole or not at all: written under a temporary name in the destination's
folder and renamed into place (``os.replace`` is atomic on one file system). A reader, a
concurrent writer or an interruption never sees a half-written file under its final name.
"""
from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["temporary_sibling", "write_bytes_atomically", "write_text_atomically",
           "copy_atomically"]


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextmanager
def temporary_sibling(path: Path | str) -> Iterator[Path]:
    """A fresh temporary path next to ``path``; on a normal exit the file written there
    replaces ``path``, on an exception it is removed and ``path`` is left as it was.

    Parameters
    ----------
    path : Path or str
        The final name.

    Yields
    ------
    Path
        Where to write (``.<name>.<random>.part`` in the same folder).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    os.fchmod(fd, 0o666 & ~_umask())         # mkstemp makes 0600; a plain file is 0666 - umask
    os.close(fd)
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_bytes_atomically(path: Path | str, data: bytes) -> None:
    """Write ``data`` to ``path`` through :func:`temporary_sibling`."""
    with temporary_sibling(path) as tmp:
        tmp.write_bytes(data)


def write_text_atomically(path: Path | str, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` through :func:`temporary_sibling`."""
    write_bytes_atomically(path, text.encode("utf-8"))


def copy_atomically(src: Path | str, dst: Path | str) -> None:
    """Copy ``src`` to ``dst`` through :func:`temporary_sibling`."""
    with temporary_sibling(dst) as tmp:
        shutil.copyfile(src, tmp)
