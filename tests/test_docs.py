"""The documentation site builds strictly and offline: every page, link, anchor and API cross-reference resolves."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import previewctl

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The site built by ``mkdocs build --strict``; the build fails the test on any warning."""
    site_dir = tmp_path_factory.mktemp("site")
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    build = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site_dir)],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=600, check=False,
    )
    log = build.stdout + build.stderr
    assert build.returncode == 0 and "WARNING" not in log, log
    return site_dir


def test_every_api_page_is_built(site: Path) -> None:
    pages = sorted(p.stem for p in (ROOT / "docs" / "api").glob("*.md"))
    assert {"index", "control", "errors"} <= set(pages)
    for page in pages:
        built = site / "api" / ("" if page == "index" else page) / "index.html"
        assert built.is_file(), page


def test_restructured_text_habits_render_as_markdown(site: Path) -> None:
    """``:func:`~previewctl.control.factory.make_controller` `` and its kin render as links, never as raw roles, and
    a ``text::`` literal block as a code block."""
    for page in (site / "api").rglob("index.html"):
        text = page.read_text()
        assert not re.search(r":(func|meth|class|mod|attr|data|exc|obj|const):", text), page
        assert not re.search(r"::\s*</p>", text), page
    control = (site / "api" / "control" / "index.html").read_text()
    assert 'href="#previewctl.control.params.CONTROLLER_NAMES"' in control


def test_the_site_requests_nothing_from_the_network(site: Path) -> None:
    for page in site.rglob("*.html"):
        assert "fonts.googleapis.com" not in page.read_text(), page


def test_the_api_overview_links_every_public_name() -> None:
    overview = (ROOT / "docs" / "api" / "index.md").read_text()
    assert set(re.findall(r"\]\[previewctl\.[\w.]+\.(\w+)\]", overview)) == set(previewctl.__all__)


def test_docs_pages_named_in_the_code_exist(site: Path) -> None:
    """A docstring's ``docs/decisions.md#anchor`` names a page and a heading of the built site."""
    named = {
        (match[1], match[2])
        for source in (ROOT / "previewctl").rglob("*.py")
        for match in re.finditer(r"docs/([\w/-]+)\.md(?:#([\w-]+))?", source.read_text())
    }
    assert ("decisions", "mutants-of-the-tracked-peak-on-spatial-arms") in named
    for page, anchor in named:
        built = site / ("" if page == "index" else page) / "index.html"
        assert built.is_file(), page
        assert not anchor or f'id="{anchor}"' in built.read_text(), f"{page}.md#{anchor}"
