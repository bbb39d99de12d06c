"""Replace only after success (issue 35): a command writes a staging folder beside --out
and swaps it in whole when it completes. A failed, refused, interrupted or killed
command leaves the earlier result byte for byte (every file hashed) and says so in one
line; two scenarios' builds never mix; a user's file named like a built-in gets its own
default folder; an export that cannot compile creates nothing. Real commands as real
processes, real signals."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from orchestrator.outputs import OutputFolderError, staged_output
from orchestrator.scenario import SCENARIO_DIR
from support.outputs import cli, staging_folders, tree_hashes, wait_until, working

#: a scenario that loads but whose design fails (A unstable, B1 cannot move its mode)
UNSTABILIZABLE = (SCENARIO_DIR / "paper.toml").read_text().replace(
    "A  = [[-1.0, 0.0], [0.0, -1.0]]", "A  = [[1.0, 0.0], [0.0, 1.0]]").replace(
    "B1 = [[3.0, 2.0], [4.0, 5.0]]", "B1 = [[1.0, 0.0], [0.0, 0.0]]")


def _run(*args: str | Path, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "orchestrator", *map(str, args)],
                          capture_output=True, text=True, timeout=timeout)


def _visible(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if not p.name.startswith("."))


@pytest.fixture(scope="module")
def earlier(tmp_path_factory) -> Path:
    """A completed ``run --T 1`` folder, copied into each test (:func:`_earlier`)."""
    out = tmp_path_factory.mktemp("earlier") / "F"
    r = _run("run", "--T", "1", "--quiet", "--out", out)
    assert r.returncode == 0, r.stderr
    return out


def _earlier(earlier: Path, tmp_path: Path) -> tuple[Path, dict[str, str]]:
    import shutil
    out = tmp_path / "F"
    shutil.copytree(earlier, out, symlinks=True)
    return out, tree_hashes(out)


def test_the_design_is_in_the_staging_helpers_and_a_clean_run_leaves_no_trace(tmp_path):
    with staged_output(tmp_path / "o", "run") as st:
        assert st.path.parent == tmp_path and st.path.name.startswith(".o.staging-")
        (st.path / "x.txt").write_text("new")
        assert not (tmp_path / "o").exists()              # nothing under the final name
    assert (tmp_path / "o" / "x.txt").read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == [".o.lock", "o"]


@pytest.mark.slow
def test_a_failed_run_keeps_the_earlier_result_byte_for_byte(earlier, tmp_path):
    out, before = _earlier(earlier, tmp_path)
    (tmp_path / "bad.toml").write_text(UNSTABILIZABLE)
    r = _run("run", "--T", "1", "--quiet", "--scenario", tmp_path / "bad.toml", "--out", out,
             "--force")
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 2 and "not stabilizable" in lines[0], r.stderr
    assert lines[1] == f"auv-cosim run: kept the earlier result in {out} (this run failed)"
    assert tree_hashes(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == [".F.lock", "F", "bad.toml"]


@pytest.mark.slow
def test_a_refused_run_keeps_the_earlier_result_in_one_line(earlier, tmp_path):
    out, before = _earlier(earlier, tmp_path)
    r = _run("run", "--T", "1", "--quiet", "--scenario", "formation-4", "--out", out)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "holds a run of command run, scenario paper" in lines[0]
    assert "kept as it was" in lines[0] and "--force" in lines[0]
    assert tree_hashes(out) == before


@contextmanager
def _inside_the_loop(out: Path, seconds: float) -> Iterator[subprocess.Popen]:
    """A long ``auv-cosim run`` into ``out`` (beside the earlier result there), ``seconds``
    after its FMUs are in its staging folder: inside its loop; killed on leaving."""
    proc = cli("run", "--T", "3000", "--quiet", "--out", out)
    try:
        wait_until(lambda: (working(out) / "fmus" / "AuvController.fmu").exists()
                   and working(out) != out, proc)
        time.sleep(seconds)
        yield proc
    finally:
        proc.kill()


@pytest.mark.slow
def test_a_sigkilled_run_keeps_the_earlier_result_and_its_staging_is_pruned(earlier, tmp_path):
    out, before = _earlier(earlier, tmp_path)
    with _inside_the_loop(out, 2.0) as proc:
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
    assert tree_hashes(out) == before
    assert len(staging_folders(out)) == 1                  # what the killed run left, hidden
    # the next command into the same parent folder deletes it (its owner is gone)
    r = _run("run", "--T", "0.5", "--quiet", "--out", tmp_path / "G")
    assert r.returncode == 0, r.stderr
    assert staging_folders(out) == [] and tree_hashes(out) == before
    assert _visible(tmp_path) == ["F", "G"]


@pytest.mark.slow
def test_an_interrupted_run_beside_an_earlier_result_goes_to_a_sibling(earlier, tmp_path):
    out, before = _earlier(earlier, tmp_path)
    with _inside_the_loop(out, 3.0) as proc:
        proc.send_signal(signal.SIGINT)
        _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    lines = stderr.strip().splitlines()
    partial = tmp_path / "F.interrupted"
    assert len(lines) == 1 and lines[0].startswith("auv-cosim: interrupted by SIGINT")
    assert f"the earlier result in {out} is kept as it was" in lines[0]
    assert f"partial result is in {partial}" in lines[0]
    assert tree_hashes(out) == before
    summary = json.loads((partial / "summary.json").read_text())
    assert summary["interrupted"] is True and summary["rrd"]["path"] == str(partial /
                                                                            "paper.rrd")
    assert (partial / "paper.rrd").is_file() and staging_folders(out) == []
    # a completed run then replaces the earlier result and the stale partial
    r = _run("run", "--T", "1", "--quiet", "--out", out)
    assert r.returncode == 0, r.stderr
    assert not partial.exists() and _visible(tmp_path) == ["F"]


def test_two_concurrent_writers_one_refused_in_one_line(tmp_path):
    out = tmp_path / "F"
    holder = subprocess.Popen([sys.executable, "-c", (
        "import time; from orchestrator.outputs import staged_output\n"
        f"with staged_output({str(out)!r}, 'run') as st:\n"
        "    (st.path / 'summary.json').write_text('{}')\n"
        "    print('held', flush=True); time.sleep(60)")], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        r = _run("build", "--no-crosscheck", "--out", out)
        assert r.returncode == 2
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and f"output folder {out} is in use by auv-cosim run (pid " \
            f"{holder.pid}" in lines[0], r.stderr
        assert not out.exists()                      # the holder has not finished yet
    finally:
        holder.kill()
        holder.wait(timeout=30)


@pytest.mark.slow
def test_builds_of_two_scenarios_into_one_folder_never_mix(tmp_path):
    out = tmp_path / "D"
    r = _run("build", "--no-crosscheck", "--scenario", "formation-4", "--out", out)
    assert r.returncode == 0, r.stderr
    before = tree_hashes(out)
    assert {"AuvAutopilot.fmu", "AuvGuidance.fmu"} <= set(_visible(out))
    r = _run("build", "--no-crosscheck", "--out", out)             # paper: refused
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "scenario formation-4" in r.stderr and "--force" in r.stderr
    assert tree_hashes(out) == before
    r = _run("build", "--no-crosscheck", "--out", out, "--force")  # replaced whole
    assert r.returncode == 0, r.stderr
    assert _visible(out) == ["AuvController.fmu", "AuvEstimator.fmu", "AuvPlant.fmu"]
    for line in r.stdout.splitlines():           # every path printed exists after the swap
        if ".fmu (" in line:
            assert Path(line.split(": ", 1)[1].rsplit(" (", 1)[0]).is_file(), line


def test_a_users_file_named_like_a_builtin_gets_its_own_default_folder(tmp_path):
    from orchestrator.running.naming import default_out, run_identity
    from orchestrator.scenario import load_scenario
    copy = tmp_path / "my-copy.toml"
    copy.write_text((SCENARIO_DIR / "formation-4.toml").read_text())
    mine, builtin = load_scenario(copy), load_scenario("formation-4")
    assert mine.name == builtin.name == "formation-4"
    assert default_out(builtin, "compare") == Path("out/formation-4_compare")
    assert default_out(mine, "compare") == Path("out/formation-4_from-my-copy_compare")
    assert run_identity(mine, "run") != run_identity(builtin, "run")
    assert str(copy.resolve()) in run_identity(mine, "run")["scenario"]
    other = tmp_path / "other.toml"                      # a name of its own: unchanged
    other.write_text((SCENARIO_DIR / "formation-4.toml").read_text().replace(
        'name = "formation-4"', 'name = "mine"'))
    assert default_out(load_scenario(other), "compare") == Path("out/mine_compare")


@pytest.mark.slow
def test_a_users_file_named_like_a_builtin_does_not_write_the_builtins_folder(tmp_path):
    copy = tmp_path / "formation-4.toml"                 # even the same file name
    copy.write_text((SCENARIO_DIR / "paper.toml").read_text().replace(
        'name = "paper"', 'name = "formation-4"'))
    r = subprocess.run([sys.executable, "-m", "orchestrator", "build", "--no-crosscheck",
                        "--scenario", str(copy)], capture_output=True, text=True,
                       timeout=300, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert _visible(tmp_path / "out") == ["formation-4_from-formation-4_fmus"]


def test_export_native_without_a_compiler_creates_nothing_and_keeps_an_earlier_d(tmp_path):
    env = dict(os.environ, CC="false")
    out = tmp_path / "D"
    r = subprocess.run([sys.executable, "-m", "orchestrator", "export", "native", "--out",
                        str(out)], capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not out.exists() and _visible(tmp_path) == []
    out.mkdir()
    (out / "keep.txt").write_text("earlier")
    with staged_output(out, "export", identity=None) as st:    # an earlier result in D
        (st.path / "paper.ssp").write_bytes(b"earlier ssp")
    before = tree_hashes(out)
    r = subprocess.run([sys.executable, "-m", "orchestrator", "export", "native", "--out",
                        str(out), "--force"], capture_output=True, text=True, timeout=300,
                       env=env)
    assert r.returncode == 2 and tree_hashes(out) == before
    assert r.stderr.strip().splitlines()[-1].startswith(
        f"auv-cosim export: kept the earlier result in {out}")


def test_refusals_of_the_destination_itself(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(OutputFolderError, match="holds the working folder"):
        with staged_output(tmp_path, "run"):
            pass
    (tmp_path / "f").write_text("x")
    with pytest.raises(OutputFolderError, match="is a file"):
        with staged_output(tmp_path / "f", "run"):
            pass


def test_a_swap_cut_by_a_crash_is_recovered(tmp_path):
    """The two-rename swap cut between its renames (no folder under the final name, the
    earlier one under its hidden old- name): the next command puts the earlier back."""
    out = tmp_path / "F"
    with staged_output(out, "run") as st:
        (st.path / "summary.json").write_text('{"earlier": 1}')
    before = tree_hashes(out)
    os.rename(out, tmp_path / ".F.old-deadbeef")                  # the cut swap
    with pytest.raises(RuntimeError):
        with staged_output(out, "run"):
            assert tree_hashes(out) == before                     # back before the work
            raise RuntimeError("this run fails")
    assert tree_hashes(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == [".F.lock", "F"]
