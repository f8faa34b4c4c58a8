"""The sweep suite's results-file format (compare/sweep/format.py): a format-1 record upgrades to
today's tags, and what the page and plots index in an ok record is checked on load."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from compare.results.record import Record, RecordError
from compare.results.store import Store
from compare.sweep.format import FORMAT, record_problem, upgrade_record
from conftest import ROOT

OLD = {"scenario": "saxpy", "backend": "warp", "device": "cpu", "precision": "float32",
       "variant": "default", "params": {"n": 1024}, "sweep": "bandwidth", "role": "saxpy",
       "knob": {"name": "n", "value": 1024}, "status": "ok"}


def test_old_records_are_upgraded_to_tags():
    new = upgrade_record(dict(OLD))
    assert new["tags"] == {"sweep": "bandwidth", "role": "bandwidth", "knob": {"name": "n", "value": 1024}}
    assert not {"sweep", "role", "knob"} & set(new) and new["params"] == {"n": 1024}
    assert upgrade_record(new) is new
    err = upgrade_record({**OLD, "scenario": "sdf", "sweep": "error", "role": "sdf", "knob": {}})
    assert err["tags"] == {"sweep": "error", "role": "sdf", "knob": {}}
    # a yardstick keeps its role (launch: the scenario's own measures); no knob reads as {}
    launch = upgrade_record({**OLD, "scenario": "launch", "role": "launch", "knob": None})
    assert launch["tags"] == {"sweep": "bandwidth", "role": "launch", "knob": {}}
    store = Store(ROOT / "unused.json", "sweep",
                  records=[Record.from_json(new), Record.from_json(upgrade_record(dict(OLD)))])
    assert len(store.records) == 1                 # the same cell, old or new shape: one key


def test_a_record_of_neither_shape_is_left_alone():
    plain = {k: v for k, v in OLD.items() if k not in ("sweep", "role", "knob")}
    assert upgrade_record(plain) is plain


def test_old_files_upgrade_without_importing_the_suite():
    """The store upgrades a format-1 file's records itself (the formats registered by an explicit
    call, as the command line's start-up makes it; no import side effect), so saving it never
    writes old-shape records under format 2."""
    code = ("from compare.suites import formats; formats.register()\n"
            "from compare.results.store import Store; s = Store.read('tests/data/format1-sweep.json', 'sweep'); "
            "assert s.upgraded_from == 1 and s.records and all(r.tags is not None for r in s.records), 'not upgraded'")
    p = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert p.returncode == 0, p.stderr


def test_a_format1_file_reads_as_today_with_every_record_and_knob():
    raw = json.loads((ROOT / "tests/data/format1-sweep.json").read_text())["records"]
    store = Store.read(ROOT / "tests/data/format1-sweep.json", "sweep")
    assert store.upgraded_from == 1 and len(store.records) == len(raw)
    by_key = {r.key: r for r in store.records}
    for old in raw:
        rec = by_key[Record.from_json(upgrade_record(dict(old))).key]
        assert rec.tags is not None and dict(rec.tags["knob"]) == (old["knob"] or {})
        assert rec.tags["sweep"] == old["sweep"]


def _ok(kind, role, **blocks):
    rec = {"scenario": "particles", "backend": "numpy", "device": "cpu", "precision": "float32",
           "variant": "default", "status": "ok", "params": {"n": 256, "steps": 300},
           "tags": {"sweep": kind, "role": role, "knob": {"name": "n", "value": 256}},
           "time": {"first_call_s": 1.0, "median_s": 1e-3, "iqr_s": 0.0, "min_s": 1e-3, "repeats": 3}}
    rec.update(blocks)
    return rec


def test_what_the_page_indexes_is_required_in_an_ok_record():
    full = _ok("scaling", "particles", error={"vs_oracle": 0.0}, work={"items": 1.0},
               memory={"peak_host_rss_bytes": 1})
    assert record_problem(full) is None
    for block in ("error", "work", "memory"):
        p = record_problem({k: v for k, v in full.items() if k != block})
        assert p is not None and p.startswith(block) and "scaling" in p
    nok = {**full, "status": "error", "tags": {**full["tags"], "knob": {}}}
    assert record_problem({k: v for k, v in nok.items() if k != "memory"}) is None   # not ok: read as is
    no_knob = {**full, "tags": {**full["tags"], "knob": {}}}
    assert "tags.knob.value" in record_problem(no_knob)
    assert record_problem({**_ok("error", "particles"), "tags": {"sweep": "error", "role": "particles",
                                                                 "knob": {}}}) is None


def test_the_store_refuses_a_sweep_record_the_page_could_not_read():
    good = _ok("horizon", "projectile", error={"vs_oracle": 0.0, "tolerance": 1e-6})
    assert Record.from_json(good, FORMAT.upgrade, FORMAT.record_problem).tags["knob"]["value"] == 256
    with pytest.raises(RecordError, match="tags.knob.value is missing .*horizon"):   # the horizon axis
        Record.from_json({**good, "tags": {**good["tags"], "knob": {}}}, FORMAT.upgrade, FORMAT.record_problem)
