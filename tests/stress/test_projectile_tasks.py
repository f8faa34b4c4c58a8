"""compare/stress/projectile_tasks.py: the typed host-loop task, its JSON for the worker, and
the outcome decoded from the worker's answer."""
from __future__ import annotations

import json
import math

from compare.stress import projectile_tasks as T
from compare.stress.numerics import ORACLE

OPT = T.Task("optimise", "numba", "cpu", "float32", ("none", "hard"), 60.0, lrs=(0.01, 0.2),
             methods=("clip", "adam"), iters=5)


def test_a_task_round_trips_through_the_json_the_worker_reads():
    sent = OPT.to_json()
    assert sent["call"] == "compare.stress.projectile_tasks:run_task"
    assert T.Task.from_json(json.loads(json.dumps(sent))) == OPT        # lists back to tuples


def test_work_items_per_contact_optimiser_and_lr_or_per_scan():
    items = T.work_items(OPT)
    assert len(items) == 2 * 2 * 2 and all(it.evals == 6 for it in items)
    assert items[0] == T.Item("none", 6, method="clip", lr=0.01)
    scan = T.Task("scan", "numba", "cpu", "float32", ("soft",), 60.0, scans={"a": [1.0, 2.0, 3.0]})
    assert T.work_items(scan) == [T.Item("soft", 3, scan="a", vy=(1.0, 2.0, 3.0))]


def test_an_outcome_round_trips_through_the_workers_answer():
    oracle = T.Task("optimise", ORACLE, "host", "float64", ("none",), math.inf, lrs=(0.01,), methods=("gd",), iters=3)
    out = T.execute(oracle)
    assert out.why_not is None and [(d.contact, d.method, d.lr) for d in out.descents] == [("none", "gd", 0.01)]
    assert len(out.descents[0].history) == 4
    back = oracle.outcome(json.loads(json.dumps(out.to_json())))
    assert back.descents == out.descents and back.scans == ()


def test_a_task_over_its_budget_is_skipped_with_the_measured_reason():
    over = T.Task("optimise", ORACLE, "host", "float64", ("none",), 0.0, lrs=(0.01,), methods=("gd",), iters=3)
    out = T.execute(over)
    assert out.descents == () and out.error is None
    assert out.why_not == out.skipped and "over this task's budget of 0 s" in out.skipped
    again = over.outcome(out.to_json())
    assert again.skipped == out.skipped and again.error is None


def test_an_answer_that_is_only_an_error_is_the_outcome_error():
    got = OPT.outcome({"error": "task process died (exit 1): boom"})
    assert got.error == "task process died (exit 1): boom" and got.skipped is None
    assert got.why_not == got.error and got.descents == () == got.scans
