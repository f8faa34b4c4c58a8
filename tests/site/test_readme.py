"""The committed reports are generated, current and embedded in README unchanged.

Each docs/results/<machine>/report is rebuilt from its store beside the committed one (at the same
depth, so relative links to docs/ are the same) and every page, table and figure's data must match
byte for byte; pictures must be the same set (PNG bytes depend on the installed font renderer).
README's matrices must equal the reports' matrix.md (``python -m compare.site.readme`` rewrites them).
"""
from __future__ import annotations

import os
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
    assert set(readme.blocks()) >= {"docs/results/h100/report/matrix.md", "docs/results/cpu/report/matrix.md"}
    assert readme.expected() == (ROOT / "README.md").read_text(encoding="utf-8"), \
        "README's matrices differ from the reports: run python -m compare.site.readme"


@pytest.mark.slow
@pytest.mark.parametrize("committed", REPORTS, ids=[p.parent.name for p in REPORTS])
def test_committed_report_rebuilds_identically(committed: Path) -> None:
    import json
    from compare import site
    how = json.loads((committed / "site.json").read_text())
    fresh = committed.parent / f".rebuild-{os.getpid()}"
    try:
        site.build([ROOT / p for p in how["inputs"]], fresh, how["title"], [ROOT / p for p in how["against"]])
        assert files(fresh) == files(committed), "pages or figures added or missing: rebuild the report"
        for name in sorted(files(committed)):
            if not name.endswith(".png"):
                assert (fresh / name).read_bytes() == (committed / name).read_bytes(), \
                    f"{committed / name} differs from its store: rebuild it as {committed / 'site.json'} says"
    finally:
        shutil.rmtree(fresh, ignore_errors=True)
