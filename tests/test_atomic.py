"""Outputs appear whole or not at all (orchestrator/atomic.py), and the writers use it."""
from __future__ import annotations

import pytest

from orchestrator.atomic import copy_atomically, temporary_sibling, write_text_atomically
from orchestrator.recording import write_rrd
from support.recording import H, make_runs


def test_a_failed_write_leaves_the_old_file_and_no_part(tmp_path):
    target = tmp_path / "summary.json"
    write_text_atomically(target, "old")
    with pytest.raises(RuntimeError, match="cut"):
        with temporary_sibling(target) as tmp:
            tmp.write_text("half of the new")
            raise RuntimeError("cut")
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["summary.json"]


def test_a_completed_write_replaces(tmp_path):
    src, dst = tmp_path / "a", tmp_path / "sub" / "b"
    src.write_bytes(b"\x00" * 1000)
    copy_atomically(src, dst)
    assert dst.read_bytes() == src.read_bytes()
    assert sorted(p.name for p in dst.parent.iterdir()) == ["b"]


def test_write_rrd_leaves_only_the_final_file(tmp_path):
    info = write_rrd(tmp_path / "x.rrd", make_runs(), H, recording_name="atomic")
    assert [p.name for p in tmp_path.iterdir()] == ["x.rrd"]
    assert info["bytes"] == (tmp_path / "x.rrd").stat().st_size


def test_a_written_file_has_the_usual_permissions(tmp_path):
    """mkstemp's 0600 is not kept: the file is 0666 minus the umask, like open() makes it."""
    import os

    from orchestrator.atomic import write_text_atomically
    old = os.umask(0o022)
    try:
        write_text_atomically(tmp_path / "a.json", "{}")
        (tmp_path / "b.json").write_text("{}")
    finally:
        os.umask(old)
    mode = (tmp_path / "a.json").stat().st_mode & 0o777
    assert mode == (tmp_path / "b.json").stat().st_mode & 0o777 == 0o644
