"""Output folders seen from the tests: where a running command writes (its staging folder
beside the destination), a folder's every file hashed, and the helpers of the tests
that start commands as real processes."""
from __future__ import annotations

import hashlib
import subprocess
import sys
import time
from pathlib import Path

from orchestrator.swap import glob_escape, tag


def staging_folders(out: Path) -> list[Path]:
    """The staging folders of the destination ``out`` (a running or killed command's)."""
    pattern = f"{glob_escape(f'.{tag(out.name)}.staging-')}*"
    return sorted(p for p in out.parent.glob(pattern) if p.is_dir())


def working(out: Path) -> Path:
    """Where a command into ``out`` is writing now: its staging folder (the newest), or
    ``out`` itself when none exists (a path that may not exist)."""
    found = staging_folders(out)
    return max(found, key=lambda p: p.stat().st_mtime) if found else out


def tree_hashes(folder: Path) -> dict[str, str]:
    """Every file, folder and link under ``folder`` (relative path -> SHA-256 of the bytes,
    ``dir`` or ``link:<target>``): equal dicts mean byte-identical trees."""
    out = {}
    for p in sorted(folder.rglob("*")):
        rel = str(p.relative_to(folder))
        if p.is_symlink():
            out[rel] = f"link:{p.readlink()}"
        elif p.is_dir():
            out[rel] = "dir"
        else:
            out[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def cli(*args: str | Path, **kw) -> subprocess.Popen:
    """``python -m orchestrator *args`` as a real process, stdout and stderr piped."""
    return subprocess.Popen([sys.executable, "-m", "orchestrator", *map(str, args)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)


def wait_until(condition, proc: subprocess.Popen, timeout: float = 180.0) -> None:
    """Poll ``condition()`` until true; fails if ``proc`` ends first or on timeout."""
    deadline = time.monotonic() + timeout
    while not condition():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.02)
