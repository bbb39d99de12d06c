"""ScenarioError, and the one line it carries, built from a pydantic ValidationError.

Every problem in a scenario is reported in one line naming the source (a file, or
``built-in scenario 'paper'``), the section, the key and what was expected::

    <source>: unknown section(s) or key(s): plant (allowed: name, description, ...)
    <source>: unknown key(s) in [cost]: S (allowed: Q, R)
    <source>: missing key(s) in [vehicles]: A, B1 (A: ...; B1: ...)
    <source>: [cost] must be a table (got 1.0)
    <source>: [simulation] h = 0.0 must be a positive number of seconds
    <source>: [simulation] estimator 'ekf' is unknown; expected one of kalman, classical, ideal
    <source>: [vehicles] A: wrong shape 2x3, expected 2x2        (a plant_model check)

The section and key come from the error's location, never from its text. pydantic collects
every error; the one reported is the first of the first kind present, in this order:
unknown sections, a section that is not a table, unknown keys, missing keys, bad values
(within a kind, in the order of the schema). Unknown and missing keys of one table are
reported together.
"""
from __future__ import annotations

import types
from collections.abc import Mapping, Sequence
from typing import Any, TypeVar, Union, get_args, get_origin

from pydantic import BaseModel, ValidationError
from pydantic_core import ErrorDetails, PydanticCustomError

__all__ = ["ScenarioError", "validate_scenario", "scenario_error", "bad_value", "unknown_choice"]

M = TypeVar("M", bound=BaseModel)

#: custom pydantic error types: "<key> = <value> <message>" and "<key> <value> <message>"
VALUE_ERROR = "scenario_value"
CHOICE_ERROR = "scenario_choice"

#: what pydantic's own type errors expect, in the words of a TOML file
_EXPECTED = {"string_type": "must be a string", "int_type": "must be an integer",
             "float_type": "must be a number", "bool_type": "must be true or false",
             "list_type": "must be an array", "finite_number": "must be finite"}
_TABLE_ERRORS = ("model_type", "dict_type")


class ScenarioError(ValueError):
    """A scenario file is invalid; the message names the file, the section and the key."""


def bad_value(message: str, **context: Any) -> PydanticCustomError:
    """An error reported as ``[section] key = <value> <message>`` (``{name}`` from context)."""
    return PydanticCustomError(VALUE_ERROR, message, context or None)


def unknown_choice(choices: Sequence[str]) -> PydanticCustomError:
    """An error reported as ``[section] key <value> is unknown; expected one of <choices>``."""
    return PydanticCustomError(CHOICE_ERROR, "is unknown; expected one of {choices}",
                               {"choices": ", ".join(choices)})


