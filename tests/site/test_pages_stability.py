"""The stability pages (compare/site/pages_stability.py, compare/site/stability_outcomes.py): the
page opens with its answer and the framework x experiment table, then one line per experiment
(the summary of compare/stress/page.py, tested in tests/stress/test_stress_page.py); each
experiment's figure and rows on its own page, every report page at most 300 lines. Built from the
site's test store and from the committed H100 store (its figures not drawn: fast tier)."""
from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from compare.site import stability_outcomes as so

ROOT = Path(__file__).resolve().parents[2]
H100 = ROOT / "docs" / "results" / "h100"
MAX_LINES = 300


def pages_of(store: Path, tmp: Path, monkeypatch) -> dict[str, str]:
    """stem -> Markdown of the stability page and its experiment pages, built from ``store``."""
    from compare.site import data
    from compare.site import questions_pages as qp
    from compare.site.pages_stability import stability
    from compare.site.render import page_md
    from compare.stress import plots
    from compare.suites import formats
    formats.register()
    monkeypatch.setattr(plots, "draw", lambda exp, series, path: Path(path).write_bytes(b"png"))
    c = qp.Ctx(data.load([store]), [], tmp, "STORE")
    out = {"stability": page_md("Stability", [], stability(c))}
    out |= {stem: page_md(title, [], blocks) for stem, (title, blocks) in c.subpages.items()}
    return out


# one xdist worker: the H100's pages, built once (seconds) for every test of the module, not once per worker
pytestmark = pytest.mark.xdist_group("pages-stability")


@pytest.fixture(scope="module")
def h100(tmp_path_factory) -> dict[str, str]:
    mp = pytest.MonkeyPatch()
    try:
        return pages_of(H100, tmp_path_factory.mktemp("h100"), mp)
    finally:
        mp.undo()


def stored_rows(store: Path = H100) -> list[dict]:
    return json.loads((store / "stress.json").read_text())["analysis"]["rows"]


def test_the_page_opens_with_its_answer_and_the_framework_by_experiment_table(h100):
    md = h100["stability"]
    lines = md.splitlines()
    assert lines[4].startswith("**") and ("Fails alone" in lines[4] or "No framework fails" in lines[4])
    table = md.index("## Each framework in each experiment")
    assert table < md.index("## Summary") and table < 40 * 80      # on the first screen: nothing above but the answer
    exps = sorted({r["experiment"] for r in stored_rows()})
    for e in exps:            # one page per experiment, linked from the table's head and cells
        assert f"[{e}](stability-{e}.md)" in md and f"stability-{e}" in h100
    got = so.outcomes(stored_rows())
    for fw in so.frameworks(stored_rows()):
        row = next(line for line in lines if line.startswith(f"| {fw} |"))
        for e in exps:
            o = got.get((fw, e))
            assert (o is None and "| - |" in row) or (o is not None and f"[{so.cell_text(o)}](stability-{e}.md)" in row)


def test_no_stability_page_is_longer_than_a_screenful_of_detail(h100):
    for stem, md in h100.items():
        assert len(md.splitlines()) <= MAX_LINES, stem


def test_a_caught_race_never_reads_as_zero_differing_elements_detected(h100):
    """A racy control is caught by two runs that differ or by both runs outside the oracle's bound
    (an earlier H100 sitting: 0 elements differing, both runs wrong alike; session 34's: 32 differ,
    and both outside the bound). Where a page shows 0 differing elements beside RACE DETECTED, it
    says which evidence caught it (the zero case itself: tests/stress/test_generic.py)."""
    rows = [r for r in stored_rows() if so.control(r) and str(r["verdict"]).startswith("RACE DETECTED")]
    assert rows, "the H100 store has a caught racy control"
    for r in rows:
        assert "outside the oracle's bound" in r["verdict"] or r["value"] > 0
    shown = "\n".join(h100.values())
    assert "= 0 (RACE DETECTED (outside the oracle's bound))" not in shown
    for line in shown.splitlines():
        if "RACE DETECTED" in line and re.search(r"(= 0 \(| \| 0 \| )RACE DETECTED", line):
            assert "the two runs agree bitwise" in line, line
    # a caught control is the detector working: its framework passes that experiment
    assert so.outcomes(stored_rows())[("warp", "races")].kind == so.PASS


@pytest.mark.xdist_group("site")
def test_the_built_site_has_every_experiment_page_and_none_longer_than_300_lines(tmp_path_factory):
    from test_site import STORE, built_site
    site = built_site(tmp_path_factory)
    for e in {r["experiment"] for r in stored_rows(STORE)}:
        assert (site / f"stability-{e}.html").is_file() and (site / f"stability-{e}.md").is_file()
        assert f'href="stability-{e}.html"' in (site / "stability.html").read_text()
    for md in site.glob("*.md"):
        assert len(md.read_text().splitlines()) <= MAX_LINES, md.name


def test_an_experiment_names_each_run_its_rows_come_from_with_commit_and_tree_state():
    from compare.site.pages_stability import made_by
    assert made_by([]) == "Its run is not recorded."
    new = {"created": "2026-11-28T01:01:03+00:00", "git_commit": "a" * 40, "git_dirty": False, "backends": ["warp"]}
    assert made_by([new]) == "From run 2026-11-28 01:01 UTC, commit aaaaaaa."
    old = {"created": "2026-11-21T21:42:30", "git_commit": "4bdffc9", "backends": ["jax", "numba"]}
    dirty = {**new, "git_dirty": True}
    assert made_by([{**old, "created": "2026-11-21 (session 1, H100)"}]).startswith("From run 2026-11-21 (session 1, H100), ")
    assert made_by([old, dirty]) == ("From 2 runs: run 2026-11-21 21:42 UTC, commit 4bdffc9 (tree state unknown): jax, "
                                     "numba; run 2026-11-28 01:01 UTC, commit aaaaaaa (dirty tree): warp.")
