"""Where a cell's time goes (compare.measuring.phases): every worker record splits its life into parts."""
from __future__ import annotations

import time

from compare.running import cells
from compare.spec import Cell
from compare.measuring import phases
from compare.results.record_parts import Timing


def test_a_cells_parts_are_named_positive_and_within_its_wall_time():
    spec = {"scenario": "saxpy", "backend": "numpy", "device": "cpu", "precision": "float32",
            "params": {"n": 4096}, "quick": True, "repeat": 3, "min_time": 0.0, "throughput": True}
    t0 = time.perf_counter()
    record, _ = cells.run(Cell.from_dict(spec), timeout=300)
    wall = time.perf_counter() - t0
    assert record["status"] == "ok", record.get("reason")
    parts = record["time"]["phases"]
    for part in ("start", "inputs", "framework", "build", "first_call", "steady", "throughput", "download",
                 "check", "record"):
        assert part in parts, part
    assert set(parts) <= set(phases.CELL_PARTS)
    assert all(v >= 0 for v in parts.values())
    assert parts["start"] > 0.01                  # an interpreter and numpy cannot start in 10 ms
    assert sum(parts.values()) <= wall            # the driver's clock holds every part


def test_a_later_cell_of_a_shared_worker_has_no_process_start():
    laps = phases.Laps(0.0)
    laps.lap("inputs")
    assert "start" not in laps.spent and laps.spent["inputs"] >= 0


def test_summary_line_shares_add_up_to_the_cells_time():
    line = phases.summary_line({"probes": 1.0, "yardstick": 2.0, "cells": 10.0, "tables and pictures": 0.5},
                               {"start": 2.0, "first_call": 3.0, "steady": 2.5, "throughput": 1.5}, 4)
    assert line.startswith("time: 4 cells in 13.5 s (probes 1 s, yardstick 2 s, cells 10 s")
    assert "40 % is measurement" in line           # steady + throughput of 10 s
    assert "compile and first call 30 %" in line and "process start and imports 20 %" in line
    assert "driver and exits 10 %" in line


def test_records_parts_are_summed():
    times = [Timing.of(phases={"start": 1.0, "steady": 2.0}), None, Timing.of(phases={"steady": 0.5})]
    assert phases.cell_parts(times) == {"start": 1.0, "steady": 2.5}


def test_summary_line_of_an_overlapped_run_shares_the_workers_time():
    line = phases.summary_line({"cells": 10.0}, {"start": 4.0, "wait": 6.0, "first_call": 3.0, "steady": 5.0}, 4)
    assert "the workers' 12 s overlapped into the cells' 10 s, 50 % of them measurement" in line
    assert "warm-up and latency 42 %" in line and "waiting" not in line
