"""The committed reports are generated, current and embedded in README unchanged; README answers first.

Each docs/results/<machine>/report is rebuilt from its store beside the committed one (at the same
depth, so relative links to docs/ are the same) and every page, table and figure's data must match
byte for byte; pictures must be the same set (PNG bytes depend on the installed font renderer).
README's matrices must equal the reports' matrix.md tables, and its answers the rows derived from
the reports' stores (``python -m compare.site.readme`` rewrites both). README opens with what the
project is and which framework for which job, before its two commands; no sentence over 40 words.
"""
from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

import pytest

from compare.site import readme

ROOT = Path(__file__).resolve().parents[2]
REPORTS = sorted(p.parent for p in (ROOT / "docs" / "results").glob("*/report/site.json"))


def files(d: Path) -> set[str]:
    return {str(p.relative_to(d)) for p in d.rglob("*") if p.is_file()}


def test_committed_reports_exist() -> None:
    assert {p.parent.name for p in REPORTS} >= {"h100", "cpu", "h200x2-scaleout"}


def test_readme_pictures_are_generated_by_the_reports() -> None:
    """Every picture README shows of a report (its overview) is a file the site build writes."""
    import re
    from compare.site import assemble
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    shown = re.findall(r"!\[[^\]]*\]\((docs/results/[^)]+/report/[^)]+\.png)\)", text)
    assert shown, "README shows no report picture"
    for rel in shown:
        path = ROOT / rel
        assert path.is_file(), rel
        assert path.name == assemble.OVERVIEW or path.parent.name == "figures", rel


def test_readme_matrices_are_the_generated_ones() -> None:
    machines = [f"docs/results/{m}/report" for m in ("h100", "h200", "cpu", "xeon")]
    assert set(readme.blocks()) >= {"docs/results/h100/report/matrix.md", "docs/results/cpu/report/matrix.md",
                                    " ".join([readme.ANSWERS, *machines])}
    assert readme.expected() == (ROOT / "README.md").read_text(encoding="utf-8"), \
        "README's answers or matrices differ from the reports: run python -m compare.site.readme"


def test_a_block_of_a_file_is_its_table_and_its_footnote_links_point_into_the_file(tmp_path) -> None:
    rep = tmp_path / "docs" / "results" / "m" / "report"
    rep.mkdir(parents=True)
    (rep / "matrix.md").write_text("| q | a |\n|---|---|\n| [Q](per-call.md) | 30×<sup>[1](#why-m-1)</sup> |\n\n"
                                   "Ratios above 20× and why:\n\n1. <a id=\"why-m-1\"></a>a 30×: eager.\n")
    (tmp_path / "README.md").write_text("# t\n<!-- BEGIN generated: docs/results/m/report/matrix.md -->\n"
                                        "<!-- END generated -->\nafter\n")
    assert readme.expected(tmp_path / "README.md") == (
        "# t\n<!-- BEGIN generated: docs/results/m/report/matrix.md -->\n| q | a |\n|---|---|\n"
        "| [Q](docs/results/m/report/per-call.md) | 30×<sup>[1](docs/results/m/report/matrix.md#why-m-1)</sup> |\n"
        "<!-- END generated -->\nafter\n")


def sentences(markdown: str) -> list[str]:
    """README's sentences: prose split at . ! ? and paragraph breaks, each table cell and list
    item apart; code blocks, HTML comments and link targets are no words."""
    text = re.sub(r"```.*?```", "", markdown, flags=re.S)
    text = re.sub(r"<!--.*?-->", "", text)
    text = re.sub(r"\]\([^)]*\)", "]", text)
    units: list[str] = []
    for para in re.split(r"\n\s*\n", text):
        lines = [ln for ln in para.splitlines() if ln.strip()]
        if lines and all(ln.lstrip().startswith("|") for ln in lines):
            units += [c for ln in lines for c in ln.split("|")]
        else:
            units += re.split(r"\n(?=\s*[-*] |\s*\d+\. |#)", "\n".join(lines))
    return [s.strip() for u in units for s in re.split(r"(?<=[.!?])\s+", u.replace("\n", " ")) if s.strip()]


def test_sentences_are_cut_at_stops_cells_and_items() -> None:
    assert sentences("One two. Three\nfour!\n\n| a b | c |\n|---|---|\n\n- x y\n- z [l](http://a.b/c d)\n```\nno words here\n```") \
        == ["One two.", "Three four!", "a b", "c", "---", "---", "- x y", "- z [l]"]


def test_readme_answers_first_in_short_sentences_then_its_two_commands() -> None:
    """The issue-58 landing page: what the project is (two sentences), which framework for which
    job (the generated answers), then the two commands; under 120 lines, no sentence over 40 words."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) < 120
    long = [s for s in sentences(text) if len(s.split()) > 40]
    assert not long, f"README sentences over 40 words: {long}"
    intro = text.split("\n## ")[0].split("\n\n", 1)[1]
    assert len(sentences(intro)) == 2, intro
    run = "python3 -m venv .venv && . .venv/bin/activate && pip install -e . && python -m compare all"
    test = 'python3 -m venv .venv && . .venv/bin/activate && pip install -e ".[test]" && python -m pytest'
    answers_at = text.index(f"<!-- BEGIN generated: {readme.ANSWERS} ")
    assert answers_at < text.index(f"```bash\n{run}\n```") < text.index(f"```bash\n{test}\n```")
    assert text.index("## Which framework for which job") < answers_at
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")     # CI runs README's test command
    assert 'pip install -q -e ".[test]"' in ci and re.search(r"^tier +#", ci, re.M)


@pytest.mark.slow
@pytest.mark.parametrize("committed", REPORTS, ids=[p.parent.name for p in REPORTS])
def test_committed_report_rebuilds_identically(committed: Path) -> None:
    from compare.site import readme
    fresh = committed.parent / f".rebuild-{os.getpid()}"
    try:
        readme.rebuild(committed / "site.json", fresh)
        assert files(fresh) == files(committed), "pages or figures added or missing: rebuild the report"
        for name in sorted(files(committed)):
            if not name.endswith(".png"):
                assert (fresh / name).read_bytes() == (committed / name).read_bytes(), \
                    f"{committed / name} differs from its store: rebuild it as {committed / 'site.json'} says"
    finally:
        shutil.rmtree(fresh, ignore_errors=True)


def test_readme_and_install_links_reach_their_files_and_every_report_and_doc() -> None:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    for doc in (ROOT / "README.md", ROOT / "docs" / "install.md"):
        for target in re.findall(r"\]\((?!https?://|#)([^)#\s]+)", doc.read_text(encoding="utf-8")):
            assert (doc.parent / target).exists(), f"{doc.name}: {target}"
    linked = set(re.findall(r"\]\(([^)#\s]+)", text))
    assert {f"docs/results/{m}/report/index.md" for m in ("h100", "cpu", "xeon")} <= linked
    assert {f"docs/{p.name}" for p in (ROOT / "docs").glob("*.md") if p.name != "ports.md"} <= linked
