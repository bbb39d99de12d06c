"""Find the places that test a registry name (a vehicle model, an estimator, a link model)
outside the modules allowed to: ``x == "name"``, ``"name" != x``, ``x in ("name", ...)``,
``"name" in xs``. A registry keeps its promise ("a new entry is one module and one row")
only while the rest of the code asks the entry instead of testing its name."""
from __future__ import annotations

import re
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
