"""compare/results/record_floor.py: a CUDA cell's own launch floor (``cell_floor``) as a typed part of the
record: read by attribute, written back key for key, checked on load; records without it unchanged."""
from __future__ import annotations

import json
from typing import Any

import pytest

from compare.results.record import Record, RecordError
from compare.results.record_floor import CellFloor, FloorProbe
from compare.results.store import jsonable

BEFORE = {"latency_s": 9.5e-6, "latency_iqr_s": 4e-7, "pipelined_s": 4.4e-6, "launches": 300, "k": 200,
          "batches": 6, "spent_s": 0.012, "context": "before the framework's set-up, on the primary context"}
AFTER = {"spent_s": 0.001, "context": "after the timed regimes, on ", "error": "OSError: cuInit failed (CUresult 3)"}


def record(**more: Any) -> dict[str, Any]:
    return {"scenario": "saxpy", "backend": "cupy", "device": "cuda", "precision": "float32", "status": "ok",
            "reason": "", "params": {"n": 1000000},
            "time": {"first_call_s": 0.1, "median_s": 2e-5, "iqr_s": 1e-6, "min_s": 1.9e-5, "repeats": 100},
            "error": {"vs_oracle": 0.0, "tolerance": 1e-6}, **more}


def test_the_part_reads_by_attribute_and_round_trips_through_json() -> None:
    obj = record(cell_floor={"before": BEFORE, "after": AFTER, "how": "empty PTX kernel"},
                 hardware={"copy_bytes_per_s": 2e12, "launch_latency_s": 1.2e-5})
    rec = Record.from_json(json.loads(json.dumps(obj)))
    floor = rec.cell_floor
    assert isinstance(floor, CellFloor) and isinstance(floor.before, FloorProbe) and isinstance(floor.after, FloorProbe)
    assert floor.before.latency_s == 9.5e-6 and floor.before.pipelined_s == 4.4e-6 and floor.before.figures
    assert floor.after.error == AFTER["error"] and floor.after.latency_s is None and not floor.after.figures
    assert rec.to_json() == obj and list(rec.to_json()) == list(obj)
    assert list(rec.to_json()["cell_floor"]["before"]) == list(BEFORE)
    assert Record.from_json(json.loads(json.dumps(jsonable(rec.to_json())))).to_json() == obj


def test_a_part_built_in_the_worker_is_the_json_the_driver_reads() -> None:
    built = CellFloor.of(before=FloorProbe.of(**BEFORE), after=None, how="h")
    rec = Record.from_json(record()).replace(cell_floor=built)
    back = Record.from_json(json.loads(json.dumps(jsonable(rec.to_json()))))
    assert back.to_json()["cell_floor"] == {"before": BEFORE, "after": None, "how": "h"}
    assert back.cell_floor is not None and back.cell_floor.after is None


def test_an_older_record_without_it_loads_and_writes_as_before() -> None:
    obj = record()
    rec = Record.from_json(obj)
    assert rec.cell_floor is None and rec.to_json() == obj and "cell_floor" not in rec.to_json()


@pytest.mark.parametrize("floor,needle", [
    ({"before": {**BEFORE, "latency_s": -1.0}}, "cell_floor.before.latency_s"),
    ({"after": {"launches": 2.5}}, "cell_floor.after.launches"),
    ({"before": "fast"}, "cell_floor.before must be an object"),
    ([1, 2], "cell_floor"),
])
def test_a_malformed_part_is_refused_by_name(floor: Any, needle: str) -> None:
    with pytest.raises(RecordError, match=needle.replace(".", r"\.")):
        Record.from_json(record(cell_floor=floor))
