"""FMUs unzipped once per content (orchestrator/cosim/unpacked.py) and the master's use of
them (orchestrator/cosim/instance.py Extracted): the same file gives the same whole folder,
a changed file a new one, concurrent processes agree, old folders are pruned, and a cache
path pythonfmu cannot read falls back to a temporary folder that is removed."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest

from orchestrator.cosim.instance import Extracted, FmuInstance
from orchestrator.cosim.unpacked import UNPACKED_MAX_AGE_S, unpacked_fmu


def _names(fmu: Path) -> set[str]:
    with zipfile.ZipFile(fmu) as z:
        return {n for n in z.namelist() if not n.endswith("/")}


def test_one_folder_per_content_holding_every_file(paper_fmus, tmp_path):
    fmu = paper_fmus["controller"]
    a = unpacked_fmu(fmu, tmp_path / "u")
    b = unpacked_fmu(fmu, tmp_path / "u")
    assert a == b and a.parent == tmp_path / "u"
    got = {str(p.relative_to(a)) for p in a.rglob("*") if p.is_file()}
    assert got == _names(fmu)
    copy = tmp_path / "copy" / fmu.name                   # same bytes elsewhere: same folder
    copy.parent.mkdir()
    shutil.copy(fmu, copy)
    assert unpacked_fmu(copy, tmp_path / "u") == a
    changed = tmp_path / "changed" / fmu.name             # one byte more: a new folder
    changed.parent.mkdir()
    with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(changed, "w") as dst:
        for item in src.infolist():
            data = src.read(item)
            dst.writestr(item, data + b"\n" if item.filename == "modelDescription.xml" else data)
    c = unpacked_fmu(changed, tmp_path / "u")
    assert c != a and (c / "modelDescription.xml").read_bytes().endswith(b"\n")
    assert not list((tmp_path / "u").glob(".unzip-*"))    # no private folder left


def test_concurrent_processes_get_one_whole_folder(paper_fmus, tmp_path):
    fmu = paper_fmus["estimator"]
    code = ("import sys; from pathlib import Path; "
            "from orchestrator.cosim.unpacked import unpacked_fmu; "
            "print(unpacked_fmu(Path(sys.argv[1]), Path(sys.argv[2])))")
    procs = [subprocess.Popen([sys.executable, "-c", code, str(fmu), str(tmp_path / "u")],
                              stdout=subprocess.PIPE, text=True,
                              cwd=Path(__file__).parents[1]) for _ in range(4)]
    outs = {p.communicate(timeout=120)[0].strip() for p in procs}
    assert all(p.returncode == 0 for p in procs)
    assert len(outs) == 1
    folder = Path(outs.pop())
    assert {str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file()} == _names(fmu)
    assert [p.name for p in (tmp_path / "u").iterdir()] == [folder.name]


def test_folders_unused_for_the_age_limit_are_pruned(paper_fmus, tmp_path):
    root = tmp_path / "u"
    old = unpacked_fmu(paper_fmus["controller"], root)
    past = time.time() - UNPACKED_MAX_AGE_S - 60
    os.utime(old, (past, past))
    (root / ".trash-cut-short").mkdir()                     # a deletion cut short earlier
    os.utime(root / ".trash-cut-short", (past, past))
    new = unpacked_fmu(paper_fmus["plant"], root)          # making a folder prunes
    assert new.exists() and not old.exists()
    assert sorted(p.name for p in root.iterdir()) == [new.name]   # renamed, then deleted
    again = unpacked_fmu(paper_fmus["controller"], root)   # and it comes back when needed
    assert again == old and (again / "modelDescription.xml").exists()
    # using a folder touches it: it is not pruned while in use
    os.utime(new, (past, past))
    unpacked_fmu(paper_fmus["plant"], root)
    assert time.time() - new.stat().st_mtime < 60


def test_the_master_uses_the_cache_or_a_temporary_folder_it_removes(paper_fmus, tmp_path,
                                                                     monkeypatch):
    ex = Extracted(paper_fmus)
    assert ex.root is None                                   # the cache's unpacked/ folders
    assert all("/unpacked/" in d for d in ex.dirs.values())
    inst = FmuInstance("controller", paper_fmus["controller"], ex.dirs["controller"], "c1")
    inst.close()
    ex.cleanup()
    assert all(Path(d, "modelDescription.xml").exists() for d in ex.dirs.values())
    # a cache whose path pythonfmu 0.7 cannot read ('+'): unzipped into a temporary folder
    monkeypatch.setenv("AUV_COSIM_CACHE", str(tmp_path / "c+c"))
    ex = Extracted(paper_fmus)
    assert ex.root is not None and all(d.startswith(str(ex.root)) for d in ex.dirs.values())
    inst = FmuInstance("controller", paper_fmus["controller"], ex.dirs["controller"], "c2")
    inst.close()
    ex.cleanup()
    assert not ex.root.exists() and not (tmp_path / "c+c").exists()


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler (cc) for native FMUs")
def test_a_native_run_twice_copies_the_same_fmus_and_unzips_nothing_new(tmp_path):
    """The native FMUs of one design are kept whole in the cache: a second run gets the
    same bytes (no new unpacked folder per run)."""
    from orchestrator.cli import main
    from orchestrator.cosim.build import fmu_cache_dir
    got = []
    for k in range(2):
        out = tmp_path / f"run{k}"
        assert main(["run", "--T", "0.2", "--quiet", "--fmus", "native", "--out", str(out)]) == 0
        got.append({p.name: p.read_bytes() for p in (out / "fmus" / "native").glob("*.fmu")})
        if k == 0:
            before = _unpacked_of(fmu_cache_dir(), got[0])
    assert len(got[0]) == 3 and got[0] == got[1]
    kept = {p.read_bytes() for p in (fmu_cache_dir() / "native").glob("*Native-*.fmu")}
    assert set(got[0].values()) <= kept                  # copied from the cache, not zipped
    assert before and _unpacked_of(fmu_cache_dir(), got[0]) == before


def _unpacked_of(cache: Path, fmus: dict[str, bytes]) -> set[Path]:
    """The unpacked folders of these FMUs (named by their file stem) in the cache; other
    xdist workers unpack other FMUs there meanwhile."""
    stems = {Path(name).stem for name in fmus}
    return {p for p in (cache / "unpacked").iterdir() if p.name.rsplit("-", 1)[0] in stems}
