"""The CPU on a shared host (compare/site/shared_host.py, ``run --busy N``): busy cells stay out
of every other row; the row ranks the time under load (busy latency against the fastest busy one
per scenario) only from figures repeated across processes (from one process a cell it shows its
ratios and names no best), with the slowdown (busy over idle) beside it on the page, never ranked; a busy figure
faster than its idle one is labelled noise unless the records explain it; a large slowdown is
explained from the cores the cell used while idle."""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from typing import Any

import pytest

from compare.results.record import Record
from compare.running import repeats
from compare.site import answers, data, fmt, matrix, pages, questions, ranking, render, shared_host
from conftest import ROOT

RUN = {"created": "2026-11-27T00:00:00+00:00", "commit": "abc1234", "dirty": False}
RULE = {r.key: r for r in questions.RULES}["busy"]


def cell(backend: str, scenario: str, latency: float, busy: int | None = 0, own: float = 1.0,
         iqr: float = 0.0, ci: tuple[float, float] | None = None) -> Record:
    t: dict[str, Any] = {
        "first_call_s": 1.0, "median_s": latency, "iqr_s": iqr, "min_s": latency, "repeats": 10,
        "latency": {"median_s": latency, "iqr_s": iqr, "min_s": latency, "repeats": 10},
        "noise": {"noisy": False, "reasons": [], "cores": 2, "own_cores": own, "others_cores": 1.0 if busy else 0.0}}
    if ci is not None:      # timed in 6 processes: the median's interval at 95 % (compare.running.repeats)
        t["processes"] = {"count": 6, "latency": {"values": [latency] * 6, "median_s": latency, "ci_lo_s": ci[0],
                                                   "ci_hi_s": ci[1], "confidence": repeats.interval(range(6))[2]}}
    return Record(scenario=scenario, backend=backend, device="cpu", precision="float32", status="ok",
                  time=t, error={"vs_oracle": 0.0, "tolerance": 1.0}, run=RUN,
                  tags={"busy_cores": busy} if busy is not None else None)


def machine(recs: list[Record]) -> data.Machine:
    return data.Machine((), tuple(r for r in recs if not r.tags), (), None, (), None,
                        tuple(r for r in recs if r.tags))    # as data.load splits a store


def page(m: data.Machine) -> str:
    return "\n".join(render.block_md(b) for b in shared_host.section(m))


def rep(t: float) -> tuple[float, float]:
    """A 95 % interval 2 % either side: the cell timed in 6 processes."""
    return 0.98 * t, 1.02 * t


def test_the_row_ranks_time_under_load_not_the_slowdown_which_stands_beside_it():
    """numba is 10x faster idle and loses 3x to the busy core; numpy loses only 10 %: the slowdown
    would name numpy, the time a user waits under load names numba, 3.67x ahead."""
    recs = []
    for sc in matrix.IN_ALL:
        recs += [cell("numpy", sc, 1e-3, ci=rep(1e-3)), cell("numpy", sc, 1.1e-3, busy=1, ci=rep(1.1e-3)),
                 cell("numba", sc, 1e-4, ci=rep(1e-4)), cell("numba", sc, 3e-4, busy=1, ci=rep(3e-4))]
    m = machine(recs)
    row = matrix.evaluate(RULE, m, fmt.value)
    assert row.best == "numba" and row.cells["numba"].value == pytest.approx(1.0)
    assert row.cells["numpy"].ratio == pytest.approx(1.1e-3 / 3e-4)
    assert shared_host.slowdowns(m) == pytest.approx({"numpy": 1.1, "numba": 3.0})
    line = next(x for x in page(m).splitlines() if x.startswith("| numpy |"))
    assert "3.67×" in line and "1.10×" in line          # time under load, the slowdown beside it
    assert "time under load" in RULE.text and "not ranked" in RULE.text