def validate_scenario(model: type[M], data: Mapping[str, Any], where: str) -> M:
    """``model`` validated from ``data``; any problem is a one-line :class:`ScenarioError`."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise scenario_error(exc, model, data, where) from None


def _rank(error: ErrorDetails) -> int:
    kind, depth = error["type"], len(error["loc"])
    if kind == "extra_forbidden":
        return 0 if depth == 1 else 2
    return 1 if kind in _TABLE_ERRORS else 3 if kind == "missing" else 4


def _unwrap(annotation: Any) -> Any:
    """The model class inside ``X | None`` and ``list[X]`` annotations."""
    while get_origin(annotation) in (Union, types.UnionType, list):
        annotation = next(a for a in get_args(annotation) if a is not type(None))
    return annotation


def _model_at(model: type[BaseModel], loc: Sequence[str | int]) -> type[BaseModel] | None:
    """The model class that validates the table at ``loc`` (None if not a table)."""
    current: Any = model
    for part in loc:
        if isinstance(part, int):
            continue                                   # an entry of a list of tables
        if not (isinstance(current, type) and issubclass(current, BaseModel)) \
                or part not in current.model_fields:
            return None
        current = _unwrap(current.model_fields[part].annotation)
    return current if isinstance(current, type) and issubclass(current, BaseModel) else None


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _place(model: type[BaseModel], data: Any, loc: Sequence[str | int]) -> str:
    """``[section] key.sub[2]`` for a location (list entries 1-based; an entry that names a
    vehicle adds ``(vehicle i)``); a top-level key that is no section is named alone."""
    if not loc:
        return ""
    if _model_at(model, loc[:1]) is None:
        return str(loc[0])
    node = data.get(loc[0]) if isinstance(data, Mapping) else None
    key, sep = "", ""
    for part in loc[1:]:
        if isinstance(part, int):
            node = node[part] if isinstance(node, list) and part < len(node) else None
            vehicle = node.get("vehicle") if isinstance(node, Mapping) else None
            named = isinstance(vehicle, int) and not isinstance(vehicle, bool)
            key += f"[{part + 1}]" + (f" (vehicle {vehicle})" if named else "")
            sep = " " if named else "."
        else:
            key += f"{sep}{part}" if key else str(part)
            node, sep = (node.get(part) if isinstance(node, Mapping) else None), "."
    return f"[{loc[0]}] {key}".rstrip()


def _names(errors: list[ErrorDetails], kind: str, parent: tuple) -> list[str]:
    return sorted({str(e["loc"][-1]) for e in errors
                   if e["type"] == kind and tuple(e["loc"][:-1]) == parent})


def _missing(table: type[BaseModel] | None, names: list[str]) -> str:
    """``A, B1 (A: description; B1: description)`` from the fields' descriptions (a single
    missing key: ``path (description)``)."""
    fields = table.model_fields if table is not None else {}
    described = [n for n in names if n in fields and fields[n].description]
    notes = [f"{n}: {fields[n].description}" for n in described]
    if names == described and len(names) == 1:
        notes = [str(fields[names[0]].description)]
    return ", ".join(names) + (f" ({'; '.join(notes)})" if notes else "")


def scenario_error(exc: ValidationError, model: type[BaseModel], data: Mapping[str, Any],
                   where: str) -> ScenarioError:
    """The one-line :class:`ScenarioError` for the first problem of ``exc`` (see the module
    docstring): ``model`` is the top-level model that was validated, ``data`` its input."""
    errors = exc.errors(include_url=False)
    first = min(errors, key=_rank)                     # min keeps the schema order among equals
    loc, kind, value = tuple(first["loc"]), first["type"], first.get("input")
    place = _place(model, data, loc)
    if kind == "extra_forbidden":
        parent = loc[:-1]
        table = _model_at(model, parent)
        allowed = ", ".join(table.model_fields) if table is not None else ""
        names = ", ".join(_names(errors, kind, parent))
        what = (f"unknown section(s) or key(s): {names}" if not parent
                else f"unknown key(s) in {_place(model, data, parent)}: {names}")
        text = f"{what} (allowed: {allowed})" if allowed else what
    elif kind == "missing":
        table = _model_at(model, loc)
        if table is not None:                          # a whole table is missing
            required = sorted(n for n, f in table.model_fields.items() if f.is_required())
            text = (f"missing key(s) in {place}: {_missing(table, required)}" if required
                    else f"{place} section is missing")
        else:
            parent = loc[:-1]
            names = _names(errors, kind, parent)
            text = (f"missing key(s) in {_place(model, data, parent)}: "
                    f"{_missing(_model_at(model, parent), names)}")
    elif kind in _TABLE_ERRORS:
        text = f"{place or 'the scenario'} must be a table (got {_short(value)})"
    elif kind == VALUE_ERROR:
        text = f"{place} = {_short(value)} {first['msg']}"
    elif kind == CHOICE_ERROR:
        text = f"{place} {_short(value)} {first['msg']}"
    elif "error" in (first.get("ctx") or {}):            # a ValueError (ModelError) of a validator
        msg = str(first["ctx"]["error"])
        section = str(loc[0]) if loc else ""
        if section and msg.startswith(f"{section}: "):
            msg = msg[len(section) + 2:]               # plant_model's own "leader: " / "graph: "
        # a message that names its section itself ("[sensors] dvl_dropout = ...") stands alone
        text = msg if section and msg.startswith(f"[{section}]") else f"{place} {msg}".strip()
    else:
        expected = _EXPECTED.get(kind, first["msg"])
        text = f"{place} = {_short(value)} {expected}" if place else expected
    return ScenarioError(" ".join(f"{where}: {text}".split("\n")))
