"""Output folders: one writer at a time (two real processes), unwritable folders refused
early in one line, scenario names that never lead outside --out."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import pytest

from orchestrator.cli import main
from orchestrator.outputs import OutputFolderError, file_stem, lock_path, output_folder
from orchestrator.scenario import SCENARIO_DIR


@pytest.mark.parametrize("name, stem", [
    ("paper", "paper"), ("../x", "_x"), ("a/b c", "a_b_c"), ("..", "scenario"),
    ("/etc/passwd", "_etc_passwd"), ("fleet-4 (v2)", "fleet-4_v2_"), ("ééé", "scenario"),
    ("x" * 300, "x" * 100),
])
def test_file_stem_stays_in_the_folder(name, stem):
    assert file_stem(name) == stem
    assert "/" not in stem and not stem.startswith(".")


def test_a_second_holder_is_refused_and_the_first_keeps_the_folder(tmp_path):
    with output_folder(tmp_path / "o", "run") as out:
        assert f"auv-cosim run (pid {os.getpid()}" in lock_path(out).read_text()
        assert lock_path(out) == tmp_path / ".o.lock"         # beside it: o is swapped
        with pytest.raises(OutputFolderError, match="is in use by auv-cosim run"):
            with output_folder(tmp_path / "o", "compare"):
                pass
    with output_folder(tmp_path / "o", "build"):       # released at the end of the block
        pass


def test_a_hostile_scenario_name_writes_only_inside_out(tmp_path, capsys):
    text = (SCENARIO_DIR / "paper.toml").read_text()
    text = text.replace('name = "paper"', 'name = "../escaped"')
    assert 'name = "../escaped"' in text
    (tmp_path / "s.toml").write_text(text)
    out = tmp_path / "deep" / "out"
    assert main(["run", "--scenario", str(tmp_path / "s.toml"), "--T", "1", "--quiet",
                 "--out", str(out)]) == 0
    assert (out / "_escaped.rrd").is_file()
    assert sorted(p.name for p in (tmp_path / "deep").iterdir()) == [".out.lock", "out"]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["scenario"] == "../escaped"        # the label is kept as written


@pytest.mark.parametrize("bad", ["\\u0000x", "a\\nb", "   "])
def test_a_name_with_control_characters_is_refused(tmp_path, capsys, bad):
    text = (SCENARIO_DIR / "paper.toml").read_text().replace('name = "paper"', f'name = "{bad}"')
    (tmp_path / "s.toml").write_text(text)
    assert main(["run", "--scenario", str(tmp_path / "s.toml"), "--T", "1", "--quiet",
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "name = " in err and "control characters" in err
    assert not (tmp_path / "o").exists()


def _cli(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "orchestrator", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.mark.parametrize("second", [
    ("run", "--T", "1", "--quiet"), ("compare", "--T", "1", "--seeds", "0", "--quiet"),
    ("build", "--no-crosscheck"),
])
@pytest.mark.slow
def test_two_real_writers_into_one_folder(tmp_path, second):
    """A long `run` holds the folder; a second command into it is refused in one line with
    exit status 2, and the first one finishes with its own files intact."""
    out = tmp_path / "shared"
    first = _cli("run", "--T", "600", "--quiet", "--out", str(out))
    try:
        deadline = time.monotonic() + 120
        while f"pid {first.pid}" not in (lock_path(out).read_text()
                                         if lock_path(out).exists() else ""):
            assert first.poll() is None and time.monotonic() < deadline, first.stderr.read()
            time.sleep(0.02)
        other = _cli(*second, "--out", str(out))
        _, err = other.communicate(timeout=120)
        assert other.returncode == 2, err
        lines = err.strip().splitlines()
        assert len(lines) == 1, err
        assert f"output folder {out} is in use by auv-cosim run (pid {first.pid}" in lines[0]
        _, err1 = first.communicate(timeout=300)
    finally:
        first.kill()
    assert first.returncode == 0, err1
    summary = json.loads((out / "summary.json").read_text())
    assert summary["T"] == 600.0 and summary["seeds"] == [0]
    for fmu in (out / "fmus").glob("*.fmu"):
        assert zipfile.ZipFile(fmu).testzip() is None


def test_two_concurrent_builds_one_refused_fmus_intact(tmp_path):
    """Two builds of two scenarios into one folder at once: one is refused in one line
    (the folder in use, or, when they did not overlap, holding the other scenario's
    build); the folder holds exactly one scenario's FMUs, whole."""
    out = tmp_path / "fmus"
    procs = [_cli("build", "--no-crosscheck", "--out", str(out)),
             _cli("build", "--no-crosscheck", "--scenario", "formation-4", "--out", str(out))]
    results = [(p.wait(timeout=300), p.stderr.read()) for p in procs]
    assert sorted(c for c, _ in results) == [0, 2], results
    err = next(e for c, e in results if c == 2)
    assert len(err.strip().splitlines()) == 1, err
    assert "is in use by auv-cosim build" in err or "holds a run of command build" in err
    won = "paper" if results[0][0] == 0 else "formation-4"
    expected = ({"AuvPlant.fmu", "AuvEstimator.fmu", "AuvController.fmu"} if won == "paper"
                else {"AuvPlant.fmu", "AuvEstimator.fmu", "AuvController.fmu",
                      "AuvAutopilot.fmu", "AuvGuidance.fmu"})
    assert {p.name for p in out.glob("*.fmu")} <= expected
    assert json.loads((out / ".auv-cosim-run.json").read_text())["scenario"] == won
    for fmu in out.glob("*.fmu"):
        assert zipfile.ZipFile(fmu).testzip() is None
    assert not list(out.glob("*.part")) and not list(out.glob(".*.part"))
    assert [p.name for p in tmp_path.iterdir()] == [".fmus.lock", "fmus"] or \
        sorted(p.name for p in tmp_path.iterdir()) == [".fmus.lock", "fmus"]