def test_the_figure_is_the_geometric_mean_over_the_scenarios_against_the_fastest_busy_time():
    recs = []
    for sc in matrix.IN_ALL:
        recs += [cell("numpy", sc, 1e-3), cell("numpy", sc, 1.2e-3, busy=1),
                 cell("numba", sc, 1e-4, own=1.9), cell("numba", sc, 1e-4 * (75 if sc == "projectile" else 1.5),
                                                         busy=1, own=1.0)]
    m = machine(recs)
    row = matrix.evaluate(RULE, m, fmt.value)
    # numba fastest busy on three scenarios; on projectile 7.5 ms against numpy's 1.2 ms
    assert row.cells["numba"].value == pytest.approx((7.5e-3 / 1.2e-3) ** 0.25)
    assert row.cells["numpy"].value == pytest.approx((1.2e-3 / 1.5e-4) ** 0.75)
    assert row.cells["numba"].processes == 1 and row.cells["numba"].ci is None
    assert row.best is None and row.top == "numba"       # one process a cell: shown, not ranked
    [(idle, busy)] = [p for p in shared_host.pairs(m) if p[0].backend == "numba" and p[0].scenario == "projectile"]
    assert "waits for its slowest thread" in shared_host.why(idle, busy)
    assert shared_host.why(*[p for p in shared_host.pairs(m) if p[0].backend == "numpy"][0]) == ""
    assert "Not ranked: each figure is from one process per cell" in page(m) and "--busy 1 --processes 6" in page(m)


def test_a_framework_missing_a_scenario_is_not_comparable():
    recs = [cell(fw, sc, 1e-3, busy=b) for fw in ("numpy", "numba") for sc in matrix.IN_ALL for b in (0, 1)]
    m = machine([r for r in recs if not (r.backend == "numba" and r.scenario == matrix.IN_ALL[0])])
    row = matrix.evaluate(RULE, m, fmt.value)
    assert row.cells["numba"].value is None and row.cells["numpy"].value == 1.0


def apart(gap: float, repeated: dict[str, bool]) -> list[Record]:
    """numba and numpy ``gap`` apart idle and busy, each timed in 6 processes where ``repeated`` says."""
    out = []
    for sc in matrix.IN_ALL:
        for fw, t in (("numba", 1e-4), ("numpy", gap * 1e-4)):
            ci = rep(t) if repeated[fw] else None
            out += [cell(fw, sc, t, ci=ci), cell(fw, sc, t, busy=1, ci=ci)]
    return out


def test_from_repeated_processes_intervals_separate_the_row_and_it_names_a_best():
    """1.3x apart from 6 processes with disjoint intervals: separated, as every ranked row is."""
    six = matrix.evaluate(RULE, machine(apart(1.3, {"numba": True, "numpy": True})), fmt.value)
    assert six.best == "numba" and six.tied == ("numba",) and six.best_text() == "numba"
    assert six.cells["numpy"].processes == 6 and six.cells["numba"].band == "best"
    assert six.cells["numpy"].ci == pytest.approx((1.3 * 0.98, 1.3 * 1.02))
    assert ranking.separated(six.cells["numba"], six.cells["numpy"]).kind == ranking.INTERVALS
    assert six.verdict.startswith("Best: numba (1), separated from numpy (1.3×; 95 % intervals apart")
    assert "the row names a best only where every framework's has one" in page(machine(apart(1.3, {
        "numba": True, "numpy": True})))


