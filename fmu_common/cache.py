"""Where the project keeps what it builds and derives (built FMUs, compiled native
libraries, unzipped FMUs, identified vehicle models): one folder, chosen here."""
from __future__ import annotations

import os
from pathlib import Path

__all__ = ["fmu_cache_dir"]


def fmu_cache_dir() -> Path:
    """Where built FMUs are kept.

    ``$AUV_COSIM_CACHE``, else ``$XDG_CACHE_HOME/auv-cosim/fmus``
    (``~/.cache/auv-cosim/fmus``). Delete it at will; entries unused for 30 days are
    removed when a new one is written. It also holds the compiled native libraries
    (``native/``) and the FMUs unzipped for runs (``unpacked/``,
    :mod:`orchestrator.cosim.unpacked`).

    Returns
    -------
    Path
        The cache folder (not created here).
    """
    env = os.environ.get("AUV_COSIM_CACHE")
    if env:
        return Path(env)
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "auv-cosim" / "fmus"
