"""What a resolved scenario runs, as canonical data: the key of a run (campaign run keys)
and of what is computed from the scenario alone (the predictions a process keeps)."""
from __future__ import annotations

import dataclasses
import hashlib
import json
from typing import Any

import numpy as np

from .loader import Scenario

__all__ = ["resolved_scenario", "scenario_digest"]


def _plain(value: Any) -> Any:
    """JSON-ready data of a resolved scenario's value (arrays as lists, dataclasses and
    mappings as dicts, a vehicle model as its name and parameters)."""
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, dict) or hasattr(value, "items"):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise TypeError(f"cannot key a scenario value of type {type(value).__name__}")


def _handed_on(sc: Scenario, name: str) -> Any:
    """A scenario field as it is written whole: the fleet as its resolved spec, the
    network and sensors as their tables."""
    value = getattr(sc, name)
    if value is None:
        return None
    if name == "fleet":
        return value.spec
    if name in ("network", "sensors"):
        return value.to_mapping()
    return value


def resolved_scenario(sc: Scenario, *, without: tuple[str, ...] = ()) -> dict[str, Any]:
    """Everything a resolved scenario runs, but its seed, its names and the fields in
    ``without``, as JSON-ready data (the run key's scenario part)."""
    skip = {"seed", "name", "description", "source", "raw", "system", *without}
    if sc.design is None:           # no [design]: the key of every scenario before it
        skip.add("design")
    out = {f.name: _plain(_handed_on(sc, f.name)) for f in dataclasses.fields(sc)
           if f.name not in skip}
    if sc.fleet is None:            # a fleet's system is made from its (resolved) fleet spec
        out["system"] = _plain(sc.system.to_mapping())
    return out


def scenario_digest(sc: Scenario, *, without: tuple[str, ...] = ()) -> str:
    """SHA-256 (hex) of :func:`resolved_scenario`'s canonical JSON."""
    text = json.dumps(resolved_scenario(sc, without=without), sort_keys=True,
                      separators=(",", ":"), allow_nan=True)
    return hashlib.sha256(text.encode()).hexdigest()
