"""The typed record (compare/results/record.py): one loader that validates, one writer that gives back the
stored object unchanged, immutable in between.

Every committed store loads through it (format 1 upgraded); each record's JSON round-trips key for
key (a whole file saved to the same bytes: tests/results/test_store.py); a malformed field is one
line naming it; a record cannot be changed in place (the engine stores nothing a reader could not
load: tests/running/test_engine.py).
"""
from __future__ import annotations

import copy
import dataclasses
import json
from pathlib import Path
from typing import Any

import pytest
from conftest import ROOT

from compare import spec
from compare.results.record import FORMAT_VERSION, Record, RecordError
from compare.results.store import Store

SITE = ROOT / "tests" / "data" / "site"
FORMAT2 = sorted({*ROOT.glob("docs/results/*/results.json"), *ROOT.glob("docs/results/*/sweep.json"),
                  *ROOT.glob("docs/results/*/stress.json"), *ROOT.glob("docs/results/*/*/sweep.json"),
                  *SITE.glob("*.json")})
FORMAT1 = [ROOT / "tests" / "data" / "format1-sweep.json"]
OK_RUN = next(r for r in json.loads((SITE / "results.json").read_text())["records"]
              if r["status"] == "ok" and r.get("time") is not None)


def ids(paths: list[Path]) -> list[str]:
    return [str(p.relative_to(ROOT)) for p in paths]


@pytest.mark.parametrize("path", FORMAT2, ids=ids(FORMAT2))
def test_every_record_of_a_committed_store_round_trips(path: Path) -> None:
    raw = json.loads(path.read_text())
    assert raw["format_version"] == FORMAT_VERSION and raw["records"] or raw["analysis"]
    for i, obj in enumerate(raw["records"]):
        got = Record.from_json(copy.deepcopy(obj)).to_json()
        assert got == obj and list(got) == list(obj), i      # same keys, same order, same values


@pytest.mark.parametrize("path", FORMAT1, ids=ids(FORMAT1))
def test_a_format_1_store_loads_upgraded_and_its_records_round_trip(path: Path) -> None:
    store = Store.read(path)
    assert store.upgraded_from == 1 and store.records
    assert all(r.tags is not None and r.tags.get("sweep") for r in store.records)
    for r in store.records:
        assert Record.from_json(r.to_json()) == r
    saved = json.loads(store.to_json())
    assert saved["format_version"] == FORMAT_VERSION and saved["upgraded_from"] == 1
    assert not any(k in rec for rec in saved["records"] for k in ("sweep", "role", "knob"))


def test_fields_are_attributes_and_blocks_are_read_only() -> None:
    r = Record.from_json(copy.deepcopy(OK_RUN))
    assert (r.scenario, r.backend, r.status, r.reason) == (OK_RUN["scenario"], OK_RUN["backend"], "ok", "")
    assert r.time["median_s"] == OK_RUN["time"]["median_s"] and r.key == spec.key(OK_RUN)
    with pytest.raises(dataclasses.FrozenInstanceError):
        r.status = "error"                                   # type: ignore[misc]
    with pytest.raises(TypeError):
        r.time["median_s"] = 1.0                             # type: ignore[index]
    with pytest.raises(TypeError):
        r.params["n"] = 1                                    # type: ignore[index]
    assert isinstance(r.to_json()["time"], dict)             # plain JSON again on the way out


def test_lists_inside_a_record_are_tuples_and_come_back_as_lists() -> None:
    obj = copy.deepcopy(OK_RUN)
    obj["time"]["noise"] = {"noisy": True, "reasons": [{"regime": "latency", "why": "spread"}]}
    r = Record.from_json(obj)
    assert r.time["noise"]["reasons"] == ({"regime": "latency", "why": "spread"},)
    assert r.to_json()["time"]["noise"]["reasons"] == [{"regime": "latency", "why": "spread"}]


def test_a_key_this_version_does_not_name_is_kept_where_it_was() -> None:
    obj = {"future_figure": {"a": [1, 2]}, **copy.deepcopy(OK_RUN), "zz_last": "x"}
    r = Record.from_json(obj)
    assert r.extra["future_figure"]["a"] == (1, 2)
    assert list(r.to_json()) == list(obj) and r.to_json() == obj


def test_replace_changes_a_copy_and_adds_a_new_field_last() -> None:
    obj = copy.deepcopy(OK_RUN)
    obj.pop("machine", None)
    r = Record.from_json(obj)
    m = r.replace(machine="box", error={**r.error, "vs_reference": 0.0})
    assert r.machine is None and r.error == OK_RUN["error"]              # the original is unchanged
    assert list(m.to_json()) == [*obj, "machine"] and m.error["vs_reference"] == 0.0


def test_a_record_built_in_code_writes_the_fields_it_has() -> None:
    r = Record(scenario="saxpy", backend="numpy", device="cpu", precision="float32", status="skipped",
               reason="not installed")
    assert r.to_json() == {"scenario": "saxpy", "backend": "numpy", "device": "cpu", "precision": "float32",
                           "status": "skipped", "variant": "default", "reason": "not installed"}
    assert Record.from_json(r.to_json()) == r


@pytest.mark.parametrize("change,needle", [
    (lambda o: o["time"].update(median_s=-1.0), "time.median_s must be a finite number > 0, got -1.0"),
    (lambda o: o.update(status="fine"), "record status must be one of ok, mismatch, error, skipped, got 'fine'"),
    (lambda o: o.update(backend="a/b"), "backend must be a name of letters, digits and _.+- (at most 64)"),
    (lambda o: o.update(scenario="nope"), "scenario 'nope' is not one this tool knows"),
    (lambda o: o["params"].update(n=-5), "params: "),
    (lambda o: o.update(error=None), "needs both time and error (or neither), got only time"),
    (lambda o: o.update(tags=[1]), "record field 'tags' must be an object or null, got list"),
])
def test_a_malformed_field_is_one_line_naming_it(change: Any, needle: str) -> None:
    obj = copy.deepcopy(OK_RUN)
    change(obj)
    with pytest.raises(RecordError) as exc:
        Record.from_json(obj)
    assert needle in str(exc.value) and "\n" not in str(exc.value), str(exc.value)


def test_not_an_object_is_refused() -> None:
    with pytest.raises(RecordError, match="a record must be an object, got list"):
        Record.from_json([1, 2])


def test_fd_agreement_is_the_gradient_blocks_share_or_none() -> None:
    """One reading of a cell's agreement with float64 finite differences, for every page and CSV:
    a number where the gradient block holds one; none without a gradient or for a stored non-finite."""
    base = Record.from_json(OK_RUN)
    assert base.replace(gradient=None).fd_agreement is None
    for stored, read in ((0.75, 0.75), (1, 1.0), ("nan", None), (None, None)):
        rec = Record.from_json({**OK_RUN, "gradient": {"method": "ad", "fd_agreement": stored}})
        assert rec.fd_agreement == read and (read is None or isinstance(rec.fd_agreement, float))


def test_process_count_is_the_time_blocks_count_else_one() -> None:
    """``Record.process_count``: the worker processes that timed the cell (``time.processes.count``);
    a record without repeats or without a time block counts one."""
    time = {k: v for k, v in OK_RUN["time"].items() if k != "processes"}
    assert Record.from_json({**OK_RUN, "time": {**time, "processes": {"count": 4}}}).process_count == 4
    assert Record.from_json({**OK_RUN, "time": time}).process_count == 1
    assert Record.from_json({**OK_RUN, "time": None, "error": None}).process_count == 1
