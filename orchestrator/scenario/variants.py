"""Variants of a scenario mapping: a value set at a dotted key (``leader.speed``), or a whole
section replaced (``leader``). Campaign points and envelope points are made this way."""
from __future__ import annotations

import copy
from collections.abc import Mapping
from typing import Any

from .errors import ScenarioError

__all__ = ["set_key", "with_keys"]


def set_key(data: dict[str, Any], key: str, value: Any) -> None:
    """``data[a][b]... = value`` for the key ``a.b...`` (creating missing tables); a key
    without a dot replaces that whole section.

    Raises
    ------
    ScenarioError
        If a table on the way is a value, not a table.
    """
    *tables, last = key.split(".")
    node = data
    for t in tables:
        node = node.setdefault(t, {})
        if not isinstance(node, dict):
            raise ScenarioError(f"{key}: {t} is not a table in the base scenario")
    node[last] = copy.deepcopy(value)


def with_keys(data: Mapping[str, Any], values: Mapping[str, Any]) -> dict[str, Any]:
    """A deep copy of ``data`` with every (key, value) of ``values`` set (:func:`set_key`)."""
    out = copy.deepcopy(dict(data))
    for key, value in values.items():
        set_key(out, key, value)
    return out
