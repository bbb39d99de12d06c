"""Bad input at the command line ends in one line naming the problem and exit status 2 (or
argparse's usage error), nothing half-done: cases from the hostile-user review."""
from __future__ import annotations

import pytest

from orchestrator.cli import main, parse_seeds
from orchestrator.scenario import SCENARIO_DIR


def _one_line_error(capsys, argv, *fragments):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    for f in fragments:
        assert f in err, err
    return err


def test_T_not_a_whole_number_of_steps(capsys, tmp_path):
    _one_line_error(capsys, ["run", "--T", "0.055", "--h", "0.01", "--out", str(tmp_path)],
                    "T = 0.055", "is not a whole number of steps h = 0.01 s (5.5 steps)",
                    "stop at 0.06 s")          # round(5.5) = 6 steps
    assert not any(tmp_path.iterdir())


def test_a_scenario_file_that_is_not_a_multiple(capsys, tmp_path):
    text = (SCENARIO_DIR / "paper.toml").read_text().replace("T = 300.0", "T = 300.005")
    (tmp_path / "odd.toml").write_text(text)
    _one_line_error(capsys, ["run", "--scenario", str(tmp_path / "odd.toml"), "--out",
                             str(tmp_path / "o")],
                    "[simulation] T = 300.005", "not a whole number of steps")


@pytest.mark.parametrize("text, fragment", [
    ("1,1,1", "seed(s) 1 given more than once"),
    ("0-3,2", "seed(s) 2 given more than once"),
    ("2147483648", "from 0 to 2^31 - 1"),
    ("0-200000", "too many"),
])
def test_seed_lists_refused(text, fragment):
    import argparse
    with pytest.raises(argparse.ArgumentTypeError, match=fragment.replace("(", r"\(")
                       .replace(")", r"\)").replace("^", r"\^")):
        parse_seeds(text)


def test_a_seed_above_the_fmi_integer_range(capsys, tmp_path):
    with pytest.raises(SystemExit) as exc:
        main(["run", "--seed", str(2**31), "--out", str(tmp_path)])
    assert exc.value.code == 2
    assert "from 0 to 2^31 - 1" in capsys.readouterr().err
    text = (SCENARIO_DIR / "paper.toml").read_text().replace("seed = 0", f"seed = {2**31}")
    (tmp_path / "s.toml").write_text(text)
    _one_line_error(capsys, ["build", "--no-crosscheck", "--scenario", str(tmp_path / "s.toml"),
                             "--out", str(tmp_path / "f")],
                    f"[simulation] seed = {2**31} must be a non-negative integer below 2^31")
    assert not (tmp_path / "f").exists()


def test_binary_garbage_and_a_folder_as_scenario(capsys, tmp_path):
    (tmp_path / "garbage.toml").write_bytes(bytes(range(256)) * 4)
    _one_line_error(capsys, ["run", "--scenario", str(tmp_path / "garbage.toml")],
                    "garbage.toml: not a text file")
    (tmp_path / "dir.toml").mkdir()
    _one_line_error(capsys, ["run", "--scenario", str(tmp_path / "dir.toml")],
                    "dir.toml is a folder")


def test_out_that_is_a_file_or_under_a_file(capsys, tmp_path):
    f = tmp_path / "a_file"
    f.write_text("keep me")
    _one_line_error(capsys, ["run", "--T", "1", "--quiet", "--out", str(f)],
                    "auv-cosim run: error: output folder", str(f), "is a file")
    _one_line_error(capsys, ["run", "--T", "1", "--quiet", "--out", str(f / "sub")],
                    "auv-cosim run: error: output folder", "is under a file")
    assert f.read_text() == "keep me"


@pytest.mark.parametrize("argv, fragments", [
    (["--T", "1e12"], ["T = 1e+12 s with h = 0.01 s is 1e+14 steps", "GB on disk",
                       "shorten T, lengthen h, record fewer samples (--record-hz) or fewer "
                       "outputs (--record)"]),
    (["--h", "1e-300"], ["[simulation] h: step h = 1e-300 s is too small for this model"]),
    (["--T", "1e9", "--h", "1e-6"], ["T = 1e+09 s with h = 1e-06 s is 1e+15 steps"]),
    (["--T", "1e-299", "--h", "1e-300"], ["step h = 1e-300 s is too small for this model",
                                          "use h >= "]),
])
def test_steps_beyond_memory_or_resolution_blame_T_and_h(capsys, tmp_path, argv, fragments):
    err = _one_line_error(capsys, ["run", *argv, "--quiet", "--out", str(tmp_path / "o")],
                          *fragments)
    assert "detectab" not in err
    assert not (tmp_path / "o").exists()


