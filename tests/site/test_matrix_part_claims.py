"""docs/measurement.md's figures for the H100's publish parts with every cut (session 41's matrix
part, the error sweep of sessions 35 and 42), held to their publish logs, publish.json and records
(issue 57, items 4 and 5). Fast tier."""
from __future__ import annotations

import json
import re

import pytest

from measurement_doc import RESULTS, doc_text, said

pytestmark = pytest.mark.xdist_group("measurement-claims")

EVIDENCE = RESULTS / "h100" / "evidence"


@pytest.fixture(scope="module")
def doc() -> str:
    return doc_text()


def error_sweep_records() -> list[dict]:
    """The H100 error sweep's records as sessions 35, 41 and 42 stored them: evidence/error-partial
    and the six that session 45 left out of it (the old compiled particle port's long rollouts)."""
    files = (EVIDENCE / "error-partial" / "sweep.json", EVIDENCE / "session45" / "error-partial-left-out.json")
    return [r for f in files for r in json.loads(f.read_text())["records"]]


def rounds(session: str, log: str = "publish.log", machine: str = "h100") -> list[tuple[int, int, int]]:
    """(process, cells, seconds) of each repeat round its publish log names."""
    text = (RESULTS / machine / "evidence" / session / log).read_text()
    return [(int(p), int(c), int(s)) for p, c, s in re.findall(r"process (\d+): (\d+) cells in (\d+) s", text)]


def part_seconds(started: str) -> float:
    log = json.loads((RESULTS / "h100" / "publish.json").read_text())
    (part,) = [p for p in log["parts"] if p["name"] == "all" and p["started"].startswith(started)]
    assert part["exit_code"] == 0 and not part["interrupted"]
    return float(part["seconds"])


def test_session_41s_row_of_the_matrix_part_table(doc: str) -> None:
    day, first, c2, c3, cold_n, k4, k5, k6, kept_n, total, minutes = said(
        doc, r"\| session 41, ([\d-]+), `--sitting 1500`, 85 cells, every cut \(\[evidence\]\(results/h100/evidence/"
             r"session41/README.md\)\) \| about (\d+) s \| (\d+) s, (\d+) s \((\d+) cells\) \| (\d+) s, (\d+) s, (\d+) s "
             r"\((\d+) cells\) \| (\d+) s \(\*\*([\d.]+) min\*\*\) \|")
    seconds = part_seconds(f"{day}T13:25")
    got = rounds("session41")
    assert [p for p, _, _ in got] == [2, 3, 4, 5, 6]         # six processes, the sitting rule stopped a seventh
    assert [(c, s) for _, c, s in got] == [(int(cold_n), int(c2)), (int(cold_n), int(c3)), (int(kept_n), int(k4)),
                                         (int(kept_n), int(k5)), (int(kept_n), int(k6))]
    assert (total, minutes) == (f"{seconds:.0f}", f"{seconds / 60:.1f}")
    assert first == f"{round((seconds - sum(s for _, _, s in got)) / 10) * 10:.0f}"
    assert said(doc, r"85 cells with every cut below in session 41: ([\d.]+) minutes") == (minutes,)


def test_session_41s_rounds_against_session_39s(doc: str) -> None:
    new, old = rounds("session41"), rounds("session39")
    got = said(doc, r"its cold rounds took (\d+) and (\d+) s over (\d+) cells, against (\d+) and (\d+) s over (\d+) \(the two\s+"
                    r"cuts are not separable in one run\), and its kept rounds (\d+)-(\d+) s over (\d+) cells; the whole part\s+"
                    r"(\d+) s, ([\d.]+) minutes, for six processes")
    kept = [s for p, _, s in new if p > 3]
    seconds = part_seconds("2026-12-07T13:25")
    assert got == (str(new[0][2]), str(new[1][2]), str(new[0][1]), str(old[0][2]), str(old[1][2]), str(old[0][1]),
                   str(min(kept)), str(max(kept)), str(new[2][1]), f"{seconds:.0f}", f"{seconds / 60:.1f}")
    (per_kept,) = said(doc, r"was low on the kept rounds: about ([\d.]+) s a kept cell")
    assert per_kept == f"{sum(kept) / sum(c for p, c, _ in new if p > 3):.1f}"
    cold, kept26 = said(doc, r"from\s+session 39's ([\d.]+) s a cold cell and session 26's ([\d.]+) s a kept one")
    s26 = [(c, s) for p, c, s in rounds("session26", "log-m") if p > 3]
    assert (cold, kept26) == (f"{old[0][2] / old[0][1]:.1f}", f"{sum(s for _, s in s26) / sum(c for c, _ in s26):.1f}")


