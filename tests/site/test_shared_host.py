"""The CPU on a shared host (compare/site/shared_host.py, ``run --busy N``): busy cells stay out
of every other row, the row's figure is the geometric mean of busy over idle latency, and a large
slowdown is explained from the cores the cell used while idle."""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from typing import Any

import pytest

from compare.results.record import Record
from compare.site import data, fmt, matrix, questions, shared_host
from conftest import ROOT

RUN = {"created": "2026-11-27T00:00:00+00:00", "commit": "abc1234", "dirty": False}
RULE = {r.key: r for r in questions.RULES}["busy"]


def cell(backend: str, scenario: str, latency: float, busy: int | None = 0, own: float = 1.0) -> Record:
    t = {"first_call_s": 1.0, "median_s": latency, "iqr_s": 0.0, "min_s": latency, "repeats": 10,
         "latency": {"median_s": latency, "iqr_s": 0.0, "min_s": latency, "repeats": 10},
         "noise": {"noisy": False, "reasons": [], "cores": 2, "own_cores": own, "others_cores": 1.0 if busy else 0.0}}
    return Record(scenario=scenario, backend=backend, device="cpu", precision="float32", status="ok",
                  time=t, error={"vs_oracle": 0.0, "tolerance": 1.0}, run=RUN,
                  tags={"busy_cores": busy} if busy is not None else None)


def machine(recs: list[Record]) -> data.Machine:
    return data.Machine((), tuple(r for r in recs if not r.tags), (), None, (), None,
                        tuple(r for r in recs if r.tags))    # as data.load splits a store


def test_the_row_is_the_geometric_mean_of_busy_over_idle_and_explains_a_parallel_loop():
    recs = []
    for sc in matrix.IN_ALL:
        recs += [cell("numpy", sc, 1e-3), cell("numpy", sc, 1.2e-3, busy=1),
                 cell("numba", sc, 1e-4, own=1.9), cell("numba", sc, 1e-4 * (75 if sc == "projectile" else 1.5),
                                                         busy=1, own=1.0)]
    m = machine(recs)
    row = matrix.evaluate(RULE, m, fmt.value)
    assert row.cells["numpy"].value == pytest.approx(1.2)
    want = math.exp((3 * math.log(1.5) + math.log(75)) / 4)
    assert row.cells["numba"].value == pytest.approx(want) and row.best == "numpy"
    [(idle, busy)] = [p for p in shared_host.pairs(m) if p[0].backend == "numba" and p[0].scenario == "projectile"]
    assert "waits for its slowest thread" in shared_host.why(idle, busy)
    assert shared_host.why(*[p for p in shared_host.pairs(m) if p[0].backend == "numpy"][0]) == ""


def test_the_experiment_stays_out_of_every_other_row():
    recs = ([cell("numpy", sc, 1e-3, busy=None) for sc in matrix.IN_ALL]
            + [cell("numpy", sc, 5e-3) for sc in matrix.IN_ALL] + [cell("numpy", sc, 9e-3, busy=1) for sc in matrix.IN_ALL])
    m = machine(recs)
    assert all(not r.tags for r in m.records) and len(m.busy) == 2 * len(matrix.IN_ALL)
    lat = data.timing(matrix.all_defaults(m, "cpu")[0], "latency")
    assert lat.median == 1e-3


@pytest.mark.alone
def test_run_busy_times_each_cpu_cell_again_with_a_core_taken(tmp_path):
    out = tmp_path / "r"
    p = subprocess.run([sys.executable, "-m", "compare", "run", "saxpy", "--backends", "numpy", "--devices", "cpu",
                        "--precision", "float32", "--quick", "--repeat", "3", "--min-time", "0", "--busy", "1",
                        "--out", str(out), "--no-plots"], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr[-2000:]
    recs: list[dict[str, Any]] = json.loads((out / "results.json").read_text())["records"]
    busy = [r for r in recs if (r.get("tags") or {}).get("busy_cores") == 1]
    idle = [r for r in recs if (r.get("tags") or {}).get("busy_cores") == 0]
    assert len(recs) == 2
    assert len(busy) == len(idle) == 1 and busy[0]["status"] == idle[0]["status"] == "ok"
    if os.path.exists("/proc/stat"):       # the other process's core shows in the host meter
        assert busy[0]["time"]["noise"]["others_cores"] > 0.5
