"""The run suite's results-file format (compare/results/run_format.py): a format-1 record, whose
distance to the reference backend was keyed ``vs_<name>``, upgrades to today's ``vs_reference``
with the reference named; a record of today's shape, or of no such distance, is left alone."""
from __future__ import annotations

import copy
import json
from pathlib import Path

import backends
import pytest

from compare.results.formats import FORMATS
from compare.results.record import Record, RecordError
from compare.results.run_format import FORMAT, upgrade_record
from compare.results.store import Store

ROOT = Path(__file__).resolve().parents[2]
CPU = ROOT / "docs" / "results" / "cpu"
REF = backends.reference()
IDENT = {"scenario": "saxpy", "backend": "numpy", "device": "cpu", "precision": "float32", "variant": "default",
         "params": {"n": 1000}}


def test_the_run_format_is_the_registered_run_suites() -> None:
    assert FORMAT.suite == "run" and FORMAT.file == "results.json" and FORMAT.upgrade is upgrade_record
    assert FORMATS["run"] is FORMAT


def test_a_format_1_distance_is_renamed_and_names_its_reference() -> None:
    old = {**IDENT, "status": "ok", "error": {"vs_oracle": 1e-7, f"vs_{REF}": 2e-7, f"vs_{REF}_device": "cpu",
                                              "tolerance": 1e-5}}
    new = upgrade_record(copy.deepcopy(old))
    assert new["error"] == {"vs_oracle": 1e-7, "tolerance": 1e-5, "vs_reference": 2e-7, "reference": REF,
                            "vs_reference_device": "cpu"}
    assert {k: v for k, v in new.items() if k != "error"} == {k: v for k, v in old.items() if k != "error"}
    # without the device key (the reference ran on the same device) only the distance moves
    assert upgrade_record({"error": {f"vs_{REF}": 0.0}})["error"] == {"vs_reference": 0.0, "reference": REF}


@pytest.mark.parametrize("rec", [
    {"error": {"vs_reference": 1.0, "reference": REF}},       # today's shape
    {"error": {"vs_not_the_reference": 1.0}},                   # another backend's name
    {"error": None}, {"error": [1]}, {},                        # no distance to move
])
def test_a_record_of_another_shape_is_left_alone(rec: dict) -> None:
    before = copy.deepcopy(rec)
    assert upgrade_record(rec) == before


def test_a_format_1_record_loads_upgraded_and_a_malformed_one_is_refused() -> None:
    ok = next(r for r in json.loads((CPU / "results.json").read_text())["records"]
              if r["status"] == "ok" and (r.get("error") or {}).get("reference") == REF)
    old = copy.deepcopy(ok)
    old["error"] = {("vs_" + REF if k == "vs_reference" else f"vs_{REF}_device" if k == "vs_reference_device" else k): v
                    for k, v in ok["error"].items() if k != "reference"}
    rec = Record.from_json(old, FORMAT.upgrade)
    assert dict(rec.error) == {k: v for k, v in ok["error"].items()}          # today's error block again
    assert rec.error["reference"] == REF and f"vs_{REF}" not in rec.error
    old["error"][f"vs_{REF}"] = "far"
    with pytest.raises(RecordError, match="vs_reference"):
        Record.from_json(old, FORMAT.upgrade)


def test_a_format_1_run_file_loads_upgraded(tmp_path: Path) -> None:
    """Format 1 of results.json: {"environment", "records"}, the reference's distance ``vs_<name>``."""
    new = json.loads((CPU / "results.json").read_text())
    ref = backends.reference()
    records = []
    for r in new["records"]:
        err = r.get("error")
        if isinstance(err, dict) and err.get("reference") == ref:
            err = {("vs_" + ref if k == "vs_reference" else f"vs_{ref}_device" if k == "vs_reference_device" else k): v
                   for k, v in err.items() if k != "reference"}
            r = {**r, "error": err}
        records.append(r)
    old = tmp_path / "results.json"
    old.write_text(json.dumps({"environment": new["runs"][0], "records": records}))
    store, today = Store.read(old, "run"), Store.read(CPU / "results.json")
    assert store.upgraded_from == 1 and any(r.error and "vs_reference" in r.error for r in store.records)
    assert [r.error for r in store.records] == [r.error for r in today.records]
