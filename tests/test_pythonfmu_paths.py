"""pythonfmu 0.7 crashes its host (SIGSEGV) on a resource folder it cannot open; our master
never hands it one. Each case runs in its own process, since the crash takes the process."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap

import pytest

from orchestrator.cosim.instance import pythonfmu_can_load_from


def _python(code: str, **env: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                          text=True, timeout=300, env=dict(os.environ, **env))


@pytest.mark.parametrize("path, ok", [("/tmp/a b/c-d_e.f~", True), ("/tmp/é", False),
                                      ("/tmp/a+b", False), ("/tmp/a%20b", False)])
def test_which_paths_pythonfmu_can_read(path, ok):
    assert pythonfmu_can_load_from(path) is ok


def test_the_upstream_crash_is_real(paper_fmus, tmp_path):
    """The fault our master avoids: fmpy's own instantiate of a pythonfmu FMU unzipped under
    a non-ASCII folder (fmpy percent-encodes the resource URI) kills the process."""
    where = tmp_path / "résumé"
    r = _python(f"""
        from fmpy import extract
        from fmpy.fmi2 import FMU2Slave
        from fmpy import read_model_description
        md = read_model_description({str(paper_fmus['controller'])!r})
        d = extract({str(paper_fmus['controller'])!r}, unzipdir={str(where)!r})
        s = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier='AuvController',
                      instanceName='x')
        s.instantiate()
        print('survived')
    """)
    assert r.returncode == -signal.SIGSEGV, (r.returncode, r.stdout, r.stderr[-500:])


def test_our_instance_refuses_such_a_folder_instead_of_crashing(paper_fmus, tmp_path):
    where = tmp_path / "résumé"
    r = _python(f"""
        from fmpy import extract
        from orchestrator.cosim.instance import CosimError, FmuInstance
        d = extract({str(paper_fmus['controller'])!r}, unzipdir={str(where)!r})
        try:
            FmuInstance('controller', {str(paper_fmus['controller'])!r}, d, 'x')
        except CosimError as exc:
            print(exc)
        import shutil, pathlib
        d = extract({str(paper_fmus['controller'])!r}, unzipdir={str(tmp_path / "plain")!r})
        shutil.rmtree(pathlib.Path(d) / 'resources')
        try:
            FmuInstance('controller', {str(paper_fmus['controller'])!r}, d, 'y')
        except CosimError as exc:
            print(exc)
    """)
    assert r.returncode == 0, r.stderr[-800:]
    first, second = r.stdout.strip().splitlines()
    assert "controller FMU: not instantiated" in first and "cannot decode" in first
    assert "holds no slave module" in second


def test_a_run_with_a_non_ascii_tmpdir_works(tmp_path):
    tmpdir = tmp_path / "tmp-ü"
    tmpdir.mkdir()
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "orchestrator", "run", "--T", "2", "--quiet",
                        "--out", str(out)], capture_output=True, text=True, timeout=300,
                       env=dict(os.environ, TMPDIR=str(tmpdir)))
    assert r.returncode == 0, (r.returncode, r.stderr[-800:])
    summary = json.loads((out / "summary.json").read_text())
    assert summary["steps"] == 200 and summary["methods"]["kalman"]["seeds_completed"] == 1
    assert list(tmpdir.iterdir()) == []                     # nothing unzipped there
