"""How deep a scenario may nest, and reading TOML without a RecursionError.

A scenario's deepest legitimate value is a matrix entry: section -> key -> row -> entry, 3
levels of tables and arrays below the document (``[vehicles] A = [[-1.0, 0.0], ...]``); a
fleet's per-vehicle tables (``[[vehicles.models]]`` with a matrix) reach 4, a campaign point
overriding one of those 5. :data:`MAX_DEPTH` = 32 is more than six times that, and far below
the ~400 levels where Python's ``tomllib`` (recursive descent) raises ``RecursionError`` or
where pydantic, ``copy.deepcopy`` and numpy (64 dimensions at most) fail on their own.

The depth counted is the number of tables and arrays enclosing a value, the document not
counted: ``a = 1`` is 0, ``a = [1]`` is 1, ``[s] a = [[1]]`` is 3.
"""
from __future__ import annotations

import tomllib
from collections.abc import Mapping
from typing import Any

from .errors import ScenarioError

__all__ = ["MAX_DEPTH", "nesting", "check_nesting", "loads_scenario_toml"]

#: the most tables and arrays a scenario value may be nested in (see the module docstring)
MAX_DEPTH = 32


def _place(path: tuple[str, ...]) -> str:
    """``[section] key`` for a path of keys, ``key 'a'`` for a top-level key."""
    if not path:
        return "the document"
    if len(path) == 1:
        return f"key {path[0]!r}"
    return f"[{path[0]}] {'.'.join(path[1:2])}"


def nesting(data: Any) -> tuple[int, tuple[str, ...]]:
    """The deepest nesting in ``data`` (tables and arrays enclosing a value, the top mapping
    not counted) and the keys leading to the first deepest value. Iterative: any depth."""
    best: tuple[int, tuple[str, ...]] = (0, ())
    stack: list[tuple[Any, int, tuple[str, ...]]] = [(data, -1, ())]
    while stack:
        value, depth, path = stack.pop()
        if isinstance(value, Mapping):
            items = [(v, depth + 1, path + (str(k),) if len(path) < 2 else path)
                     for k, v in value.items()]
        elif isinstance(value, list | tuple):
            items = [(v, depth + 1, path) for v in value]
        else:
            continue
        if depth + 1 > best[0]:
            best = (depth + 1, path)
        stack.extend(reversed(items))
    return best


def check_nesting(data: Any, where: str) -> None:
    """Refuse ``data`` nested deeper than :data:`MAX_DEPTH`, in one line naming the depth,
    the limit and the section and key.

    Raises
    ------
    ScenarioError
        ``<where>: nested 401 levels deep (at most 32 allowed) at [vehicles] A``.
    """
    depth, path = nesting(data)
    if depth > MAX_DEPTH:
        raise ScenarioError(f"{where}: nested {depth} levels deep (at most {MAX_DEPTH} "
                            f"allowed) at {_place(path)}")


def _text_depth(text: str) -> tuple[int, tuple[str, ...]]:
    """The deepest nesting in TOML ``text`` counted from its brackets (``[``/``{`` outside
    strings and comments, plus the table header's dotted names) and the section and key of
    the first deepest value: a lexical count, used to refuse before ``tomllib`` recurses."""
    depth = best = 0
    header: tuple[str, ...] = ()
    key = ""
    where: tuple[str, ...] = ()
    i, n, line_start = 0, len(text), 0
    while i < n:
        c = text[i]
        if c in "\"'":
            quote = text[i:i + 3] if text[i:i + 3] in ('"""', "'''") else c
            i += len(quote)
            while i < n and text[i:i + len(quote)] != quote:
                i += 2 if c == '"' and text[i] == "\\" else 1
            i += len(quote)
            continue
        if c == "#":
            while i < n and text[i] != "\n":
                i += 1
            continue
        if c == "[" and depth == 0 and not text[line_start:i].strip():     # a table header
            end = text.find("\n", i)
            end = n if end < 0 else end
            line = text[i:end].split("#")[0].strip()
            array = line.startswith("[[")
            names = tuple(p.strip().strip("\"'") for p in line.strip("[]").split("."))
            header, key = names, ""
            if len(names) + array > best:
                best, where = len(names) + array, names
            i = end
            continue
        if c == "\n":
            line_start = i + 1
        elif c == "=" and depth == 0:
            key = text[line_start:i].strip().strip("\"'")
        elif c in "[{":
            depth += 1
            if len(header) + depth > best:
                best, where = len(header) + depth, (header + (key,))[:2] if header else (key,)
        elif c in "]}":
            depth = max(depth - 1, 0)
        i += 1
    return best, where


def loads_scenario_toml(text: str, where: str) -> dict[str, Any]:
    """``tomllib.loads(text)``, refusing a document nested deeper than :data:`MAX_DEPTH`
    (before parsing when the brackets show it, else after) instead of a RecursionError.

    Raises
    ------
    ScenarioError
        Nesting too deep (one line naming depth, limit and key), or not valid TOML.
    """
    depth, path = _text_depth(text)
    if depth > MAX_DEPTH:
        raise ScenarioError(f"{where}: nested {depth} levels deep (at most {MAX_DEPTH} "
                            f"allowed) at {_place(path)}")
    try:
        data = tomllib.loads(text)
    except RecursionError:      # a nesting the lexical count missed; say what we know
        raise ScenarioError(f"{where}: nested too deep to read (at most {MAX_DEPTH} levels "
                            "allowed)") from None
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{where}: not valid TOML: {exc}") from None
    check_nesting(data, where)
    return data
