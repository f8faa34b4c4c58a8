"""docs/findings.md's summary table lists every finding on the page (fast tier): each numbered
heading (``## N. ...``) has its row ``| N | ...`` in the table at the top, and no row names a
finding the page does not have."""
from __future__ import annotations

import re
from pathlib import Path

FINDINGS = Path(__file__).resolve().parent.parent / "docs" / "findings.md"


def numbers(text: str) -> tuple[list[int], list[int]]:
    """(the findings' heading numbers, the summary table's row numbers), in page order."""
    heads = [int(n) for n in re.findall(r"^## (\d+)\. ", text, re.M)]
    rows = [int(n) for n in re.findall(r"^\| (\d+) \| ", text, re.M)]
    return heads, rows


def test_the_summary_table_lists_every_finding():
    heads, rows = numbers(FINDINGS.read_text())
    assert heads and heads == list(range(1, len(heads) + 1)), heads
    assert rows == heads, f"summary table rows {rows}, findings {heads}"


def test_the_check_catches_a_missing_row():
    text = FINDINGS.read_text()
    heads, _ = numbers(text)
    dropped = re.sub(rf"^\| {heads[-1]} \| .*\n", "", text, flags=re.M)
    assert numbers(dropped)[1] == heads[:-1]
