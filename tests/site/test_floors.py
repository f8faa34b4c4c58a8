"""compare/site/floors.py: which floor a compared figure was divided by, in words (hand-made records)."""
from __future__ import annotations

import dataclasses
from typing import Any

from compare.results.record import Record
from compare.site import floors

ONE = {"median_s": 30e-6, "iqr_s": 1e-6, "repeats": 50}
TIME = {**ONE, "first_call_s": 0.1, "min_s": 29e-6, "latency": ONE, "throughput": {**ONE, "k": 100}}
HW = {"launch_latency_s": 10e-6, "launch_pipelined_s": 4e-6}


def rec(**fields: Any) -> Record:
    return Record(scenario="saxpy", backend="warp", device="cuda", precision="float32", status="ok",
                  time=TIME, hardware=HW, **fields)


@dataclasses.dataclass(frozen=True)
class Pair:
    rec: Record
    there: Record | None
    regime: str
    floor_ratio: float | None = 1.0


OWN = rec(cell_floor={"before": {"latency_s": 12e-6}})
RUN = rec()


def test_a_pair_is_marked_by_the_side_whose_cells_own_floor_divides_it() -> None:
    assert floors.mark(Pair(OWN, RUN, "latency")) == " (cell floors: here)"
    assert floors.mark(Pair(RUN, OWN, "latency")) == " (cell floors: there)"
    assert floors.mark(Pair(OWN, OWN, "latency")) == " (cell floors: both)"
    assert floors.mark(Pair(RUN, RUN, "latency")) == ""              # both runs' yardsticks: as before
    assert floors.mark(Pair(OWN, None, "latency")) == " (cell floors: here)"
    # the probe measured no pipelined figure: the throughput regime is in the run's yardstick
    assert floors.mark(Pair(OWN, OWN, "throughput")) == "" and floors.mark(Pair(OWN, OWN, "graph")) == ""


def test_the_note_and_the_count_cover_the_pairs_in_floors_only() -> None:
    pairs = [Pair(OWN, RUN, "latency"), Pair(RUN, RUN, "latency"), Pair(OWN, OWN, "latency", None)]
    assert floors.note(pairs) == floors.NOTE and floors.count(pairs) == " (1 with a cell's own floor on one side or both)"
    assert floors.note(pairs[1:]) == floors.count(pairs[1:]) == ""
