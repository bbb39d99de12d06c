"""Every host, a command that works as printed (docs/other-tools.md, "Running an export").

The commands are read from the docs page itself (each ``<!-- host-command: FORMAT HOST -->``
followed by a ``sh`` block), so the page cannot drift: they must equal what
:func:`orchestrator.interop.hosts.host_commands` renders for the paper scenario and what
``auv-cosim export`` prints, and the slow tests run each block as written with bash, in a
folder laid out like the checkout (``.venv`` and ``tests`` linked), after exporting to the
default folders there, over the paper's full 300 s. Each host's traces must be finite and
equal our own master's where the algorithm is the same: libcosim, ecos and the C host run
libcosim's fixed-step algorithm (our ``coupling="jacobi"``) to the digits their CSVs keep
(the C host's ``%.17g``: bit for bit); fmpy's simulate_ssp runs the one-step-delayed loop of
tests/test_ssp_export.py, whose numpy reference it matches to 1e-12.
"""
from __future__ import annotations

import os
import re
import subprocess
import zipfile
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from orchestrator.interop.hosts import HOSTS, export_hint, host_commands
from orchestrator.scenario import load_scenario

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "other-tools.md"
BLOCK = re.compile(r"<!-- host-command: (\w+) ([\w-]+) -->\n```sh\n(.*?)\n```", re.S)
FORMATS = ("osp", "ssp", "native")
#: signal -> the stacked paper component whose output it is
OWNER = {"y": "plant", "ybar": "plant", "x": "plant", "w": "plant", "z": "plant", "e": "plant",
         "xhat": "estimator", "what": "estimator", "zhat": "estimator", "u": "controller"}
BY_KEY = {h.key: h for h in HOSTS}
#: what ecos's CSV row k holds against our Jacobi row k: the plant's outputs the same
#: samples, the control the one our master transfers into step k + 1 (ecos records it
#: after the step); the estimator's feedthrough outputs it samples at another point of the
#: step (checked finite only)
ECOS_ALIGNED = {"y": 0, "ybar": 0, "x": 0, "w": 0, "z": 0, "e": 0, "u": 1}


def doc_commands() -> dict[tuple[str, str], str]:
    """(format, host) -> the command docs/other-tools.md shows, in page order."""
    found = BLOCK.findall(DOC.read_text(encoding="utf-8"))
    out = {(fmt, key): text for fmt, key, text in found}
    assert len(out) == len(found), "a (format, host) pair shown twice"
    return out


def paper_files(fmt: str) -> dict[str, Path]:
    """The files the paper's export writes in its default folder (relative to the checkout)."""
    d = Path("out") / f"paper_{fmt}"
    return {"osp": {"system": d / "OspSystemStructure.xml"},
            "ssp": {"ssp": d / "paper.ssp"},
            "native": {"system": d / "OspSystemStructure.xml",
                       "ssp": d / "paper-native.ssp"}}[fmt]


def test_the_docs_show_what_hosts_renders_for_the_paper():
    """Every block of the page is the rendered command for the paper's default export, and
    every host of every export is shown (the cosim one too, though it is not run here)."""
    paper = load_scenario("paper")
    shown = doc_commands()
    rendered = {}
    for fmt in FORMATS:
        for host, text in host_commands(fmt, Path("out") / f"paper_{fmt}", T=paper.T,
                                        h=paper.h, needs_python=fmt != "native",
                                        **paper_files(fmt)):
            rendered[(fmt, host.key)] = text
    assert set(shown) == set(rendered)
    for k, text in rendered.items():
        assert shown[k] == text, k
    assert {k for _, k in shown} == set(BY_KEY)     # each host appears


def test_results_paths_are_quoted_for_the_shell():
    """A folder with a space is quoted in shell lines and a relative archive made absolute
    before ecos changes folder."""
    cmds = dict((h.key, t) for h, t in host_commands(
        "ssp", Path("my out/x"), T=1.0, h=0.01, ssp=Path("my out/x/a.ssp")))
    assert "mkdir -p 'my out/x_results'" in cmds["fmpy"]
    assert "SSP=\"$PWD/\"'my out/x/a.ssp'" in cmds["ecos"]
    assert "--stopTime 1.0 --stepSize 0.01" in cmds["ecos"]


