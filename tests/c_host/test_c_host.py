"""A non-Python FMI host (tests/c_host/host.c) running the controller FMU.

What a C host needs for our pythonfmu FMUs on Linux (all checked below):

- libpython of the Python the FMU's packages were installed for (here CPython 3.11 built
  with --enable-shared, ``libpython3.11.so.1.0``) loaded with global symbols before the
  FMU binary: ``LD_PRELOAD`` or ``dlopen(..., RTLD_GLOBAL)`` in the host. The binary
  (pythonfmu's ``libpythonfmu-export.so`` renamed) does not link libpython, and the
  extension modules of numpy/scipy need its symbols too.
- that Python must find numpy and scipy (and networkx for fleet FMUs):
  ``PYTHONEXECUTABLE=<venv>/bin/python`` makes the embedded interpreter read the
  venv's pyvenv.cfg (exactly the venv's site-packages); ``PYTHONPATH=<site-packages>``
  also works but keeps the base interpreter's site-packages after it;
  ``PYTHONHOME=<venv>`` breaks start-up (a venv has no standard library).
- pythonfmu 0.7's binary frees its static ``std::shared_ptr<PyState>`` twice at process
  exit: the C++ static destructor (registered with __cxa_atexit) releases it, then the
  library's ``__attribute__((destructor)) onLibraryUnload`` assigns nullptr to the
  destroyed shared_ptr and decrements the freed control block. With scipy loaded, its
  bundled libgfortran frees memory afterwards and glibc aborts
  (``free(): corrupted unsorted chunks``). The host avoids it by calling the library's
  exported ``finalizePythonInterpreter()`` after freeing its instances (``--exit
  pythonfmu``) or by leaving with ``_exit`` after flushing (``--exit _exit``).
  dlclose does not help: the library has STB_GNU_UNIQUE symbols and is never unloaded.
"""
from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import numpy as np
import pytest

from controller_fmu.design import lq_tracking_design
from orchestrator.cosim.build import FMU_KINDS, build_fmu
from orchestrator.running import scenario_config
from orchestrator.scenario import load_scenario

HERE = Path(__file__).resolve().parent
INPUTS = [f"{s}[{i}]" for s in ("xhat", "what", "zhat") for i in (1, 2)]
OUTPUTS = ["u[1]", "u[2]"]
STEPS = 40


def _compiler() -> str | None:
    for cc in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if cc and shutil.which(cc):
            return shutil.which(cc)
    return None


def _libpython() -> Path | None:
    if not sysconfig.get_config_var("Py_ENABLE_SHARED"):
        return None
    libdir = Path(sysconfig.get_config_var("LIBDIR") or "")
    for name in (sysconfig.get_config_var("INSTSONAME"), sysconfig.get_config_var("LDLIBRARY")):
        if name and (libdir / name).exists():
            return libdir / name
    return None


@pytest.fixture(scope="module")
def host(tmp_path_factory) -> Path:
    cc = _compiler()
    if cc is None:
        pytest.skip("no C compiler (cc, gcc or clang) on PATH")
    out = tmp_path_factory.mktemp("c_host") / "host"
    subprocess.run([cc, "-O2", "-Wall", "-Wno-format-truncation", "-o", str(out),
                    str(HERE / "host.c"), "-ldl"], check=True, capture_output=True, text=True)
    return out


@pytest.fixture(scope="module")
def libpython() -> Path:
    lib = _libpython()
    if lib is None:
        pytest.skip("this Python has no shared libpython (built without --enable-shared)")
    return lib


@pytest.fixture(scope="module")
def paper():
    return load_scenario("paper")


@pytest.fixture(scope="module")
def controller_dir(tmp_path_factory, paper) -> Path:
    """The paper scenario's controller FMU, built and extracted."""
    d = tmp_path_factory.mktemp("controller_fmu")
    fmu = build_fmu(FMU_KINDS["controller"], scenario_config(paper), d)
    with zipfile.ZipFile(fmu) as z:
        z.extractall(d / "extracted")
    return d / "extracted"


@pytest.fixture(scope="module")
def inputs() -> np.ndarray:
    return np.random.default_rng(42).normal(scale=2.0, size=(STEPS, len(INPUTS)))


def host_env(libpython: Path | None, **extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items()
           if k not in ("LD_PRELOAD", "PYTHONHOME", "PYTHONPATH", "PYTHONEXECUTABLE")}
    if libpython is not None:
        env["LD_PRELOAD"] = str(libpython)
    env["PYTHONEXECUTABLE"] = sys.executable        # the venv: numpy, scipy
    env.update(extra)
    return env


