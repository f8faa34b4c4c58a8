"""compare/sweep/page.py: the sweep's page from stored sweep files (moved here from
tests/suites/test_sweep.py). Named test_sweep_page: pytest collects test files by basename, and
compare/stress/ has a page module too."""
from __future__ import annotations

import pytest

from compare.results.store import Store
from compare.suites import sweep
from compare.sweep import page as sweep_page
from conftest import ROOT


@pytest.mark.parametrize("published,device,old_format", [
    ("docs/results/cpu/sweep.json", "cpu", None),    # today's format
    ("tests/data/format1-sweep.json", "cuda", 1)])   # a format-1 file, upgraded on reading
def test_published_sweep_file_still_renders(tmp_path, published, device, old_format):
    store = Store.read(ROOT / published, "sweep")
    assert store.upgraded_from == old_format
    data = sweep.contents(store)
    assert all(r.tags is not None for r in data.records)
    text = sweep_page.page(data, {}, tmp_path / "page.md", "t", ["sweep.json"])
    for heading in (f"## {device}: launch overhead", f"## {device}: copy bandwidth (roofline)",
                    f"## {device}: SAXPY bandwidth against size", "### projectile",
                    f"## {device}: particles scaling"):
        assert heading in text
    assert "| 2^24 " in text and "| particle-steps/s " in text and "No data." not in text
    assert "Roofline for this device" in text
