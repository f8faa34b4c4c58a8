"""docs/measurement.md's "One process is not the sitting" held to the H100 stores (every runs list
under docs/results/h100, each run once, up to session 42's day): why a CUDA sitting check takes
the best of several yardstick processes (compare/running/sitting_run.py). Fast tier."""
from __future__ import annotations

import json
import statistics
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pytest

from compare.running import sitting_run
from measurement_doc import RESULTS, doc_text, said

pytestmark = pytest.mark.xdist_group("measurement-claims")
UNTIL = "2026-12-07T16"        # the stores as the paragraph read them (session 42)


def h100_runs() -> dict[str, Mapping[str, Any]]:
    """Every H100 run with a CUDA yardstick in any store or evidence file, once by its time."""
    out: dict[str, Mapping[str, Any]] = {}
    for path in sorted(Path(RESULTS / "h100").rglob("*.json")):
        try:
            obj = json.loads(path.read_text())
        except ValueError:
            continue
        for run in obj.get("runs", []) if isinstance(obj, dict) and isinstance(obj.get("runs"), list) else []:
            hw = ((run.get("hardware") or {}).get("cuda") or {}) if isinstance(run, dict) else {}
            if hw.get("launch_pipelined_s") and str(run.get("created", "")) < UNTIL:
                out.setdefault(run["created"], run)
    return out


def test_one_process_is_not_the_sitting() -> None:
    doc = doc_text()
    runs = h100_runs()
    pairs = []
    single = []
    for run in runs.values():
        own = run["hardware"]["cuda"]["launch_pipelined_s"]
        single.append(own)
        start = (run.get("sitting") or {}).get("start") or {}
        if start.get("launch_pipelined_s") and start["launch_pipelined_s"] != own:    # another process's
            pairs.append((start["launch_pipelined_s"], own))
            single.append(start["launch_pipelined_s"])
    (n, top, median, split, n_again, limit, ratio, quiet, s42_check, s42_own, floors, n_runs, checks, over,
     processes) = said(
        doc, r"(\d+) H100 runs in the stores took their\s+check and their own yardstick in two processes seconds apart "
             r"\(a `publish` part's check, then the\s+run's yardstick\); their pipelined floors differ by up to ([\d.]+)× "
             r"\(median ([\d.]+)×\), and in (\d+) of the (\d+)\s+one process was over the limit \(([\d.]+) µs, ([\d.]+)× the "
             r"quiet ([\d.]+) µs\) and the other under it\. Session\s+42's own start read ([\d.]+) µs, its run's yardstick "
             r"([\d.]+) µs\. Of the (\d+) single-process pipelined\s+floors the H100 stores hold up to that day \((\d+) runs' "
             r"yardsticks and (\d+) checks\), (\d+) are over the\s+limit\. .*? a\s+CUDA check is now the best of (\d+) "
             r"yardstick processes")
    spans = [max(a, b) / min(a, b) for a, b in pairs]
    line = float(quiet) * 1e-6 * float(ratio)
    assert (n, n_again, top, median) == (str(len(pairs)), n, f"{max(spans):.2f}", f"{statistics.median(spans):.2f}")
    assert split == str(sum((a > line) != (b > line) for a, b in pairs)) and limit == f"{line * 1e6:.2f}"
    assert (floors, n_runs, checks, over) == (str(len(single)), str(len(runs)), str(len(pairs)),
                                               str(sum(x > line for x in single)))
    last = runs[max(runs)]
    assert (s42_check, s42_own) == (f"{last['sitting']['start']['launch_pipelined_s'] * 1e6:.2f}",
                                    f"{last['hardware']['cuda']['launch_pipelined_s'] * 1e6:.2f}")
    assert processes == str(sitting_run.PROCESSES)
    (odds,) = said(doc, r"all five at the slower level comes\s+about 1 time in (\d+) at that rate")
    assert odds == f"{1 / (sum(x > line for x in single) / len(single)) ** sitting_run.PROCESSES:.0f}"
    from compare.measuring.sitting import FLOOR_RATIO
    assert float(ratio) == FLOOR_RATIO
