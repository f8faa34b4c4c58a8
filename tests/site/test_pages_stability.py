"""The stability page leads with one line per experiment (fast tier), the summary of
compare/stress/page.py (tested in tests/stress/test_stress_page.py), before every experiment's
rows; the site folds those rows under a <details> (compare/site/pages_stability.py), stress.md
keeps them under each heading."""
from __future__ import annotations

import pytest


# ---- the stability page: a summary first, the rows folded ------------------------------------
@pytest.mark.xdist_group("site")
def test_stability_page_leads_with_one_line_per_experiment_and_folds_the_rows(tmp_path_factory):
    import json
    import re

    from test_site import STORE, built_site
    site = built_site(tmp_path_factory)

    from compare.stress.registry import experiments
    rows = json.loads((STORE / "stress.json").read_text())["analysis"]["rows"]
    ran = [e for e in experiments() if any(r["experiment"] == e for r in rows)]
    assert ran, "the committed store has stability rows"
    html = (site / "stability.html").read_text()
    summary = html.index("<h2>Summary</h2>")
    table = html[summary:html.index("</table>", summary)]
    assert [re.sub(r"<[^>]+>", "", c) for c in re.findall(r"<tr><td[^>]*>(.*?)</td>", table)] == ran
    # every experiment's rows under its own heading, folded, after the summary
    assert html.count("<details><summary>") == len(ran)
    for e in ran:
        head = html.index(f'<h2 id="{e}">')
        assert summary < head < html.index("<details><summary>", head)
        assert "<p>From " in html[head:html.index("<details><summary>", head)], e     # the runs it came from
    md = (site / "stability.md").read_text()
    assert md.index("## Summary") < min(md.index(f"## {e}: ") for e in ran)
    assert "<details>" not in md


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
