"""A ratio above 20x carries its reason on the row's page, read from the records (fast tier):
the slow port's loop, its launches per call, eager execution, a host busy for the whole call,
a first call that compiles for seconds, and the leader's own structure beside it
(compare/site/pages_why.py). A cell within 20x, or a reference cell, carries none."""
from __future__ import annotations

from typing import Any

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
                      params=dict(data.defaults(scenario)), info={"compiled": compiled} if compiled else {},
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