def _as_nobody(cmd: list[str], env: dict) -> subprocess.CompletedProcess:
    return subprocess.run(["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups",
                           *cmd], capture_output=True, text=True, env=env, timeout=120)


@pytest.fixture
def open_tmp():
    """A temporary folder other users can enter (pytest's tmp_path is under a 0700 folder)."""
    d = Path(tempfile.mkdtemp(prefix="auv_perm_"))
    d.chmod(0o755)
    yield d
    shutil.rmtree(d, ignore_errors=True)


def test_an_unwritable_out_is_refused_before_any_work(open_tmp):
    """Run as an unprivileged user (root writes anywhere): one line, exit 2, nothing built."""
    tmp_path = open_tmp
    ro = tmp_path / "readonly"
    ro.mkdir()
    env = dict(os.environ, AUV_COSIM_CACHE=str(tmp_path / "cache"), HOME=str(tmp_path))
    cmd = [sys.executable, "-m", "orchestrator", "run", "--T", "1", "--quiet",
           "--out", str(ro / "o")]
    if os.geteuid() == 0:
        if shutil.which("setpriv") is None:
            pytest.skip("running as root and setpriv (util-linux) is missing: cannot drop "
                        "privileges to test an unwritable folder")
        probe = _as_nobody([sys.executable, "-c", "import orchestrator"], env)
        if probe.returncode != 0:
            pytest.skip(f"user nobody cannot import the project here: {probe.stderr[-200:]}")
        r = _as_nobody(cmd, env)
    else:
        ro.chmod(0o555)
        r = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert "permission denied" in lines[0] and str(ro / "o") in lines[0]
    assert not (tmp_path / "cache").exists()            # refused before building anything
    assert list(ro.iterdir()) == []


def test_the_lock_goes_with_a_killed_holder(tmp_path):
    out = tmp_path / "o"
    holder = subprocess.Popen([sys.executable, "-c", (
        "import sys, time; from orchestrator.outputs import output_folder\n"
        f"with output_folder({str(out)!r}, 'run'):\n"
        "    print('held', flush=True); time.sleep(60)")], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(OutputFolderError):
            with output_folder(out, "run"):
                pass
        holder.kill()
        holder.wait(timeout=30)
    finally:
        holder.kill()
    with output_folder(out, "run") as o:               # the kernel released it
        assert Path(o) == out


def test_a_folder_holding_another_kind_of_run_is_refused_unless_forced(tmp_path):
    """staged_output: the same kind of run replaces its earlier outputs as a whole (the
    names it recorded: figures, recording, per-plant subfolders), the user's own files are
    carried over; another kind is refused in one line naming both and the folder is left
    as it was; with force it is replaced."""
    from orchestrator.outputs import RUN_MARKER, staged_output
    from support.outputs import tree_hashes
    out = tmp_path / "o"
    stacked = {"command": "run", "deployment": "stacked"}
    with staged_output(out, "run", identity=stacked) as st:
        (st.path / "summary.json").write_text("{}")
        (st.path / "paper.rrd").write_bytes(b"x")
        (st.path / "figures").mkdir()
        (st.path / "figures" / "error-1.png").write_bytes(b"x")
        (st.path / "remus100").mkdir()
        (st.path / "remus100" / "summary.json").write_text("{}")
    (out / "notes.txt").write_text("the user's own file")
    before = tree_hashes(out)
    per_vehicle = {"command": "run", "deployment": "per-vehicle"}
    with pytest.raises(OutputFolderError) as exc:
        with staged_output(out, "run", identity=per_vehicle):
            pass
    assert "deployment stacked" in str(exc.value) and "deployment per-vehicle" in str(exc.value)
    assert "--force" in str(exc.value) and "\n" not in str(exc.value)
    assert tree_hashes(out) == before                          # nothing touched
    with staged_output(out, "run", identity=stacked) as st:   # the same kind: replaced
        (st.path / "summary.json").write_text('{"new": 1}')
    assert not (out / "figures").exists() and not (out / "paper.rrd").exists()
    assert not (out / "remus100").exists() and (out / "notes.txt").read_text() == \
        "the user's own file"
    with staged_output(out, "run", identity=per_vehicle, force=True):
        pass
    assert not (out / "summary.json").exists() and (out / "notes.txt").exists()
    assert json.loads((out / RUN_MARKER).read_text()) == {**per_vehicle, "outputs": []}
    assert sorted(p.name for p in tmp_path.iterdir()) == [".o.lock", "o"]   # no leftovers