# ------------------------------------------------------------------ running them
@pytest.fixture(scope="module")
def workspace(tmp_path_factory) -> dict:
    """A folder laid out like the checkout, with the paper exported to the default folders
    by the ``auv-cosim`` of the venv; returns the folder and what each export printed."""
    ws = tmp_path_factory.mktemp("hosts")
    (ws / ".venv").symlink_to(ROOT / ".venv")
    (ws / "tests").symlink_to(ROOT / "tests")
    (ws / "orchestrator").symlink_to(ROOT / "orchestrator")     # the C host's source
    printed = {}
    for fmt in FORMATS:
        r = subprocess.run([str(ROOT / ".venv" / "bin" / "auv-cosim"), "export", fmt],
                           cwd=ws, capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        printed[fmt] = r.stdout
    return {"dir": ws, "printed": printed}


def run_block(ws: Path, fmt: str, host: str) -> subprocess.CompletedProcess:
    """Run the page's block for (fmt, host) with bash in ``ws``, as a user pastes it."""
    text = doc_commands()[(fmt, host)]
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "LD_"))}
    r = subprocess.run(["bash", "-e", "-c", text], cwd=ws, capture_output=True, text=True,
                       env=env, timeout=900)
    assert r.returncode == 0, f"{fmt} {host}: exit {r.returncode}\n{r.stderr[-2000:]}"
    return r


def jacobi_traces(fmus: dict[str, Path], system, steps: int) -> dict[str, np.ndarray]:
    """Our master's traces with libcosim's coupling."""
    from orchestrator.cosim.master import run_system
    traces, _, _ = run_system(system, fmus, steps, coupling="jacobi")
    return traces


def assert_matches(get, ours: dict[str, np.ndarray], rows: int, *, rtol: float,
                   atol: float, signals: dict[str, int] | None = None) -> None:
    """``get(component, signal, i)`` (column i + 1; ``rows`` or ``rows + 1`` samples from
    t = 0) is finite and equals ``ours[signal][:rows, i]`` within ``atol + rtol |ours|``;
    ``signals``: signal -> rows its samples lead ours by (default every signal, 0)."""
    for sig, comp in OWNER.items():
        for i in range(ours[sig].shape[1]):
            col = get(comp, sig, i)
            assert col.ndim == 1 and col.size in (rows, rows + 1), (sig, i, col.shape)
            col = col[:rows]                       # t = 0 .. T - h (some add t = T)
            assert np.isfinite(col).all(), (sig, i)
            if signals is not None and sig not in signals:
                continue
            lead = 0 if signals is None else signals[sig]
            col, ref = col[:rows - lead], ours[sig][lead:rows, i]
            err = np.abs(col - ref) - rtol * np.abs(ref)
            assert err.max() <= atol, (sig, i, float(np.abs(col - ref).max()))
    assert np.std(ours["x"][:, 0]) > 0.01                # a moving loop, not zeros


def read_csv(path: Path) -> dict[str, np.ndarray]:
    """A CSV with one header line (names split at commas outside brackets: ``A[1,2]``), as
    column name -> values, for the columns whose first value is a number (String
    variables left out)."""
    with path.open() as f:
        head = [h.strip().strip('"')
                for h in re.split(r",(?![^\[]*\])", f.readline().rstrip("\n"))]
        first = f.readline().rstrip("\n").split(",")
    assert len(first) == len(head)

    def number(x: str) -> bool:
        try:
            float(x)
        except ValueError:
            return False
        return True
    cols = [j for j, x in enumerate(first) if number(x)]
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2, usecols=cols)
    return {head[j]: data[:, c] for c, j in enumerate(cols)}


@pytest.fixture(scope="module")
def paper():
    return load_scenario("paper")


@pytest.mark.slow
def test_export_prints_the_docs_commands(workspace):
    """What each export prints after its first line (and, for native, the line of the
    platforms it built) is the page's blocks for that format, under each host's title, in
    the page's order."""
    shown = doc_commands()
    for fmt in FORMATS:
        mine = [(BY_KEY[k], t) for (f, k), t in shown.items() if f == fmt]
        first, _, rest = workspace["printed"][fmt].partition("\n")
        if fmt == "native":
            platforms, _, rest = rest.partition("\n")
            assert platforms.startswith("binaries for linux64"), platforms
        assert rest.rstrip("\n") == export_hint(mine), fmt
        assert f"out/paper_{fmt}" in first


