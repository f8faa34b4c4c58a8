"""A ratio above 20x carries its reason on the row's page, read from the records (fast tier):
the slow port's loop, its launches per call, eager execution, a host busy for the whole call,
a first call that compiles for seconds, and the leader's own structure beside it
(compare/site/pages_why.py). A cell within 20x, or a reference cell, carries none."""
from __future__ import annotations

from typing import Any

import pytest

from compare.results.record import Record
from compare.site import data, fmt, matrix, pages, pages_why, questions, questions_pages
from compare.site.render import Items

RULES = {r.key: r for r in questions.RULES}
RUN = {"created": "2026-11-27T00:00:00+00:00", "commit": "abc1234", "dirty": False}
PARTICLES = data.defaults("particles")


def particles(backend: str, per_call: float, info: dict[str, Any], host_share: float | None = None) -> Record:
    thr = {"median_s": per_call, "iqr_s": 0.0, "repeats": 5, "k": 4,
           "host_s": None if host_share is None else host_share * per_call}
    return Record(scenario="particles", backend=backend, device="cuda", precision="float32", status="ok",
                  params=dict(PARTICLES), info=info, run=RUN,
                  time={"median_s": per_call, "iqr_s": 0.0, "repeats": 50, "throughput": thr,
                        "latency": {"median_s": per_call, "iqr_s": 0.0, "repeats": 50}})


def explained(key: str, recs: list[Record]) -> matrix.Row:
    m = data.Machine((), tuple(recs), (), None, (), None)
    return pages_why.explain(matrix.evaluate(RULES[key], m, fmt.value), m)


def test_a_far_cell_names_its_launches_loop_and_host_share_and_the_leaders_launches():
    steps = PARTICLES["steps"]
    row = explained("particles-small", [
        particles("triton", 10e-6, {"launches_per_run": 1}),
        particles("torch", 3e-3, {"execution": "eager", "loop": "host loop over steps", "kernels_per_step": 19},
                  host_share=0.99),
        particles("jax", 50e-6, {"loop": "lax.fori_loop"})])
    why = row.cells["torch"].why
    assert "loop: host loop over steps" in why and "execution: eager" in why
    assert f"19 kernel launches per step × {steps} steps = {19 * steps:,} per call" in why
    assert "host-bound: issuing a call takes 99 % of its time" in why
    assert why.endswith("(leader triton: 1 launch per call)")
    assert row.cells["jax"].why == "" and row.cells["triton"].why == ""       # 5x and the leader
    blocks = questions_pages.verdicts([row])
    items = next(b for b in blocks if isinstance(b, Items))
    assert items.texts == (f"**torch 300×**: {why}.",)


def test_a_far_cell_without_facts_in_its_record_says_nothing_rather_than_guess():
    row = explained("particles-small", [particles("triton", 10e-6, {}), particles("torch", 3e-3, {})])
    assert row.cells["torch"].ratio == 300 and row.cells["torch"].why == ""
    assert not [b for b in questions_pages.verdicts([row]) if isinstance(b, Items)]


def test_the_first_call_row_names_the_first_calls_and_the_largest():
    def rec(backend: str, scenario: str, first: float, compiled: str = "") -> Record:
        return Record(scenario=scenario, backend=backend, device="cuda", precision="float32", status="ok",
                      params=dict(data.defaults(scenario)),
                      info={"compiled": compiled} if compiled else {"fast_math": False},
                      run=RUN, time={"first_call_s": first, "setup_s": 0.01, "median_s": 1e-3, "iqr_s": 0.0,
                                     "repeats": 10})
    recs = [rec("drjit", sc, 0.02) for sc in matrix.IN_ALL] + \
        [rec("mlx", sc, 20.0 if sc == "particles" else 1.0, "mx.compile") for sc in matrix.IN_ALL]
    row = explained("compile", recs)
    why = row.cells["mlx"].why
    n = len(matrix.IN_ALL)
    assert why.startswith(f"first calls (compile or trace, and the call) {fmt.seconds(20.0 + n - 1)}, "
                          "the largest 20 s (particles)")
    assert "compiled with mx.compile" in why and "(leader drjit: first calls" in why


