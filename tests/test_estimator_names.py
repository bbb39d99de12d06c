"""No estimator name is tested anywhere but in its own module and the estimator registry.

Every string literal of the source packages whose value is an estimator's name (``"kalman"``,
``"kalman-tv"``, ...) is a test of that name (a comparison, a dict key, a default): outside
estimator_fmu/registry.py and the estimator's own module the code asks the registry row
(estimator_fmu.registry.estimator_kind) instead. The test fails naming file and line.
"""
from __future__ import annotations

from estimator_fmu.registry import ESTIMATOR_MODES
from tests.support import name_tests
from tests.support.name_tests import PACKAGES, ROOT

REGISTRY = "estimator_fmu/registry.py"
#: each estimator's own module (its mathematics)
OWN = {"kalman": ("estimator_fmu/estimators.py",),
       "classical": ("estimator_fmu/estimators.py",),
       "ideal": ("estimator_fmu/estimators.py",),
       "kalman-tv": ("estimator_fmu/kalman_tv.py",)}


def test_every_estimator_has_its_own_module_listed():
    assert set(OWN) == set(ESTIMATOR_MODES)


def test_the_scan_finds_a_name_test():
    assert name_literals('if mode == "kalman":\n    pass\n') == [(1, "kalman")]
    assert name_literals("x = {'ideal': 1}\n") == [(1, "ideal")]
    assert name_literals('s = "kalman filter"\n') == []


def name_literals(text: str) -> list[tuple[int, str]]:
    """(line, name) of every string literal whose value is an estimator name."""
    return name_tests.name_literals(text, ESTIMATOR_MODES)


def test_no_estimator_name_is_tested_outside_its_module_and_the_registry():
    bad = []
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            if rel == REGISTRY:
                continue
            for line, name in name_literals(path.read_text()):
                if rel not in OWN[name]:
                    bad.append(f"{rel}:{line}: estimator name {name!r}")
    assert not bad, ("estimator names tested outside their module and "
                     f"{REGISTRY} (ask estimator_kind(name) instead):\n" + "\n".join(bad))
