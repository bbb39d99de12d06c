"""The documentation: every link is a relative path inside the repository, and the pages
build as a site (``mkdocs build --strict``, mkdocs.yml) with the API reference."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
PAGES = sorted(DOCS.glob("*.md"))
API_PACKAGES = ("plant_model", "estimator_fmu", "controller_fmu", "fmu_common", "orchestrator")
LINK = re.compile(r"\]\(([^)\s]+)\)")


def _links(path: Path) -> list[str]:
    text = re.sub(r"```.*?```", "", path.read_text(encoding="utf-8"), flags=re.S)
    return LINK.findall(text)


@pytest.mark.parametrize("path", [ROOT / "README.md", *PAGES], ids=lambda p: p.name)
def test_links_are_relative_paths_inside_the_repository(path):
    for target in _links(path):
        if target.startswith(("http://", "https://", "#")):
            continue
        file = target.split("#", 1)[0]
        assert not file.startswith("/"), f"{path.name}: absolute link {target}"
        resolved = (path.parent / file).resolve()
        assert resolved.is_relative_to(ROOT), f"{path.name}: {target} points outside the repository"
        assert resolved.exists(), f"{path.name}: {target} does not exist"


def test_readme_lists_every_docs_page():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    missing = [p.name for p in PAGES if p.name != "index.md" and f"(docs/{p.name})" not in readme]
    assert not missing, f"README's table of contents lacks {missing}"


@pytest.mark.slow
def test_mkdocs_build_strict(tmp_path):
    site = tmp_path / "site"
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir",
                           str(site)], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-4000:]
    for page in PAGES:
        built = site / "index.html" if page.stem == "index" else site / page.stem / "index.html"
        assert built.is_file(), f"{page.name} is not in the site (mkdocs.yml nav?)"
    for package in API_PACKAGES:
        html = (site / "api" / package / "index.html").read_text(encoding="utf-8")
        # mkdocstrings renders every documented object with its dotted path as the id
        assert f'id="{package}.' in html, f"the API page of {package} documents nothing"
    assert 'id="plant_model.vehicles"' in (site / "api" / "plant_model" / "index.html").read_text(
        encoding="utf-8")
