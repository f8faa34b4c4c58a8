"""docs/measurement.md's "One process is not the sitting" held to the H100 stores (every runs list
under docs/results/h100, each run once, up to session 42's day): why a CUDA sitting check takes
several yardstick processes and what its rule calls noisy (compare/measuring/sitting.py,
compare/running/sitting_run.py). Fast tier."""
from __future__ import annotations

import json
import math
import statistics
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import pytest

from compare.measuring.sitting import FLOOR_RATIO, SLOW_SHARE, rank
from compare.running import sitting_run
from measurement_doc import RESULTS, doc_text, said

pytestmark = pytest.mark.xdist_group("measurement-claims")
UNTIL = "2026-12-07T16"        # the stores as the paragraph read them (session 42)


def stores() -> Iterator[dict[str, Any]]:
    for path in sorted(Path(RESULTS / "h100").rglob("*.json")):
        try:
            obj = json.loads(path.read_text())
        except ValueError:
            continue
        if isinstance(obj, dict) and isinstance(obj.get("runs"), list):
            yield obj


def h100_runs() -> dict[str, Mapping[str, Any]]:
    """Every H100 run with a CUDA yardstick in any store or evidence file, once by its time."""
    out: dict[str, Mapping[str, Any]] = {}
    for obj in stores():
        for run in obj["runs"]:
            hw = ((run.get("hardware") or {}).get("cuda") or {}) if isinstance(run, dict) else {}
            if hw.get("launch_pipelined_s") and str(run.get("created", "")) < UNTIL:
                out.setdefault(run["created"], run)
    return out


def cell_floors() -> dict[str, list[float]]:
    """Each compare run's (not a stress run's) cells' own pipelined floors, each cell once, for
    runs with ten or more."""
    out: dict[str, list[float]] = {}
    seen = set()
    for obj in stores():
        envs = {r.get("created"): r for r in obj["runs"] if isinstance(r, dict)}
        for rec in obj.get("records") or []:
            before = (rec.get("cell_floor") or {}).get("before") or {}
            created = (rec.get("run") or {}).get("created", "")
            if rec.get("device") != "cuda" or not before.get("pipelined_s") or created >= UNTIL \
                    or "overlap" not in envs.get(created, {}):
                continue
            key = (created, rec["scenario"], rec["backend"], rec["precision"], rec["variant"],
                   json.dumps(rec["params"], sort_keys=True))
            if key not in seen:
                seen.add(key)
                out.setdefault(created, []).append(before["pipelined_s"])
    return {c: v for c, v in out.items() if len(v) >= 10}


def noisy_odds(share: float) -> float:
    """How often ``PROCESSES`` processes drawn from a sitting with ``share`` of them slow have at
    least ``SLOW_SHARE`` of them slow."""
    n = sitting_run.PROCESSES
    need = n - rank(n)
    return sum(math.comb(n, k) * share ** k * (1 - share) ** (n - k) for k in range(need, n + 1))


