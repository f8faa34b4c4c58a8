"""The stability page leads with one line per experiment (fast tier): how many cases it measured,
how many it skipped, how many verdicts flag a problem (CAPITALS, docs/stress.md) and its worst
row (compare/stress/page.py), before every experiment's rows; the site folds those rows under a
<details> (compare/site/pages_stability.py), stress.md keeps them under each heading."""
from __future__ import annotations

from typing import Any

import pytest

from compare.stress import page
from compare.stress.numerics import Experiment


def row(exp: str, verdict: str, value: Any, figure: str = "gradient rel. error vs float64",
        backend: str = "warp") -> dict[str, Any]:
    return {"experiment": exp, "backend": backend, "device": "cuda", "precision": "float32",
            "setting": "s", "figure": figure, "value": value, "verdict": verdict, "detail": ""}


@pytest.mark.parametrize("verdict, flag", [
    ("EXCEEDS derived bound", True), ("RACE DETECTED (outside the oracle's bound)", True),
    ("within derived bound at every horizon; float32 gradient OFF BY 62% at steps=720", True),
    ("race not observable on CPU", False), ("GD locally stable iff lr < 0.05", False),
    ("unstable, reported: Inf/NaN from step 12", False), ("within derived bound", False)])
def test_capitals_flag_a_verdict_and_names_do_not(verdict: str, flag: bool):
    assert page.flagged(verdict) is flag


REG = {"a": Experiment("a", "first", lambda ctx: ([], {})), "b": Experiment("b", "second", lambda ctx: ([], {})),
       "c": Experiment("c", "never ran", lambda ctx: ([], {}))}


def test_one_summary_line_per_experiment_with_its_worst_row():
    rows = [row("a", "within derived bound", 0.9, backend="jax"),
            row("a", "EXCEEDS derived bound", 1.5, backend="torch"),
            row("a", "EXCEEDS derived bound", 3.0, backend="mlx"),
            row("a", "skipped", None, figure="-"),
            row("b", "within derived bound", 0.2), row("b", "within derived bound", 0.7, backend="cupy")]
    lines = page.summary(rows, REG)
    assert [ln[:5] for ln in lines] == [("a", "first", "3", "1", "2"), ("b", "second", "2", "0", "0")]
    assert lines[0][5].startswith("mlx cuda float32 s: gradient rel. error vs float64 = 3 (EXCEEDS")
    assert lines[1][5].startswith("cupy ")         # nothing flagged: the largest error of all


def test_a_figure_without_a_worse_direction_gives_the_first_flagged_row_or_none():
    first = "first step with a non-finite state"
    rows = [row("a", "LOSS JUMPS", 7, figure=first, backend="jax"), row("a", "LOSS JUMPS", 9, figure=first),
            row("b", "unstable, reported", 3, figure=first)]
    lines = page.summary(rows, REG)
    assert lines[0][5].startswith("jax ") and lines[1][5] == "-"


def test_stress_md_leads_with_the_summary(tmp_path):
    rows = [row("a", "EXCEEDS derived bound", 3.0), row("b", "within derived bound", 0.2)]
    md = page.markdown({"environment": {}, "rows": rows, "_out": str(tmp_path)}, REG)
    assert md.index("## Summary") < md.index("| a ") < md.index("## a: first")


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
    md = (site / "stability.md").read_text()
    assert md.index("## Summary") < min(md.index(f"## {e}: ") for e in ran)
    assert "<details>" not in md