def test_the_error_sweeps_pace_one_cell_at_a_time(doc: str) -> None:
    """Why the sweeps' set-ups overlap: the unfinished H100 error sweep's first run (its part's
    seconds, its timed cells' windows) and the cells its plan has left (evidence/error-partial)."""
    import argparse

    from compare.planning import publish_plan
    from compare.suites import sweep
    folder = EVIDENCE / "error-partial"
    records = error_sweep_records()
    stored = json.loads((folder / "sweep.json").read_text())["records"]
    (first, *_) = [p for p in json.loads((folder / "publish.json").read_text())["parts"] if p["name"] == "error"]
    mine = [r for r in records if r["run"]["created"][:10] == first["started"][:10] and r["status"] == "ok"]
    windows = sum(r["time"]["window"][1] - r["time"]["window"][0] for r in mine)
    got = said(doc, r"cut off by its lease\s+at (\d+) s in session 35, timed (\d+) cells whose windows took (\d+) s of it, "
                    r"([\d.]+) s a cell against ([\d.]+) s\s+of window")
    seconds = float(first["seconds"])
    assert got == (f"{seconds:.0f}", str(len(mine)), f"{windows:.0f}", f"{seconds / len(mine):.1f}",
                   f"{windows / len(mine):.1f}")
    parser = argparse.ArgumentParser()
    sweep.add_arguments(parser)
    planned = sweep.plan(parser.parse_args(["error", "--devices", "cuda", "--backends", "all"]))
    parts = [p for p in json.loads((folder / "publish.json").read_text())["parts"] if p["name"] == "error"]
    s42 = parts[-1]
    before = [r for r in records if r["run"]["created"] < s42["started"]]
    left, alone, beside = said(doc, r"the (\d+) cells it had left after session 41 would take about (\d+) minutes one at a time, "
                                    r"more than a\s+lease leaves after its wheels and sitting check; with the set-ups beside the "
                                    r"windows, about the\s+windows' (\d+)")
    assert int(left) == len(planned) - len(before)
    assert (alone, beside) == (f"{int(left) * seconds / len(mine) / 60:.0f}", f"{int(left) * windows / len(mine) / 60:.0f}")
    # session 42: the last error part, overlapped, cut off by the lease's end
    ran = [r for r in records if r["run"]["created"] >= s42["started"]]
    assert all(r["status"] == "ok" for r in ran) and s42["exit_code"] is None
    spans = [r["time"]["window"] for r in ran]
    covered = sum(b - a for a, b in spans)
    torch = [r for r in ran if r["backend"] == "torch"]
    compiled = [r["time"]["first_call_s"] for r in torch if r["scenario"] == "particles" and r["variant"].startswith("compile")]
    got = said(doc, r"Session 42 ran (\d+) of them so and was cut off in turn\*\* \((\d+) s,[^)]*\)\): the set-ups hid beside "
                    r"the\s+windows, which covered (\d+) s of it, but its cells' windows were ([\d.]+) s each, not ([\d.]+)\. "
                    r"They were the\s+plan's heavier cells: torch's (\d+) took (\d+) s, its compiled particle rollouts "
                    r"compiling inside their\s+windows for up to (\d+) s a point, longer as the steps grow \(.*?\)\. "
                    r"(\d+) cells are left \((\d+), and six of those rollouts left out since\)")
    assert got == (str(len(ran)), f"{float(s42['seconds']):.0f}", f"{covered:.0f}", f"{covered / len(ran):.1f}",
                   f"{windows / len(mine):.1f}", str(len(torch)),
                   f"{sum(r['time']['window'][1] - r['time']['window'][0] for r in torch):.0f}", f"{max(compiled):.0f}",
                   str(len(planned) - len(stored)), str(len(planned) - len(records)))
    # the windows one at a time: the part's seconds are theirs and small gaps
    assert max(b for _, b in spans) - min(a for a, _ in spans) - covered < 0.05 * covered
    assert "SETUPS" in said(doc, r"one process a cell, `publish_plan\.(\w+)`") and publish_plan.SETUPS[0] == "--overlap"


def test_mlxs_first_calls_in_the_scaling_sweep(doc: str) -> None:
    """'MLX's first calls in the H100 store's scaling sweep took 20-111 s a point, its projectile's
    54-111 s': why a curve's points share their caches (compare/suites/family_caches.py)."""
    from measurement_doc import span
    records = json.loads((RESULTS / "h100" / "sweep.json").read_text())["records"]
    mine = [r for r in records if r["backend"] == "mlx" and r["tags"].get("sweep") == "scaling" and r["status"] == "ok"]
    first = {s: [r["time"]["first_call_s"] for r in mine if r["scenario"] == s] for s in ("particles", "projectile")}
    got = said(doc, r"MLX's first calls in the H100 store's scaling sweep took ([\d-]+) s a point,\s+its projectile's ([\d-]+) s")
    assert got == (span(first["particles"] + first["projectile"]), span(first["projectile"]))