def test_the_overview_evaluation_gives_the_reasons():
    m = data.Machine((), (particles("triton", 10e-6, {"launches_per_run": 1}),
                          particles("torch", 3e-3, {"kernels_per_step": 2})), (), None, (), None)
    rows, _ = pages.evaluate(m)
    small = next(r for r in rows if r.rule.key == "particles-small")
    assert "2 kernel launches per step" in small.cells["torch"].why


# ---- the matrix's footnotes: each far ratio marked where it stands, its reason under the matrix ----
def test_a_far_cell_carries_a_footnote_mark_and_its_reason_under_the_matrix():
    row = explained("particles-small", [
        particles("triton", 10e-6, {"launches_per_run": 1}),
        particles("torch", 3e-3, {"execution": "eager", "kernels_per_step": 19}),
        particles("mlx", 1e-3, {}),                        # far, but its record says nothing
        particles("jax", 50e-6, {"loop": "lax.fori_loop"})])
    fws = ["triton", "jax", "torch", "mlx"]
    md = pages.matrix_md([row], fws, key="h100")
    table, notes = md.split("\n\n", 1)
    assert "🟥 300×<sup>[1](#why-h100-1)</sup>" in table and "🟥 100×<sup>[2](#why-h100-2)</sup>" in table
    assert table.count("<sup>") == 2                      # the 5x cell and the leader: no mark
    lines = notes.splitlines()
    assert lines[0] == pages_why.HEAD and len(lines) == 3             # one line per row
    assert lines[2] == ('- [Particle loop, small n](particles.md#particle-loop-small-n): '
                        f'<a id="why-h100-1"></a>**1** torch 300×: {row.cells["torch"].why}. '
                        f'<a id="why-h100-2"></a>**2** mlx 100×: {pages_why.NO_REASON}.')
    assert "say nothing of how the port ran" in pages_why.NO_REASON and "the row's page" in pages_why.NO_REASON
    html = pages.matrix_html([row], fws, "h100")
    assert '300×<sup><a href="#why-h100-1">1</a></sup>' in html
    assert '<li><a href="particles.html#particles-small">Particle loop, small n</a>: <span id="why-h100-1">' \
           '<strong>1</strong> torch 300×: ' in html
    assert "#why-1)" in pages.matrix_md([row], fws)       # no machine key: plain ids


def test_reference_cells_and_rows_within_twenty_times_carry_no_footnote():
    row = explained("particles-small", [particles("triton", 10e-6, {}), particles("torch", 150e-6, {})])
    assert pages_why.notes([row], ["triton", "torch"]) == []
    assert "<sup>" not in pages.matrix_md([row], ["triton", "torch"]) and "\n\n" not in pages.matrix_md([row], ["triton"])


@pytest.mark.xdist_group("site")       # test_site.built_site: one build, on the worker of its group
def test_no_page_promises_a_tooltip_and_the_footnotes_reach_their_rows(tmp_path_factory):
    import re

    from test_site import built_site
    site = built_site(tmp_path_factory)
    assert "tooltip" not in pages.legend().markdown and "row's page" in pages.legend().markdown
    for page in [*site.rglob("*.md"), *site.rglob("*.html")]:
        assert "tooltip" not in page.read_text(encoding="utf-8").lower(), page.name
    index = (site / "index.md").read_text(encoding="utf-8")
    marks = re.findall(r"<sup>\[(\d+)\]\(#(why-[\w-]+)\)</sup>", index)
    assert marks, "the test store has ratios above 20x"
    for n, anchor in marks:
        assert f'<a id="{anchor}"></a>**{n}** ' in index
    links = re.findall(r'^- \[[^\]]+\]\((\w[\w-]*\.md)#([\w-]+)\): <a id="why-', index, re.M)
    assert links
    for page, heading in links:
        titles = re.findall(r"^## (.+)$", (site / page).read_text(encoding="utf-8"), re.M)
        assert heading in {pages_why.slug(t) for t in titles}, (page, heading)
    html = (site / "index.html").read_text(encoding="utf-8")
    keys = re.findall(r'<li><a href="(\w[\w-]*\.html)#([\w-]+)">[^<]*</a>: <span id="why-', html)
    assert len(keys) == len(links)
    for page, key in keys:
        assert f'id="{key}"' in (site / page).read_text(encoding="utf-8"), (page, key)
