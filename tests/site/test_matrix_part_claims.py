"""docs/measurement.md's figures for session 41's H100 matrix part (the first with every cut), held to
its publish log and the store's publish.json (issue 57, items 4 and 5). Fast tier."""
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


def rounds(session: str, log: str = "publish.log") -> list[tuple[int, int, int]]:
    """(process, cells, seconds) of each repeat round its publish log names."""
    text = (EVIDENCE / session / log).read_text()
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
    records = json.loads((folder / "sweep.json").read_text())["records"]
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
    left, alone, beside = said(doc, r"its other (\d+) cells would take about (\d+) minutes one at a time, more than a lease "
                                    r"leaves after its\s+wheels and sitting check; with the set-ups beside the windows, "
                                    r"about the windows' (\d+)")
    assert int(left) == len(planned) - len(records)
    assert (alone, beside) == (f"{int(left) * seconds / len(mine) / 60:.0f}", f"{int(left) * windows / len(mine) / 60:.0f}")
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