def test_kept_caches_serve_mlxs_later_points(doc: str) -> None:
    """'MLX's float32 particles took 23.5 s at a curve's first point and 0.07-0.26 s at the
    others, its projectile 35.9 s and then 3.2-7.2 s': session 42's error-sweep records."""
    from measurement_doc import span
    records = json.loads((EVIDENCE / "error-partial" / "sweep.json").read_text())["records"]
    mine = [r for r in records if r["run"]["commit"].startswith("2711403") and r["backend"] == "mlx"
            and r["precision"] == "float32"]
    got = said(doc, r"MLX's float32\s+particles took ([\d.]+) s at a curve's first point and ([\d.-]+) s at the others, "
                    r"its projectile\s+([\d.]+) s and then ([\d.-]+) s")
    want: list[str] = []
    for scenario in ("particles", "projectile"):
        rows = [r["time"] for r in mine if r["scenario"] == scenario]
        (cold,) = [t["first_call_s"] for t in rows if t["cache"].startswith("cold:")]
        kept = [t["first_call_s"] for t in rows if t["cache"].startswith("kept:")]
        assert len(kept) == 5
        want += [f"{cold:.1f}", span(kept, "{:.2f}" if scenario == "particles" else "{:.1f}")]
    assert got == tuple(want)


def test_the_own_timer_in_the_error_sweeps_windows(doc: str) -> None:
    """'never in a sweep's cells (... when it took 342 s of the H100 error sweep's 1541 s of
    windows, Triton's 4.1 s a cell)': session 42's error-sweep records, their phases."""
    records = error_sweep_records()
    mine = [r["time"] for r in records if r["run"]["commit"].startswith("2711403")]
    triton = [r["time"]["phases"].get("own_timer", 0.0) for r in records
              if r["run"]["commit"].startswith("2711403") and r["backend"] == "triton"]
    got = said(doc, r"when it took (\d+) s of the H100 error sweep's (\d+) s of windows, Triton's ([\d.]+) s a cell\)")
    assert got == (f"{sum(t['phases'].get('own_timer', 0.0) for t in mine):.0f}",
                   f"{sum(t['window'][1] - t['window'][0] for t in mine):.0f}", f"{sum(triton) / len(triton):.1f}")


def test_the_h200s_matrix_part_as_its_log_says(doc: str) -> None:
    """Session 43's H200 lease: the rounds its publish log names, the part cut off after four
    processes (publish.json: no exit code), and the six-process projection from them."""
    got = rounds("session43", machine="h200")
    assert [p for p, _, _ in got] == [2, 3, 4]
    first, c2, c3, cold_n, k4, kept_n, total, minutes = said(
        doc, r"round 1 about (\d+) s, its cold rounds (\d+) and (\d+) s over (\d+) cells, its\s+first kept round "
             r"(\d+) s over (\d+); the lease ended there, after four processes\. At that pace six\s+processes take "
             r"about (\d+) s \(([\d.]+) minutes\)")
    assert [(c, s) for _, c, s in got] == [(int(cold_n), int(c2)), (int(cold_n), int(c3)), (int(kept_n), int(k4))]
    (part,) = json.loads((RESULTS / "h200" / "publish.json").read_text())["parts"]
    assert part["name"] == "all" and part["exit_code"] is None
    six = int(first) + int(c2) + int(c3) + 3 * int(k4)        # rounds 4-6 at the first kept round's pace
    assert (total, minutes) == (f"{round(six / 50) * 50}", f"{round(six / 60 * 2) / 2:.1f}")
    assert int(first) + sum(s for _, _, s in got) <= part["seconds"]


def test_the_h200s_first_processes_against_session_41s(doc: str) -> None:
    """The H200's slower round 1 is host work: each cell's set-up + first call (its first process)
    over session 41's H100 run's, the median cell and each framework's sum."""
    import statistics

    def firsts(store: str, created: str | None) -> dict[tuple[str, ...], float]:
        recs = json.loads((RESULTS / store / "results.json").read_text())["records"]
        return {(r["scenario"], r["backend"], r["variant"], json.dumps(r["params"], sort_keys=True)):
                r["time"]["setup_s"] + r["time"]["first_call_s"] for r in recs
                if r["status"] == "ok" and (created is None or r["run"]["created"] == created)}
    h100, h200 = firsts("h100", "2026-12-07T13:26:02+00:00"), firsts("h200", None)
    common = sorted(set(h100) & set(h200))
    assert len(common) == 85
    median, lo, hi = said(doc, r"took ([\d.]+)× session 41's in the\s+median cell, every framework ([\d.]+)-([\d.]+)×")
    assert median == f"{statistics.median(h200[k] / h100[k] for k in common):.2f}"
    per = {b: sum(h200[k] for k in common if k[1] == b) / sum(h100[k] for k in common if k[1] == b)
           for b in {k[1] for k in common}}
    assert (lo, hi) == (f"{min(per.values()):.2f}", f"{max(per.values()):.2f}")
