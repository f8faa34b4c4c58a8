"""Each suite's results-file format is registered (compare.results.formats), not imported by side effect:
the sweep's and stress suite's are handed in at start-up (compare.suites.formats.register), a file
of every old format loads through its suite's format (the run suite's own upgrade:
tests/results/test_run_format.py), and reading one loads no suite's driver."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from compare.results import formats
from compare.results.formats import FORMATS
from compare.results.store import SUITES, Store
from compare.stress.format import FORMAT as STRESS
from compare.suites import formats as suite_formats
from compare.sweep.format import FORMAT as SWEEP

ROOT = Path(__file__).resolve().parents[2]
CPU = ROOT / "docs" / "results" / "cpu"


def test_every_suite_has_a_format() -> None:
    suite_formats.register()
    assert set(FORMATS) == set(SUITES) == {"run", "sweep", "stress"}
    assert FORMATS["sweep"] is SWEEP and FORMATS["stress"] is STRESS
    assert all(formats.registered(s) for s in FORMATS)
    assert FORMATS["run"].upgrade and FORMATS["sweep"].upgrade and FORMATS["sweep"].record_problem
    assert FORMATS["stress"].store_problem


def test_a_file_of_a_format_not_registered_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    """Before the start-up's call a sweep or stress file is never read unchecked or unupgraded."""
    monkeypatch.setitem(FORMATS, "sweep", formats.STAND_INS["sweep"])
    monkeypatch.setitem(FORMATS, "stress", formats.STAND_INS["stress"])
    assert not formats.registered("sweep") and formats.registered("run")
    for f in ("sweep.json", "stress.json"):
        with pytest.raises(formats.NotRegistered, match="compare.suites.formats.register"):
            Store.read(CPU / f)
    with pytest.raises(formats.NotRegistered):
        Store.read(ROOT / "tests" / "data" / "format1-sweep.json", "sweep")
    Store.read(CPU / "results.json")           # the run suite's format is the results stage's own
    with pytest.raises(ValueError, match="unknown format"):
        formats.register(formats.Format("sweep", "other.json"))


def test_a_format_1_stress_file_loads_upgraded(tmp_path: Path) -> None:
    """Format 1 of stress.json: {"environment", "provenance", "rows", "series"}, no records."""
    new = json.loads((CPU / "stress.json").read_text())
    old = tmp_path / "stress.json"
    old.write_text(json.dumps({"environment": new["runs"][0], **new["analysis"]}))
    store = Store.read(old, "stress")
    assert store.upgraded_from == 1 and store.analysis["rows"] == new["analysis"]["rows"]


def test_a_format_1_sweep_file_loads_upgraded() -> None:
    store = Store.read(ROOT / "tests" / "data" / "format1-sweep.json", "sweep")
    assert store.upgraded_from == 1 and all(r.tags is not None for r in store.records)


def test_reading_any_file_imports_no_suite() -> None:
    """The schema and the store know no suite's driver: the formats registered at start-up are
    leaves (they import the schema and their suite's definitions, never a driver)."""
    code = ("import sys; from compare.suites import formats; formats.register()\n"
            "from compare.results.store import Store\n"
            "for f in ('results.json', 'sweep.json', 'stress.json'): Store.read('docs/results/cpu/' + f)\n"
            "bad = [m for m in ('compare.suites.run', 'compare.suites.sweep', 'compare.suites.stress', 'compare.running.engine')"
            " if m in sys.modules]\n"
            "assert not bad, bad")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr


def test_the_schema_and_the_store_import_no_suite() -> None:
    """No arrow runs back up: the results stage (its registry of formats included) loads no
    sweep or stress module; their formats are handed in."""
    code = ("import sys, compare.results.records, compare.results.record, compare.results.store\n"
            "bad = [m for m in sys.modules if m.startswith(('compare.sweep', 'compare.stress'))]\n"
            "assert not bad, bad")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
