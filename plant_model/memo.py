"""A per-process cache of design results, keyed by a hash of the numbers they come from.

The FMUs solve their design in exitInitializationMode: the controller its Riccati and
Sylvester equations, the estimator its Kalman filters, plant and estimator the sampled
model (matrix exponential, Van Loan). A campaign runs many seeds of one design point, each
in new FMU instances; pythonfmu slaves run inside the host's interpreter and import the
same modules, so a module-level cache here persists across FMU instances (and across the
runs of one worker process). The same design is then solved once per process, not once
per seed: at N = 50 vehicles that is most of a run's set-up.

The key is a SHA-256 of every input array (dtype, shape, bytes) and scalar: only an
identical problem hits, and a hit returns exactly what solving again would return (the
solvers are deterministic), so a seed gives the same traces with or without the cache.
Cached arrays are made read-only: a caller that tried to change one in place would get an
error, not a silently changed design. Exceptions are not cached. ``AUV_COSIM_DESIGN_CACHE=0``
turns the cache off (read when a cached function is called), e.g. to measure what it saves.
"""
from __future__ import annotations

import dataclasses
import hashlib
import os
import threading
from collections import OrderedDict
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np

__all__ = ["content_key", "feed_hash", "DesignCache", "cache_enabled", "cache_stats",
           "clear_caches"]

T_ = TypeVar("T_")

_CACHES: dict[str, DesignCache] = {}


def feed_hash(h: Any, value: Any) -> None:
    """Feed a canonical encoding of ``value`` to the hash ``h`` (hashlib): arrays by dtype,
    shape and bytes; scipy sparse matrices by shape and canonical CSR arrays; scalars by
    type and repr; lists, tuples, dicts (sorted keys) and frozensets (sorted) recursively.

    Raises
    ------
    TypeError
        For any other type (a key must not depend on an object's identity).
    """
    if hasattr(value, "tocsr") and not isinstance(value, np.ndarray):    # scipy sparse
        M = value.tocsr()
        M.sort_indices()
        h.update(f"s{M.shape}".encode())
        for a in (M.indptr, M.indices, M.data):
            h.update(np.ascontiguousarray(a).tobytes())
    elif isinstance(value, np.ndarray):
        arr = np.ascontiguousarray(value)
        h.update(f"a{arr.dtype.str}{arr.shape}".encode())
        h.update(arr.tobytes())
    elif isinstance(value, (bool, int, float, str, type(None), np.generic)):
        h.update(f"{type(value).__name__}:{value!r};".encode())
    elif isinstance(value, (list, tuple)):
        h.update(f"l{len(value)}[".encode())
        for v in value:
            feed_hash(h, v)
        h.update(b"]")
    elif isinstance(value, dict):
        h.update(f"d{len(value)}{{".encode())
        for k in sorted(value, key=str):
            feed_hash(h, str(k))
            feed_hash(h, value[k])
        h.update(b"}")
    elif isinstance(value, frozenset):
        feed_hash(h, sorted(str(v) for v in value))
    else:
        raise TypeError(f"cannot key a design cache on a {type(value).__name__}")


def content_key(*parts: Any) -> str:
    """SHA-256 (hex) of the values ``parts``: arrays by dtype, shape and bytes; scalars by
    type and repr; lists, tuples and dicts (sorted keys) recursively.

    Parameters
    ----------
    *parts : Any
        The values a result depends on.

    Returns
    -------
    str
        64 hex digits.
    """
    h = hashlib.sha256()
    feed_hash(h, parts)
    return h.hexdigest()


def cache_enabled() -> bool:
    """Whether the design caches are on (``AUV_COSIM_DESIGN_CACHE`` is not ``0``)."""
    return os.environ.get("AUV_COSIM_DESIGN_CACHE", "1").strip() not in ("0", "false", "no")


def _freeze(value: Any) -> Any:
    """Make the arrays of a result read-only (arrays, dataclass fields, tuples)."""
    if isinstance(value, np.ndarray):
        value.flags.writeable = False
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        for f in dataclasses.fields(value):
            _freeze(getattr(value, f.name))
    elif isinstance(value, (tuple, list)):
        for v in value:
            _freeze(v)
    return value


class DesignCache:
    """Least-recently-used results of one function, by :func:`content_key`.

    Parameters
    ----------
    name : str
        What is cached (for :func:`cache_stats`).
    maxsize : int
        Number of results kept.
    """

    def __init__(self, name: str, maxsize: int = 8):
        self.name = name
        self.maxsize = int(maxsize)
        self.hits = 0
        self.misses = 0
        self._data: OrderedDict[str, Any] = OrderedDict()
        self._lock = threading.Lock()
        _CACHES[name] = self

    def get(self, key_parts: tuple, compute: Callable[[], T_]) -> T_:
        """The cached result for ``key_parts``, or ``compute()`` (then cached, read-only).

        Parameters
        ----------
        key_parts : tuple
            Everything the result depends on (:func:`content_key`).
        compute : callable
            Computes the result; its exceptions propagate and are not cached.

        Returns
        -------
        Any
            The result.
        """
        if not cache_enabled():
            return compute()
        key = content_key(*key_parts)
        with self._lock:
            if key in self._data:
                self.hits += 1
                self._data.move_to_end(key)
                return self._data[key]
        result = _freeze(compute())
        with self._lock:
            self.misses += 1
            self._data[key] = result
            while len(self._data) > self.maxsize:
                self._data.popitem(last=False)
        return result

    def clear(self) -> None:
        """Forget every result and reset the counters."""
        with self._lock:
            self._data.clear()
            self.hits = self.misses = 0


def cache_stats() -> dict[str, dict[str, int]]:
    """Hits, misses and size of every design cache of this process.

    Returns
    -------
    dict[str, dict[str, int]]
        Cache name -> ``hits``, ``misses``, ``size``.
    """
    return {n: {"hits": c.hits, "misses": c.misses, "size": len(c._data)}
            for n, c in _CACHES.items()}


def clear_caches() -> None:
    """Empty every design cache of this process."""
    for c in _CACHES.values():
        c.clear()
