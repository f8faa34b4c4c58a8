"""compare/site/harness.py: what the clock itself costs, one row per timed record (fast tier)."""
from __future__ import annotations

from compare.results.record import Record
from compare.site.harness import harness_table


def rec(backend, variant="default", status="ok", **time) -> Record:
    t = {"median_s": 10e-6, "iqr_s": 0.0, "repeats": 100, "latency": {"median_s": 10e-6, "iqr_s": 0.0, "repeats": 100}}
    return Record(scenario="saxpy", backend=backend, device="cuda", precision="float32", status=status,
                  variant=variant, time={**t, **time})


def test_one_row_per_ok_record_without_graph_variants_sorted():
    table = harness_table([rec("warp"), rec("cupy"), rec("jax", status="error"), rec("cupy", "graph")])
    assert [r[:2] for r in table.rows] == [("cupy", "default"), ("warp", "default")]
    assert len(table.headers) == len(table.rows[0]) == 11


def test_null_call_events_and_own_timer():
    r = rec("warp", null={"median_s": 2e-6, "iqr_s": 0.0}, events={"median_s": 5e-6, "iqr_s": 0.0},
            own_timer={"tool": "wp.ScopedTimer", "median_s": 8e-6, "ours_s": 9e-6, "rounds": 5, "block": 10,
                       "ours_call_s": 11e-6})
    row = dict(zip(harness_table([r]).headers, harness_table([r]).rows[0]))
    assert row["latency (ours)"] == "10 µs" and row["null call"] == "2 µs" and row["device events"] == "5 µs"
    assert row["own timer"] == "8 µs" and row["own timer's tool"] == "wp.ScopedTimer"
    assert row["ours, its statistic"] == "9 µs" and row["ours / own"] == "1.12"        # 9 / 8
    assert row["alternated"] == "5 rounds, blocks of 10" and row["ours per call, same stretches"] == "11 µs"


def test_without_an_own_timer_the_columns_say_so():
    row = harness_table([rec("numpy", own_timer={"failed": "no timer"})]).rows[0]
    assert row[5:10] == ("-", "no timer", "-", "-", "-")
    # a recorded ratio wins over ours / theirs; without ours_s the latency regime stands in
    row = harness_table([rec("jax", own_timer={"tool": "t", "median_s": 5e-6, "ratio": 3.0})]).rows[0]
    assert row[7:10] == ("10 µs", "3.00", "once")
