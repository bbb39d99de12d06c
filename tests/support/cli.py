"""The CLI seen from the tests: a refusal is exit status 2 and one line on stderr."""
from __future__ import annotations

from typing import Any


def assert_one_line_error(capsys: Any, argv: list[str], *fragments: str) -> None:
    """``auv-cosim argv`` exits with 2 and writes one line containing every fragment."""
    from orchestrator.cli import main
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    for f in fragments:
        assert f in err, err