@pytest.mark.slow
def test_fmpy_runs_the_ssp_export_over_300_s(workspace, paper):
    """simulate_ssp as printed: 30001 rows (fmpy accumulates t += h), finite, equal to the
    numpy reference of its delayed loop to 1e-12 (the bare ``stop_time=300`` of before
    asked for 3 s steps, which the FMUs refuse)."""
    from test_ssp_export import fmpy_traces, loop_reference, max_rel_error
    run_block(workspace["dir"], "ssp", "fmpy")
    got = read_csv(workspace["dir"] / "out" / "paper_ssp_results" / "fmpy.csv")
    rows = got["time"].size
    assert rows == round(paper.T / paper.h) + 1
    assert got["time"][-1] == pytest.approx(paper.T)
    assert all(np.isfinite(v).all() for v in got.values())
    ref = loop_reference(paper.system, paper.h, paper.estimator, paper.seed, rows, "fmpy")
    assert max_rel_error(fmpy_traces(got, ref), ref) < 1e-12


def _archive_fmus(ssp: Path, dest: Path) -> dict[str, Path]:
    with zipfile.ZipFile(ssp) as z:
        z.extractall(dest)
    return {"plant": dest / "resources" / "AuvPlant.fmu",
            "estimator": dest / "resources" / "AuvEstimator.fmu",
            "controller": dest / "resources" / "AuvController.fmu"}


def _ecos_ok() -> None:
    """Skip, saying what is missing, if the ecos engine cannot start here."""
    ecospy = pytest.importorskip("ecospy", reason="ecospy is not installed (the test extra)")
    exe = Path(ecospy.__file__).parent / "binaries" / "ecos"
    if not os.access(exe, os.X_OK):
        os.chmod(exe, 0o755)
    r = subprocess.run([str(exe), "--version"], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"the ecos engine does not start ({r.stderr.strip()[:120]}); on Debian "
                    "it needs libtbb12")


@pytest.mark.slow
def test_ecos_runs_the_ssp_export_over_300_s(workspace, paper, tmp_path):
    """ecos as printed, with the pythonfmu FMUs (libpython preloaded), over 30000 steps:
    the plant's outputs and the control equal our Jacobi master's on the archive's FMUs to
    ecos's 6 decimals (:data:`ECOS_ALIGNED`), every output finite."""
    from orchestrator.running import scenario_system
    _ecos_ok()
    run_block(workspace["dir"], "ssp", "ecos")
    got = read_csv(workspace["dir"] / "out" / "paper_ssp_results" / "ecos" / "paper.csv")
    steps = round(paper.T / paper.h)
    ours = jacobi_traces(_archive_fmus(workspace["dir"] / "out" / "paper_ssp" / "paper.ssp",
                                       tmp_path), scenario_system(paper), steps)
    assert_matches(lambda c, s, i: got[f"{c}::{s}[{i + 1}][REAL]"], ours, steps,
                   rtol=0.0, atol=6e-7, signals=ECOS_ALIGNED)


def _libcosim_csv(folder: Path, component: str) -> dict[str, np.ndarray]:
    (path,) = folder.glob(f"{component}_*.csv")
    return read_csv(path)


@pytest.mark.slow
def test_libcosimpy_runs_the_osp_export_over_300_s(workspace, paper):
    """The libcosimpy script as printed: 30001 samples per variable (steps 0..30000),
    equal to our Jacobi master's on the exported FMUs to the file observer's 6 digits."""
    pytest.importorskip("libcosimpy")
    from orchestrator.running import scenario_system
    run_block(workspace["dir"], "osp", "libcosimpy")
    folder = workspace["dir"] / "out" / "paper_osp_results" / "libcosim"
    csv = {c: _libcosim_csv(folder, c) for c in set(OWNER.values())}
    steps = round(paper.T / paper.h)
    assert csv["plant"]["Time"].size == steps + 1
    exported = workspace["dir"] / "out" / "paper_osp"
    ours = jacobi_traces({k: exported / f"Auv{k.capitalize()}.fmu" for k in csv},
                         scenario_system(paper), steps)
    assert_matches(lambda c, s, i: csv[c][f"{s}[{i + 1}]"], ours, steps,
                   rtol=6e-6, atol=1e-12)


