"""The distributed fleet's cost predictions on disk, keyed by what they depend on.

:func:`orchestrator.analysis.distributed_verdict.predict_cost` solves, for formation-100, a
dense eigenproblem and a block Stein equation of about 3400 states (tens of seconds): the
largest part of a native fleet command outside its loop. They depend only on the loop's
matrices (Phi, Gam, W, Gx, Geta, Ce, Qc, Rc, which coordinates are deterministic, h, the
graph's L + G, the cohesion gain, the estimator), the window, the initial state and the
code that computes them; so a second run of the same fleet (another seed, another output
folder, ``compare`` after ``run``) reads them back from the prediction cache of
:mod:`orchestrator.analysis.acoustic.cache` (its folder, its switch
``AUV_COSIM_PREDICTION_CACHE=0``). Values are written with every digit: a hit is
bit-identical.
"""
from __future__ import annotations

import dataclasses
import hashlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from plant_model.memo import feed_hash

__all__ = ["cached_prediction", "distributed_digest"]

#: the modules whose code the cached values come from
_SOURCES = ("distributed_verdict.py", "distributed.py", "block_stein.py", "prediction.py",
            "mean_motion.py", "distributed_cache.py")


def distributed_digest(loop: Any) -> str:
    """SHA-256 of what the loop's cost predictions depend on (module docstring), computed
    once per loop object.

    Parameters
    ----------
    loop : DistributedLoop
        The stacked loop.

    Returns
    -------
    str
        Hex digest.
    """
    if "_digest" in loop.__dict__:
        return loop.__dict__["_digest"]
    from .acoustic.cache import code_digest
    h = hashlib.sha256()
    feed_hash(h, code_digest(Path(__file__).parent, _SOURCES))
    feed_hash(h, [loop.Phi, loop.Gam, loop.W, loop.Gx, loop.Geta, loop.Ce, loop.Qc, loop.Rc,
                  np.asarray(loop.deterministic), float(loop.h), np.asarray(loop.LG),
                  float(loop.cohesion), str(loop.estimator)])
    out = h.hexdigest()
    object.__setattr__(loop, "_digest", out)       # a frozen dataclass, with a __dict__
    return out


def cached_prediction(loop: Any, window: tuple[int, int] | None, X0: np.ndarray | None,
                      transient: bool, compute: Callable[[], Any], result: type) -> Any:
    """``compute()`` (a ``result``, a dataclass), or its value stored for the same loop,
    window, initial state and ``transient``.

    Parameters
    ----------
    loop : DistributedLoop
        The loop (:func:`distributed_digest`).
    window : tuple[int, int] or None
        Samples k0 <= k < K, or None.
    X0 : np.ndarray or None
        The initial state of the mean motion, or None.
    transient : bool
        The window average from a known start.
    compute : callable
        Computes the prediction.
    result : type
        Its dataclass (``DistributedPrediction``): a stored value is ``result(**fields)``.

    Returns
    -------
    result
    """
    from .acoustic.cache import cached_digest
    args = [list(window) if window is not None else None,
            None if X0 is None else np.asarray(X0, dtype=float), bool(transient)]
    return cached_digest("distributed-cost", distributed_digest(loop), args, compute,
                         encode=dataclasses.asdict,
                         decode=lambda d: result(**d))