def test_the_memory_estimate_is_a_chunk_and_the_disk_holds_the_recording():
    from orchestrator.running import check_memory
    from orchestrator.running.statistics import chunk_steps
    from orchestrator.scenario import load_scenario
    sc = load_scenario("paper")
    one = check_memory(sc, 1, available=10**15, disk=10**15)
    chunk = min(chunk_steps(20), sc.steps)
    assert one == 8 * 4 * chunk * 20                    # 20 outputs per step, 4 copies
    long = sc.with_run(T=1e6)                           # a longer run keeps no more
    assert check_memory(long, 3, available=10**15, disk=10**15) == one
    with pytest.raises(Exception, match=r"a chunk of 16384 steps \(20 values per step\) "
                                        r"needs about 0.0105 GB, more than the 0.01 GB"):
        check_memory(long, 1, available=10**7, disk=10**15)
    with pytest.raises(Exception, match="its recording .* needs about 192 GB on disk, "
                                        "more than the 1 GB free"):
        check_memory(long, 3, available=10**15, disk=10**9)


def test_validate_refuses_what_is_not_an_fmu(capsys, tmp_path):
    (tmp_path / "x.fmu").write_text("not a zip archive")
    _one_line_error(capsys, ["validate", str(tmp_path / "x.fmu")],
                    "not an FMU (an FMU is a zip archive)", "x.fmu")
    _one_line_error(capsys, ["validate", str(tmp_path / "missing.fmu")],
                    "FMU file(s) not found", "missing.fmu")


def test_an_internal_bug_says_so_and_where_the_traceback_is(capsys, tmp_path, monkeypatch):
    """Fault injection: a function of ours raising an unexpected exception (a bug, not bad
    input) ends in one line that says so and names a log file holding the traceback."""
    import orchestrator.running as wf

    def broken(*a, **k):
        raise ZeroDivisionError("division by zero in a place it should not happen")

    monkeypatch.setattr(wf, "simulate", broken)
    monkeypatch.setenv("AUV_COSIM_CACHE", str(tmp_path / "cache" / "fmus"))
    err = _one_line_error(capsys, ["run", "--T", "1", "--quiet", "--out", str(tmp_path / "o")],
                          "internal error (a bug in auv-cosim, not in your input)",
                          "ZeroDivisionError: division by zero", "traceback in ")
    log = err.split("traceback in ")[1].split(";")[0]
    assert log.startswith(str(tmp_path / "cache" / "logs"))
    text = open(log).read()
    assert "Traceback (most recent call last)" in text and "in broken" in text


def test_an_architecture_on_a_stacked_fleet_is_refused(capsys, tmp_path):
    """--architecture chooses between the per-vehicle laws: on a stacked run it would be
    ignored (the stacked law ran, summary architecture null), so it is refused and
    nothing is written."""
    out = tmp_path / "o"
    _one_line_error(capsys, ["run", "--scenario", "formation-4", "--architecture",
                             "distributed", "--T", "1", "--out", str(out)],
                    "--architecture distributed", "runs 'stacked'",
                    "add --deployment per-vehicle")
    assert not out.exists()


def test_a_huge_seed_range_is_refused_before_it_is_made():
    """0-2000000000 is refused by its size, without building a list of two billion seeds
    (which ended in a MemoryError)."""
    import argparse
    with pytest.raises(argparse.ArgumentTypeError, match="2000000001 seeds is too many"):
        parse_seeds("0-2000000000")
    assert len(parse_seeds("0-99999")) == 100_000


@pytest.mark.parametrize("modes", [("--native", "--phases"), ("--tools", "--campaign"),
                                   ("--remus", "--fleet", "4")])
def test_two_bench_modes_are_refused(capsys, modes):
    """bench's modes are one mutually exclusive group: two of them is a usage error."""
    with pytest.raises(SystemExit) as exit_:
        main(["bench", *modes])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "not allowed with argument" in err and modes[0].lstrip("-") in err
