"""An on-disk cache of the networked loop's predictions, keyed by what they depend on.

The second-moment radius, the critical loss and the window's expected cost are functions
of the loop's transition matrices over its message cycle, the links' loss probabilities,
the cost and noise weights, and (the window) the start and the window: nothing else. A
second run of the same scenario (more seeds, another output folder, ``compare`` after
``run``, another T for the radius and the critical loss) finds them here instead of
computing them again; the critical-loss search is the one that costs (seconds to a
minute for larger loops), which is why the cache is on disk and not only in the process.

The key (:func:`loop_digest`) is a SHA-256 of:

- every distinct transition pattern's matrices (A0 and each arriving link's D_l, sparse:
  shape, indices and values) and the sequence of patterns over the start-up and one
  message cycle (beyond, the patterns repeat), with the period and start-up step;
- the links' loss probabilities, the cost weight Qz, the noise intensity W, c0, which
  coordinates are deterministic (the leader), h;
- the source of the modules that compute the predictions and the numpy and scipy versions
  (a change of algorithm or of the libraries' rounding is a new key);

plus, per entry, the function's own arguments (the loss, the window, Z0, ...). Entries are
small JSON files ``<kind>-<key>.json`` written by one rename (two processes writing the same
entry both leave a whole one). The folder: ``$AUV_COSIM_PREDICTION_CACHE``, else
``predictions`` next to the FMU cache (``$AUV_COSIM_CACHE/..``, else
``$XDG_CACHE_HOME/auv-cosim``, ``~/.cache/auv-cosim``); ``AUV_COSIM_PREDICTION_CACHE=0``
turns it off. Delete it at will.
"""
from __future__ import annotations

import hashlib
import json
import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from plant_model.memo import feed_hash

from .loop import NetworkedLoop

__all__ = ["cached", "cached_digest", "code_digest", "loop_digest", "prediction_cache_dir"]

T_ = TypeVar("T_")

#: the modules whose code the cached values come from
_SOURCES = ("prediction.py", "blocks.py", "stability.py", "cycle.py", "cache.py", "loop.py")
_OFF = ("0", "off", "false", "no")


def prediction_cache_dir() -> Path | None:
    """The cache folder (module docstring), None when turned off."""
    env = os.environ.get("AUV_COSIM_PREDICTION_CACHE")
    if env is not None and env.strip().lower() in _OFF:
        return None
    if env:
        return Path(env)
    fmus = os.environ.get("AUV_COSIM_CACHE")
    base = (Path(fmus).parent if fmus else
            Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "auv-cosim")
    return base / "predictions"


def code_digest(here: Path = Path(__file__).parent, sources: tuple[str, ...] = _SOURCES
                ) -> str:
    """SHA-256 of the numpy and scipy versions and the code of ``sources`` (file names in
    the folder ``here``): what a cached prediction was computed with."""
    import scipy
    h = hashlib.sha256()
    h.update(f"numpy {np.__version__} scipy {scipy.__version__}".encode())
    for name in sources:
        h.update(name.encode())
        h.update((here / name).read_bytes())
    return h.hexdigest()


def loop_digest(net: NetworkedLoop) -> str:
    """SHA-256 of what the loop's predictions depend on (module docstring); computed once
    per loop object."""
    if "_digest" in net.__dict__:
        return net.__dict__["_digest"]
    h = hashlib.sha256()
    feed_hash(h, code_digest())
    seq, seen = [], {}
    for k in range(net.startup + net.period):
        pat = net.pattern(k)
        if pat not in seen:
            seen[pat] = len(seen)
            A0, D = net.matrices(pat)
            feed_hash(h, [A0, [(str(key), Dl) for key, Dl in D.items()]])
        seq.append(seen[pat])
    feed_hash(h, [np.asarray(seq), net.period, net.startup, net.n, float(net.h), float(net.c0)])
    feed_hash(h, {str(k): float(v) for k, v in net.loss.items()})
    feed_hash(h, [net.Qz, np.asarray(net.form.W, float), net.deterministic])
    net.__dict__["_digest"] = out = h.hexdigest()
    return out


def cached(kind: str, net: NetworkedLoop, args: Any, compute: Callable[[], T_],
           encode: Callable[[T_], Any] = lambda v: v,
           decode: Callable[[Any], T_] = lambda v: v) -> T_:
    """``compute()``, or its value stored under (kind, the loop's digest, args).

    Parameters
    ----------
    kind : str
        What is cached (a file name prefix).
    net : NetworkedLoop
        The loop (:func:`loop_digest`).
    args : Any
        The function's own arguments (arrays, numbers, tuples).
    compute : callable
        Computes the value.
    encode, decode : callable, optional
        To and from JSON (floats are written with every digit: a hit is bit-identical).

    Returns
    -------
    The value.
    """
    return cached_digest(kind, loop_digest(net), args, compute, encode, decode)


def cached_digest(kind: str, digest: str, args: Any, compute: Callable[[], T_],
                  encode: Callable[[T_], Any] = lambda v: v,
                  decode: Callable[[Any], T_] = lambda v: v) -> T_:
    """:func:`cached` for any loop: ``digest`` is the SHA-256 of what ``compute`` depends
    on (its code included).

    Parameters
    ----------
    kind : str
        What is cached (a file name prefix).
    digest : str
        The loop's digest.
    args, compute, encode, decode
        As :func:`cached`.

    Returns
    -------
    The value.
    """
    folder = prediction_cache_dir()
    if folder is None:
        return compute()
    h = hashlib.sha256()
    feed_hash(h, [kind, digest, args])
    path = folder / f"{kind}-{h.hexdigest()[:40]}.json"
    try:
        return decode(json.loads(path.read_text())["value"])
    except (OSError, ValueError, KeyError, TypeError):
        pass
    value = compute()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=".entry-", dir=folder)
        with os.fdopen(fd, "w") as f:
            json.dump({"kind": kind, "value": encode(value)}, f)
        os.replace(tmp, path)
    except OSError:                         # a read-only cache: computed, not kept
        pass
    return value
