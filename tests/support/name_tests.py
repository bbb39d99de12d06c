"""Find the places that test a registry name (a vehicle model, an estimator, a link model)
outside the modules allowed to. A registry keeps its promise ("a new entry is one module
and one row") only while the rest of the code asks the entry instead of testing its name.

Two strengths: :func:`name_tests` finds comparisons (``x == "name"``, ``"name" != x``,
``x in ("name", ...)``, ``"name" in xs``); :func:`name_literals` finds every string literal
whose value is a name (a comparison, a dict key, a default)."""
from __future__ import annotations

import ast
import io
import re
import tokenize
from collections.abc import Iterable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
#: the packages whose code may not test names (tests and docs may)
PACKAGES = ("orchestrator", "plant_model", "controller_fmu", "estimator_fmu", "fmu_common")


def _patterns(name: str) -> list[re.Pattern[str]]:
    q = rf"""["']{re.escape(name)}["']"""
    return [re.compile(rf"(==|!=)\s*{q}"), re.compile(rf"{q}\s*(==|!=)"),
            re.compile(rf"\bin\s*[\(\[\{{][^\)\]\}}]*{q}"),
            re.compile(rf"{q}\s+(not\s+)?in\b")]


def name_tests(names: Iterable[str], allowed: Iterable[str]) -> list[str]:
    """``path:line: code`` of every test of one of ``names`` in :data:`PACKAGES` outside the
    files ``allowed`` (paths relative to the repository; a folder ending in ``/`` allows
    everything under it)."""
    allowed = tuple(allowed)
    pats = [p for n in names for p in _patterns(n)]
    found = []
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            if any(rel == a or (a.endswith("/") and rel.startswith(a)) for a in allowed):
                continue
            for k, line in enumerate(path.read_text().splitlines(), start=1):
                code = line.split("#", 1)[0]
                if any(p.search(code) for p in pats):
                    found.append(f"{rel}:{k}: {line.strip()}")
    return found


def name_literals(text: str, names: Iterable[str]) -> list[tuple[int, str]]:
    """(line, name) of every string literal of the Python source ``text`` whose value is one
    of ``names`` (an f-string is never a bare name)."""
    names = set(names)
    out = []
    for tok in tokenize.generate_tokens(io.StringIO(text).readline):
        if tok.type != tokenize.STRING:
            continue
        try:
            value = ast.literal_eval(tok.string)
        except (ValueError, SyntaxError):
            continue
        if isinstance(value, str) and value in names:
            out.append((tok.start[0], value))
    return out
