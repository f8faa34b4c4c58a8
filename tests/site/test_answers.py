"""compare/site/answers.py: README's answers, one line per question, from the rows the reports
derive: the leader or the tie, by how much, how sure (fast tier). That README holds them:
tests/site/test_readme.py."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from compare.results.record import Record
from compare.site import answers, data, fmt, matrix, questions
from compare.site.matrix import Cell, Row

ROOT = Path(__file__).resolve().parents[2]
RULES = {r.key: r for r in questions.RULES}
RUN = {"created": "2026-11-27T00:00:00+00:00", "commit": "abc1234", "dirty": False}


def particles(backend: str, per_call: float, run: dict[str, Any] | None = RUN) -> Record:
    t = {"median_s": per_call, "iqr_s": 0.0, "repeats": 50}
    return Record(scenario="particles", backend=backend, device="cuda", precision="float32", status="ok",
                  params=dict(data.defaults("particles")), run=run,
                  time={**t, "throughput": {**t, "k": 4}, "latency": t})


def row(*recs: Record) -> Row:
    return matrix.evaluate(RULES["particles-small"], data.Machine((), recs, (), None, (), None), fmt.value)


def test_a_separated_leader_names_its_lead_over_the_next_and_the_test_that_separated_them():
    r = row(particles("warp", 10e-6), particles("cupy", 20e-6), particles("jax", 90e-6))
    assert answers.answer(r) == "**warp**, 2× ahead of cupy (under 6 processes, no 95 % interval: past the 1.6× that needs)"


def test_a_tie_names_everyone_in_it_the_spread_why_and_the_next():
    r = row(particles("warp", 10e-6), particles("cupy", 12e-6), particles("jax", 30e-6))
    assert answers.answer(r) == "tie: **warp**, **cupy** (within 1.2×: under 6 processes, no 95 % interval: under 1.6×; next jax 3×)"


def test_intervals_decide_where_every_figure_has_one():
    rule = RULES["latency"]
    cells = {"a": Cell("a", 1.0, status="ok", ratio=1.0, ci=(0.9, 1.1), tied=True),
             "b": Cell("b", 1.3, status="ok", ratio=1.3, ci=(1.2, 1.4))}
    r = Row(rule, "cuda", cells, "a", ("a",), "", "", ("run x",))
    assert answers.answer(r) == "**a**, 1.3× ahead of b (95 % intervals apart)"
    overlap = {**cells, "b": Cell("b", 1.04, status="ok", ratio=1.04, ci=(1.0, 1.1), tied=True)}
    r = Row(rule, "cuda", overlap, "a", ("a", "b"), "", "", ("run x",))
    assert answers.answer(r) == "tie: **a**, **b** (within 1.04×: 95 % intervals overlap)"


def test_a_row_of_several_runs_names_its_leading_figure_but_no_best():
    r = row(particles("warp", 10e-6), particles("cupy", 40e-6, run=None))
    assert r.tied == ()
    assert answers.answer(r) == "warp leads, 4× ahead of cupy, not ranked (not one run)"


def test_gradient_rows_rank_ad_and_name_a_hand_adjoint_that_beats_it():
    rule = RULES["gradients"]
    cells = {"drjit": Cell("drjit", 10.0, status="ok", ratio=1.0, tied=True),
             "jax": Cell("jax", 5.0, status="ok", ratio=2.0),
             "triton": Cell("triton", 25.0, status="ok", ratio=0.4, reference=True)}
    r = Row(rule, "cuda", cells, "drjit", ("drjit",), "", "", ("run x",))
    assert answers.answer(r) == ("AD: **drjit**, 2× ahead of jax (under 6 processes, no 95 % interval: past the 1.6× that needs); "
                                 "hand-written triton 2.5× better")
    behind = {**cells, "triton": Cell("triton", 2.0, status="ok", ratio=5.0, reference=True)}
    assert "hand-written" not in answers.answer(Row(rule, "cuda", behind, "drjit", ("drjit",), "", "", ("run x",)))


def test_the_table_has_a_line_per_question_and_a_column_per_report(tmp_path):
    report = tmp_path / "docs" / "r" / "report"
    report.mkdir(parents=True)
    (report / "site.json").write_text(json.dumps({"inputs": ["tests/data/site"], "title": "t", "against": []}))
    text = answers.table([report], tmp_path / "README.md")
    lines = text.splitlines()
    m = answers.machine_of(report)
    assert lines[0] == f"| job | [{m.name()}](docs/r/report/index.md) |" and lines[1] == "|---|---|"
    from compare.site import pages
    rows, _ = pages.evaluate(m)
    assert [ln.split(" | ")[0].removeprefix("| ") for ln in lines[2:]] == \
        [q.question for q in questions.RULES if q.key in {x.rule.key for x in rows}]
    assert all(f"| {answers.answer(r)} |" in text for r in rows)