def test_one_process_is_not_the_sitting() -> None:
    doc = doc_text()
    runs = h100_runs()
    pairs = [(start["launch_pipelined_s"], run["hardware"]["cuda"]["launch_pipelined_s"]) for run in runs.values()
             if (start := (run.get("sitting") or {}).get("start") or {}).get("launch_pipelined_s")
             and start["launch_pipelined_s"] != run["hardware"]["cuda"]["launch_pipelined_s"]]   # another process's
    (n, top, median, split, n_again, limit, ratio, quiet, s42_check, s42_own) = said(
        doc, r"(\d+) H100 runs in the stores took their check and their own yardstick in two\s+processes seconds apart "
             r"\(a `publish` part's check, then the run's yardstick\); their pipelined\s+floors differ by up to ([\d.]+)× "
             r"\(median ([\d.]+)×\), and in (\d+) of the (\d+) one process was over the limit\s+\(([\d.]+) µs, ([\d.]+)× the "
             r"quiet ([\d.]+) µs\) and the other under it\. Session 42's own start read ([\d.]+) µs, its\s+run's yardstick "
             r"([\d.]+) µs\.")
    spans = [max(a, b) / min(a, b) for a, b in pairs]
    line = float(quiet) * 1e-6 * float(ratio)
    assert (n, n_again, top, median) == (str(len(pairs)), n, f"{max(spans):.2f}", f"{statistics.median(spans):.2f}")
    assert split == str(sum((a > line) != (b > line) for a, b in pairs)) and limit == f"{line * 1e6:.2f}"
    assert float(ratio) == FLOOR_RATIO
    last = runs[max(runs)]
    assert (s42_check, s42_own) == (f"{last['sitting']['start']['launch_pipelined_s'] * 1e6:.2f}",
                                    f"{last['hardware']['cuda']['launch_pipelined_s'] * 1e6:.2f}")
    # the cells' own floors, each its own process: the share over the limit per run
    floors = cell_floors()
    share = {c: sum(x > line for x in v) / len(v) for c, v in floors.items()}
    got = said(doc, r"in the (\d+) H100 runs of the stores with ten or more, (\d+)-(\d+) % of a run's cell processes "
                    r"were over the\s+limit, (\d+) % in the median\. Session 38's quiet per-call sittings had (\d+) and "
                    r"(\d+) %; session 39's matrix\s+part had (\d+) %")
    ordered = sorted(share.values())
    s39 = share["2026-12-07T08:38:36+00:00"]
    assert got == (str(len(share)), f"{100 * ordered[0]:.0f}", f"{100 * ordered[-1]:.0f}",
                   f"{100 * statistics.median(ordered):.0f}", f"{100 * ordered[0]:.0f}", f"{100 * ordered[1]:.0f}",
                   f"{100 * s39:.0f}")
    assert share["2026-12-07T06:12:53+00:00"] == ordered[0] and share["2026-12-07T06:21:36+00:00"] == ordered[1]
    assert runs["2026-12-07T08:38:36+00:00"]["sitting"]["start"]["launch_pipelined_s"] < line
    # the rule: PROCESSES processes, a limit counts when SLOW_SHARE of them are over it
    procs, need, nth, odds_median, odds_39, odds_38 = said(
        doc, r"now takes (\d+) yardstick processes, one after another .*? a launch limit counts when at least (\d+) of "
             r"the \d+ are over it\s+\(`sitting\.SLOW_SHARE`: its figure is the (\d)rd lowest; the copy's the \d+rd fastest\)\. "
             r"A sitting like\s+the median run is then called noisy about 1 time in (\d+), one like session 39's (\d+) % "
             r"of the time, one\s+like session 38's second about 1 time in (\d+)\.")
    assert (int(procs), int(need), int(nth)) == (sitting_run.PROCESSES, sitting_run.PROCESSES - rank(sitting_run.PROCESSES),
                                                 rank(sitting_run.PROCESSES) + 1)
    assert math.ceil(round(SLOW_SHARE * int(procs), 9)) == int(need)
    assert (odds_median, odds_39, odds_38) == (f"{1 / noisy_odds(statistics.median(ordered)):.0f}",
                                               f"{100 * noisy_odds(s39):.0f}", f"{1 / noisy_odds(ordered[1]):.0f}")


def test_floors_under_overlap_name_the_share_of_slow_processes() -> None:
    """'three in four of its cells' processes sat at the slower of a process's two levels, against
    about one in three in session 41's run'."""
    doc = doc_text()
    said(doc, r"three in four of its cells' processes\s+sat at the slower of a process's two levels, against "
              r"about one in three in session 41's run")
    (quiet,) = said(doc, r"1\.25× the quiet ([\d.]+) µs\) and the other under it")
    line = FLOOR_RATIO * float(quiet) * 1e-6
    share = {c: sum(x > line for x in v) / len(v) for c, v in cell_floors().items()}
    assert round(4 * share["2026-12-07T08:38:36+00:00"]) == 3 and round(3 * share["2026-12-07T13:26:02+00:00"]) == 1
