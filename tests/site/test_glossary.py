"""docs/glossary.md and its place in every page's navigation (compare/site/glossary.py, fast tier):
every framework and every variant a backend declares is defined there, every link of the glossary
reaches an existing file and heading, and every page of a built site (HTML and Markdown) links it:
relative to docs/ for a site in the repository, a copy beside the pages for one elsewhere."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

import backends
from compare.site import glossary, pages_why

from test_site import built_site, markdown_problems, page_problems, parse

TEXT = glossary.SOURCE.read_text(encoding="utf-8")
LINK = re.compile(r"\]\((?!https?://)([^)\s#]*)(?:#([^)\s]*))?\)")


def defined() -> set[str]:
    """The names the glossary defines: each entry's bold head (``- **name** ...``)."""
    return set(re.findall(r"^- \*\*([^*]+)\*\*", TEXT, re.M))


def test_every_framework_and_every_variant_a_backend_declares_is_defined():
    names = defined()
    assert set(backends.BACKENDS) <= names, set(backends.BACKENDS) - names
    for name, b in backends.BACKENDS.items():
        declared = {*b.variants, *b.comparison_variants, *(v for vs in b.scenario_variants.values() for v in vs)}
        assert declared <= names, f"{name}: {declared - names} not in docs/glossary.md"
    # the method's words the pages use without defining them (issue 58 item 2)
    assert {"sitting", "separated", "tie", "hand adjoint `✎`", "adstack", "noisy `~`", "floor", "port",
            "throughput regime", "latency regime", "graph replay", "process", "interval", "oracle",
            "derived bound", "run", "static", "per_step"} <= names


def headings(md: Path) -> set[str]:
    return {pages_why.slug(re.sub(r"[`*]", "", h)) for h in re.findall(r"^#+ (.+)$", md.read_text(encoding="utf-8"), re.M)}


def test_every_link_of_the_glossary_reaches_a_file_and_its_heading():
    links = LINK.findall(TEXT)
    assert len(links) > 20
    for path, anchor in links:
        target = (glossary.SOURCE.parent / path) if path else glossary.SOURCE
        assert target.is_file(), path
        if anchor:
            assert anchor in headings(target), f"{path}#{anchor}: no such heading"


def test_a_site_in_the_repository_links_docs_and_one_elsewhere_gets_a_copy(tmp_path: Path):
    report = glossary.REPO_DOCS / "results" / "h100" / "report"
    assert glossary.href(report) == "../../../glossary.md"
    assert (report / glossary.href(report)).resolve() == glossary.SOURCE.resolve()
    assert glossary.place(report, tmp_path) == [] and not (tmp_path / glossary.NAME).exists()
    assert glossary.href(tmp_path / "site") == glossary.NAME
    assert glossary.place(tmp_path / "site", tmp_path) == [tmp_path / glossary.NAME]
    copy = (tmp_path / glossary.NAME).read_text(encoding="utf-8")
    assert "(`docs/measurement.md#two-regimes` in the repository)" in copy
    assert markdown_problems(tmp_path / glossary.NAME) == []       # no link left to a missing file
    assert "](#variants)" in copy                                  # its own anchors kept


@pytest.mark.xdist_group("site")       # test_site.built_site: one build, on the worker of its group
def test_every_page_of_a_built_site_links_the_glossary(tmp_path_factory: pytest.TempPathFactory):
    site = built_site(tmp_path_factory)
    assert (site / glossary.NAME).is_file()
    html = sorted(site.rglob("*.html"))
    md = [p for p in sorted(site.rglob("*.md")) if p.name not in ("matrix.md", glossary.NAME)]
    assert html and len(md) == len(html)
    for page in html:
        assert glossary.NAME in parse(page).links, f"{page.name}: no link to the glossary"
        assert not page_problems(page)
    for page in md:
        assert f"[{glossary.LABEL}]({glossary.NAME})" in page.read_text(encoding="utf-8").split("\n\n")[1], page.name