@pytest.fixture(scope="module")
def native_reference(workspace, paper, tmp_path_factory) -> dict[str, np.ndarray]:
    """Our Jacobi master on the native FMUs of the same design, 30000 steps."""
    from orchestrator.interop.native import native_system
    from orchestrator.running import build, scenario_system
    t = tmp_path_factory.mktemp("native_ref")
    ns = native_system(scenario_system(paper), build(paper, t / "py"), t / "n")
    return jacobi_traces(ns.fmus, ns.system, round(paper.T / paper.h))


@pytest.mark.slow
def test_the_c_host_runs_the_native_export_bit_for_bit(workspace, native_reference, paper):
    """The C host as printed (compiled, its system file written from the OSP system, run
    with no Python): every output equals our Jacobi master's bit for bit."""
    from fmpy import read_model_description
    run_block(workspace["dir"], "native", "c-host")
    res = workspace["dir"] / "out" / "paper_native_results"
    got = read_csv(res / "c_host.csv")
    vrs = {}
    for comp, model in (("plant", "AuvPlantNative"), ("estimator", "AuvEstimatorNative"),
                        ("controller", "AuvControllerNative")):
        md = read_model_description(str(workspace["dir"] / "out" / "paper_native"
                                        / f"{model}.fmu"))
        vrs[comp] = {v.name: v.valueReference for v in md.modelVariables}
    steps = round(paper.T / paper.h)
    assert_matches(lambda c, s, i: got[f"{c}.{vrs[c][f'{s}[{i + 1}]']}"], native_reference,
                   steps, rtol=0.0, atol=0.0)


@pytest.mark.slow
def test_ecos_and_libcosimpy_run_the_native_export(workspace, native_reference, paper):
    """ecos (no Python in it) and libcosimpy as printed, on the native FMUs: equal to our
    Jacobi master's to the digits of their CSVs."""
    pytest.importorskip("libcosimpy")
    steps = round(paper.T / paper.h)
    res = workspace["dir"] / "out" / "paper_native_results"
    run_block(workspace["dir"], "native", "libcosimpy")
    csv = {c: _libcosim_csv(res / "libcosim", c) for c in set(OWNER.values())}
    assert_matches(lambda c, s, i: csv[c][f"{s}[{i + 1}]"], native_reference, steps,
                   rtol=6e-6, atol=1e-12)
    _ecos_ok()
    run_block(workspace["dir"], "native", "ecos")
    got = read_csv(res / "ecos" / "paper-native.csv")
    assert_matches(lambda c, s, i: got[f"{c}::{s}[{i + 1}][REAL]"], native_reference, steps,
                   rtol=0.0, atol=6e-7, signals=ECOS_ALIGNED)


@pytest.mark.slow
def test_fmpy_runs_the_native_export(workspace, paper):
    """simulate_ssp as printed on the native archive: the delayed loop's reference to 1e-9
    (the native FMUs compute in C, in another order than numpy)."""
    from test_ssp_export import fmpy_traces, loop_reference, max_rel_error
    run_block(workspace["dir"], "native", "fmpy")
    got = read_csv(workspace["dir"] / "out" / "paper_native_results" / "fmpy.csv")
    rows = got["time"].size
    assert rows == round(paper.T / paper.h) + 1
    ref = loop_reference(paper.system, paper.h, paper.estimator, paper.seed, rows, "fmpy")
    assert max_rel_error(fmpy_traces(got, ref), ref) < 1e-9


