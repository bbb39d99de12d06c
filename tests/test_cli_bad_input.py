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