def test_from_one_process_a_cell_the_row_shows_its_ratios_and_names_no_best():
    """2x apart, past the one-process gap another row would rank at: the busy row names no best
    from one process a cell; its ratios stay, the leader is not coloured, the verdict says why."""
    m = machine(apart(2.0, {"numba": False, "numpy": False}))
    row = matrix.evaluate(RULE, m, fmt.value)
    assert row.best is None and row.tied == () and row.top == "numba"
    assert row.cells["numpy"].ratio == pytest.approx(2.0) and row.cells["numba"].band != "best"
    assert row.best_text() == "— (one process)"
    assert row.verdict == (
        "Not ranked: every figure here is from one process a cell; this row ranks only figures repeated "
        f"across processes, each with a 95 % interval (`{shared_host.REPEAT}`). Ratios are to the leading "
        "figure; no best is named. Leading figure: numba (1).")
    line = pages.matrix_md([row], ["numba", "numpy"]).splitlines()[2]
    assert "**" not in line and line.endswith("| — (one process) |") and "2.00×" in line
    assert answers.answer(row) == "numba leads, 2× ahead of numpy, not ranked (one process)"
    assert "Not ranked: each figure is from one process per cell" in page(m)
    assert "separated" not in page(m)


def test_one_framework_without_an_interval_leaves_the_row_unranked():
    mixed = matrix.evaluate(RULE, machine(apart(2.0, {"numba": True, "numpy": False})), fmt.value)
    assert mixed.best is None and mixed.best_text() == "— (one process)"
    assert mixed.verdict.startswith("Not ranked: numpy: no 95 % interval across processes; this row ranks only")
    def three(r: Record) -> Record:      # 3 processes: their range covers the median at 75 %, no interval
        lat = r.time["processes"]["latency"]
        return r.replace(time={**r.time, "processes": {"count": 3, "latency": {
            **lat, "values": lat["values"][:3], "confidence": repeats.interval(range(3))[2]}}})
    few = [three(r) for r in apart(2.0, {"numba": True, "numpy": True})]
    short = matrix.evaluate(RULE, machine(few), fmt.value)
    assert short.best is None and short.best_text() == "— (under 6 processes)" and short.cells["numpy"].processes == 3
    assert "Not ranked: some figures are from under 6 processes" in page(machine(few))


def test_a_busy_figure_faster_than_idle_is_noise_unless_the_records_explain_it():
    sc = matrix.IN_ALL
    recs = [cell("numpy", s, 1e-3, iqr=0.4e-3) for s in sc] + [cell("numba", s, 1e-3) for s in sc]
    recs += [cell("numpy", s, 0.9e-3, busy=1) for s in sc]          # inside the idle quartiles 0.8-1.2 ms
    recs += [cell("numba", s, 0.5e-3, busy=1) for s in sc]          # idle had no spread: outside
    m = machine(recs)
    got = {(i.backend, i.scenario): shared_host.faster(i, b) for i, b in shared_host.pairs(m)}
    assert got[("numpy", sc[0])] == shared_host.WITHIN == "within the spread of the idle figure"
    assert got[("numba", sc[0])] == shared_host.UNEXPLAINED == "faster under load: unexplained by the records"
    text = page(m)
    numpy_row = next(x for x in text.splitlines() if x.startswith(f"| numpy | {sc[0]} |"))
    assert "1 ms (quartiles 800 µs–1.2 ms)" in numpy_row and "900 µs" in numpy_row and shared_host.WITHIN in numpy_row
    assert shared_host.UNEXPLAINED in next(x for x in text.splitlines() if x.startswith(f"| numba | {sc[0]} |"))
    assert "4 of its 4 cells (below): 4 unexplained by the records" in text
    # an idle cell timed while other processes held the host: its record explains the slow idle figure
    flagged = cell("numba", sc[0], 1e-3)
    flagged = flagged.replace(time={**flagged.time, "noise": {
        "noisy": True, "cores": 2, "own_cores": 1.0, "others_cores": 1.5,
        "reasons": [{"regime": "", "why": "host busy: other processes used 1.50 cores"}]}})
    assert shared_host.faster(flagged, cell("numba", sc[0], 0.5e-3, busy=1)).startswith(
        "faster under load: the idle figure was not idle (host busy")
    assert shared_host.faster(*[p for p in shared_host.pairs(machine(
        [cell("numpy", sc[0], 1e-3), cell("numpy", sc[0], 2e-3, busy=1)]))][0]) == ""


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
