"""No report page is longer than 300 lines (issue 58: every page opens with its answer and fits a
screen before the detail): each committed store's site, built into a temporary folder as its
docs/results/<machine>/report/site.json says (slow tier: a build takes about 20 s)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
REPORTS = sorted(p.parent for p in (ROOT / "docs" / "results").glob("*/report/site.json"))
MAX_LINES = 300


@pytest.mark.slow
@pytest.mark.parametrize("committed", REPORTS, ids=[p.parent.name for p in REPORTS])
def test_no_generated_report_page_exceeds_300_lines(committed: Path, tmp_path: Path) -> None:
    from compare import site
    how = json.loads((committed / "site.json").read_text())
    out = tmp_path / "report"
    site.build([ROOT / p for p in how["inputs"]], out, how["title"], [ROOT / p for p in how["against"]])
    long = {md.name: n for md in out.glob("*.md") if (n := len(md.read_text().splitlines())) > MAX_LINES}
    assert not long, f"pages over {MAX_LINES} lines: {long}"