def run_host(host: Path, fmu_dir: Path, inputs: np.ndarray, env: dict[str, str],
             *args: str, wrapper: list[str] | None = None, timeout: float = 120):
    stdin = "\n".join(" ".join(repr(float(v)) for v in row) for row in inputs) + "\n"
    cmd = [*(wrapper or []), str(host), str(fmu_dir), "--in", ",".join(INPUTS),
           "--out", ",".join(OUTPUTS), *args]
    return subprocess.run(cmd, input=stdin, capture_output=True, text=True, env=env,
                          timeout=timeout)


def parse_u(stdout: str) -> np.ndarray:
    rows = [line.split() for line in stdout.splitlines() if line.strip()]
    assert [int(r[0]) for r in rows] == list(range(len(rows)))
    return np.array([[float(v) for v in r[1:]] for r in rows])


def expected_u(paper, inputs: np.ndarray) -> np.ndarray:
    Ks = lq_tracking_design(paper.system).gain_on_state()     # u = -Ks [xhat; what; zhat]
    return -inputs @ Ks.T


@pytest.mark.parametrize("exit_mode", ["pythonfmu", "_exit"])
def test_c_host_computes_the_controllers_u(host, libpython, controller_dir, inputs, paper,
                                           exit_mode):
    res = run_host(host, controller_dir, inputs, host_env(libpython), "--exit", exit_mode)
    assert res.returncode == 0, res.stderr[-2000:]
    # the logger callback printed the slave's message from exitInitializationMode
    assert "[OK] c_host (logAll): design (lq): slowest closed-loop pole" in res.stderr
    u = parse_u(res.stdout)
    assert u.shape == (STEPS, 2)
    assert np.allclose(u, expected_u(paper, inputs), rtol=1e-12, atol=1e-12)


def test_libpython_by_dlopen_instead_of_ld_preload(host, libpython, controller_dir, inputs, paper):
    res = run_host(host, controller_dir, inputs, host_env(None), "--libpython", str(libpython),
                   "--exit", "pythonfmu")
    assert res.returncode == 0, res.stderr[-2000:]
    assert np.allclose(parse_u(res.stdout), expected_u(paper, inputs), rtol=1e-12, atol=1e-12)


def test_without_libpython_the_fmu_does_not_load(host, controller_dir, inputs):
    res = run_host(host, controller_dir, inputs, host_env(None))
    assert res.returncode != 0
    assert "undefined symbol: _Py_NoneStruct" in res.stderr


def test_pythonhome_of_a_venv_breaks_startup(host, libpython, controller_dir, inputs):
    venv = Path(sys.prefix)
    if venv == Path(sys.base_prefix):
        pytest.skip("not running in a virtual environment")
    res = run_host(host, controller_dir, inputs, host_env(libpython, PYTHONHOME=str(venv)))
    assert res.returncode != 0
    assert "No module named 'encodings'" in res.stderr


def test_default_exit_and_the_pythonfmu_teardown(host, libpython, controller_dir, inputs, paper):
    """Returning from main after fmi2FreeInstance: the results are right, the process may
    then abort in glibc (heap corrupted by pythonfmu's teardown, see the module doc)."""
    res = run_host(host, controller_dir, inputs, host_env(libpython), "--exit", "return")
    assert np.allclose(parse_u(res.stdout), expected_u(paper, inputs), rtol=1e-12, atol=1e-12)
    assert "# freed the instance" in res.stderr and "# leaving by return from main" in res.stderr
    if res.returncode != 0:
        assert res.returncode == -signal.SIGABRT
        assert "corrupted" in res.stderr or "free()" in res.stderr, res.stderr[-500:]


@pytest.mark.slow
def test_valgrind_shows_the_use_after_free_and_the_workaround(host, libpython, controller_dir,
                                                              inputs):
    valgrind = shutil.which("valgrind")
    if valgrind is None:
        pytest.skip("valgrind is not installed")
    env = host_env(libpython, PYTHONMALLOC="malloc")
    uaf = re.compile(r"Invalid (read|write) of size \d+\n==\d+==\s+at 0x[0-9A-Fa-f]+: "
                     r"finalizePythonInterpreter")
    cases = {"return": ("--exit", "return"), "pythonfmu": ("--exit", "pythonfmu"),
             "_exit": ("--exit", "_exit"),
             # the host owning and finalizing the interpreter does not avoid it
             "host finalizes": ("--init-python", "--exit", "finalize")}
    from concurrent.futures import ThreadPoolExecutor

    def one(args: tuple[str, ...]) -> bool:         # each case its own process: 2 at a time
        res = run_host(host, controller_dir, inputs[:2], env, *args,
                       wrapper=[valgrind, "--num-callers=6", "--undef-value-errors=no", "--leak-check=no"], timeout=900)
        return bool(uaf.search(res.stderr))
    with ThreadPoolExecutor(max_workers=2) as pool:
        found = dict(zip(cases, pool.map(one, cases.values())))
    assert found == {"return": True, "pythonfmu": False, "_exit": False, "host finalizes": True}
