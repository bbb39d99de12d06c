"""Shared fixtures: the paper's example typed in from docs/theory.md, and small scalar systems.

The paper's matrices are copied from docs/theory.md (section 9) here, independently of
orchestrator/scenario/builtin/paper.toml, so that test_scenario.py can compare the two.
"""
from __future__ import annotations

import copy

import pytest

from plant_model.system import LinearSystem
from support.recording import FLEET_STRIDE_IDS, FLEET_STRIDES

#: The paper's example (docs/theory.md section 9): every noise intensity 2, Q = R = I, T = 300 s.
PAPER_MAPPING = {
    "A": [[-1.0, 0.0], [0.0, -1.0]],
    "B1": [[3.0, 2.0], [4.0, 5.0]],
    "B2": [[-0.1, 0.0], [0.0, 1.0]],
    "C": [[1.0, 2.0], [3.0, 4.0]],
    "x0": [0.0, 0.0],
    "F": [[-0.1, 1.0], [-1.0, -0.2]],
    "H": [[0.2, 4.0], [2.0, 5.0]],
    "z0": [0.4, 0.5],
    "K": [[-5.0, 1.0], [-1.0, -9.0]],
    "Bz": [[0.0, 0.0], [0.0, 0.0]],     # single vehicle: no leader term in its dynamics
    "w0": [0.3, 0.4],
    "Q": [[1.0, 0.0], [0.0, 1.0]],
    "R": [[1.0, 0.0], [0.0, 1.0]],
    "W_x": [[2.0, 0.0], [0.0, 2.0]],
    "W_w": [[2.0, 0.0], [0.0, 2.0]],
    "W_z": [[2.0, 0.0], [0.0, 2.0]],
    "V_y": [[2.0, 0.0], [0.0, 2.0]],
    "V_ybar": [[2.0, 0.0], [0.0, 2.0]],
    "noise_convention": "intensity",
}

def scalar_mapping(**changes) -> dict:
    """A 1x1 system (n = m = r = p = l = 1) with unit noise; entries may be overridden."""
    d = {
        "A": [[-1.0]], "B1": [[1.0]], "B2": [[1.0]], "C": [[1.0]],
        "F": [[-0.5]], "H": [[1.0]], "K": [[-2.0]],
        "Q": 1.0, "R": 1.0,
        "W_x": 1.0, "W_w": 1.0, "W_z": 1.0, "V_y": 1.0, "V_ybar": 1.0,
    }
    d.update(changes)
    return d


@pytest.fixture
def paper_mapping() -> dict:
    """A fresh deep copy of the paper's mapping (safe to modify in a test)."""
    return copy.deepcopy(PAPER_MAPPING)


@pytest.fixture(scope="session")
def paper_system() -> LinearSystem:
    return LinearSystem.from_mapping(copy.deepcopy(PAPER_MAPPING))


@pytest.fixture(scope="session")
def scalar_system() -> LinearSystem:
    return LinearSystem.from_mapping(scalar_mapping())


@pytest.fixture
def scalar_mapping_factory():
    """Factory: ``scalar_mapping_factory(**changes)`` -> a fresh 1x1 mapping."""
    return scalar_mapping


@pytest.fixture
def make_scalar():
    """Factory: ``make_scalar(**changes)`` -> validated 1x1 LinearSystem."""
    return lambda **changes: LinearSystem.from_mapping(scalar_mapping(**changes))


@pytest.fixture(scope="session", autouse=True)
def fmu_cache(tmp_path_factory, request):
    """Built FMUs are cached per test run (AUV_COSIM_CACHE), not in the user's cache. The
    pytest-xdist workers of one run share one cache (beside their own temporary folders):
    a build is written under a temporary name and renamed, so two workers building the
    same FMU leave one whole file, and each FMU is built once per run, not once per
    worker."""
    import os
    if getattr(request.config, "workerinput", None) is None:      # not an xdist worker
        path = tmp_path_factory.mktemp("fmu_cache")
    else:
        path = tmp_path_factory.getbasetemp().parent / "fmu_cache"
        path.mkdir(exist_ok=True)
    old = os.environ.get("AUV_COSIM_CACHE")
    os.environ["AUV_COSIM_CACHE"] = str(path)
    yield path
    if old is None:
        os.environ.pop("AUV_COSIM_CACHE", None)
    else:
        os.environ["AUV_COSIM_CACHE"] = old


@pytest.fixture(scope="session")
def paper():
    """The built-in paper scenario (orchestrator/scenario/builtin/paper.toml)."""
    from orchestrator.scenario import load_scenario
    return load_scenario("paper")


@pytest.fixture(scope="session")
def formation4():
    """The built-in formation-4 fleet scenario."""
    from orchestrator.scenario import load_scenario
    return load_scenario("formation-4")


@pytest.fixture(scope="session")
def paper_fmus(built_scenario):
    """The paper scenario's three FMUs, built once per session (read-only: copy to change)."""
    return built_scenario("paper")[0]


@pytest.fixture(scope="session")
def formation4_fmus(built_scenario):
    """The formation-4 scenario's three FMUs, built once per session."""
    return built_scenario("formation-4")[0]


@pytest.fixture(scope="session")
def built_scenario(tmp_path_factory):
    """Factory: ``built_scenario(name)`` -> (FMU paths, configuration) of a built-in
    scenario's three FMUs, built once per test session."""
    from orchestrator.running import build, scenario_config
    from orchestrator.scenario import load_scenario

    cache: dict[str, tuple] = {}

    def get(name: str = "paper", consensus: str | None = None):
        key = (name, consensus)
        if key not in cache:
            sc = load_scenario(name)
            if consensus is not None:           # a fleet in the other consensus form
                import tomllib

                from orchestrator.scenario import SCENARIO_DIR, scenario_from_dict
                data = tomllib.loads((SCENARIO_DIR / f"{name}.toml").read_text())
                data["graph"]["consensus"] = consensus
                sc = scenario_from_dict(data, f"built-in scenario '{name}' ({consensus})")
            cache[key] = (build(sc, tmp_path_factory.mktemp(f"fmus_{name}")),
                          scenario_config(sc))
        return cache[key]

    return get


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """The paper layout's recording (support.recording), written once per test module."""
    from support.recording import write_paper_recording
    return write_paper_recording(tmp_path_factory)


@pytest.fixture(scope="module", params=FLEET_STRIDES, ids=FLEET_STRIDE_IDS)
def fleet_written(request, tmp_path_factory):
    """The fleet layout's recording at each stride, written once per test module."""
    from support.recording import write_fleet_recording
    return write_fleet_recording(tmp_path_factory, request.param)


@pytest.fixture(scope="session")
def resume_reference(tmp_path_factory):
    """The rows (timing columns dropped) of support.campaign.RESUME run uninterrupted on a
    local cluster of 2 workers: what an interrupted and resumed campaign must equal. Once
    per test process (the fault and resume tests share it)."""
    import subprocess
    import sys

    from support.campaign import RESUME, rows, without_timing
    d = tmp_path_factory.mktemp("resume_reference")
    (d / "spec.toml").write_text(RESUME)
    proc = subprocess.run([sys.executable, "-m", "orchestrator", "campaign", str(d / "spec.toml"),
                           "--workers", "2", "--out", str(d / "out")], capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    table = without_timing(rows(d / "out"))
    assert len(table) == 12 and all(r["status"] == "ok" for r in table)
    return table