@pytest.mark.slow
def test_the_c_host_system_from_osp_equals_the_one_from_the_design(tmp_path):
    """formation-4 per vehicle (13 components, initial values per component): the system
    file written from the exported OSP system holds the same FMUs, values, active
    connections and recorded outputs as the one written from the system description, and
    the C host runs it."""
    from orchestrator.benchmarks.native import c_host_binary, write_c_host_system
    from orchestrator.interop.c_host import write_c_host_system_from_osp
    from orchestrator.interop.native import export_native, native_system
    from orchestrator.running import build, scenario_system
    sc = load_scenario("formation-4").with_run(T=1.0, deployment="per-vehicle",
                                               architecture="distributed")
    paths = export_native(sc, tmp_path / "x")
    mine = write_c_host_system_from_osp(paths["system"], tmp_path / "from osp")
    ns = native_system(scenario_system(sc), build(sc, tmp_path / "py"), tmp_path / "n")
    theirs = write_c_host_system(ns.system, ns.fmus, tmp_path / "from design")

    def lines(path: Path) -> list[str]:
        out = []
        for ln in path.read_text().splitlines():
            out.append(" ".join(ln.split()[:4]) if ln.startswith("fmu ") else ln)
        return out
    a, b = lines(mine), lines(theirs)
    assert sum(ln.startswith("real ") for ln in a) > 100
    # the OSP system also wires the truth the estimators read only in mode 'ideal'
    # (write_c_host_system leaves out inactive connections); libcosim sets them too
    extra = list((Counter(a) - Counter(b)).elements())
    assert not Counter(b) - Counter(a)
    assert extra and all(ln.startswith("connect vehicle_") for ln in extra)
    exe = c_host_binary(tmp_path)
    r = subprocess.run([str(exe), str(mine), str(sc.steps), repr(sc.h), str(tmp_path / "c.csv")],
                       capture_output=True, text=True, env={}, timeout=120)
    assert r.returncode == 0, r.stderr
    got = np.loadtxt(tmp_path / "c.csv", delimiter=",", skiprows=1)
    assert got.shape == (sc.steps, 1 + sum(ln.startswith("record ") for ln in a))
    assert np.isfinite(got).all()


@pytest.mark.slow
def test_the_c_host_runs_the_native_survey_export_of_every_platform(tmp_path):
    """survey-4-remus (the 6-DOF vehicles, the multi-rate filter, guidance and autopilot
    beside them): every exported native FMU carries linux64, win64 and aarch64-linux
    binaries (those whose compiler is installed), and the C host runs the system from the
    OSP file with no Python: finite, every vehicle moving with the leader (its x[1],
    north, grows by more than 5 m in its first 10 s, from rest)."""
    from fmpy import read_model_description

    from orchestrator.benchmarks.native import c_host_binary
    from orchestrator.cosim.platforms import resolve_platforms
    from orchestrator.interop.c_host import write_c_host_system_from_osp
    from orchestrator.interop.native import export_native
    sc = load_scenario("survey-4-remus").with_run(T=10.0)
    platforms, _ = resolve_platforms(None)
    paths = export_native(sc, tmp_path / "x", platforms=platforms)
    fmus = sorted((tmp_path / "x").glob("*.fmu"))
    assert {f.name for f in fmus} >= {"AuvRemus6dofNative.fmu", "AuvGuidanceNative.fmu",
                                      "AuvAutopilotNative.fmu"}
    for f in fmus:
        with zipfile.ZipFile(f) as z:
            held = {n.split("/")[1] for n in z.namelist() if n.startswith("binaries/")}
        assert held == set(platforms), (f.name, held)
    system = write_c_host_system_from_osp(paths["system"], tmp_path / "host")
    r = subprocess.run([str(c_host_binary(tmp_path)), str(system), str(sc.steps), repr(sc.h),
                        str(tmp_path / "c.csv")], capture_output=True, text=True, env={},
                       timeout=120)
    assert r.returncode == 0, r.stderr
    header = (tmp_path / "c.csv").read_text().splitlines()[0].split(",")
    got = np.loadtxt(tmp_path / "c.csv", delimiter=",", skiprows=1)
    assert got.shape[0] == sc.steps and np.isfinite(got).all()
    md = read_model_description(str(tmp_path / "x" / "AuvRemus6dofNative.fmu"))
    north = next(v.valueReference for v in md.modelVariables if v.name == "x[1]")
    columns = [i for i, h in enumerate(header) if h.startswith("vehicle_")
               and h.endswith(f".{north}")]
    assert len(columns) == sc.fleet.N
    assert all(got[-1, i] - got[0, i] > 5.0 for i in columns), got[[0, -1]][:, columns]
