"""A results file's typed analysis (compare/results/analysis.py): the stored JSON object is the
analysis itself, so a stress file's findings, series and provenance come back to the same JSON, and
the types name every field the store checks (``compare.results.records.ANALYSIS``)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from compare.results import records
from compare.results.analysis import Analysis, Finding, RunInfo, analysis_of
from compare.results.store import Store

ROOT = Path(__file__).resolve().parents[2]
STRESS = [ROOT / "tests" / "data" / "site" / "stress.json", ROOT / "docs" / "results" / "cpu" / "stress.json"]


@pytest.mark.parametrize("path", STRESS, ids=lambda p: str(p.relative_to(ROOT)))
def test_a_stress_files_analysis_round_trips_to_the_same_json(path: Path) -> None:
    raw = json.loads(path.read_text())["analysis"]
    got = Store.read(path, "stress").analysis
    assert raw["rows"] and got["rows"]
    assert json.dumps(got) == json.dumps(raw)                 # same keys, same order, same values
    assert list(got) == list(raw) and list(got["rows"][0]) == list(raw["rows"][0])
    for row in got["rows"]:
        assert set(row) == set(Finding.__annotations__)


def test_analysis_of_is_the_object_itself() -> None:
    obj = {"rows": [], "series": {"ulps": {"x": [1, 2]}}, "provenance": {"ulps": {"command": "c"}}, "later": 1}
    got = analysis_of(obj)
    assert got is obj and got["series"]["ulps"] == {"x": [1, 2]} and got["later"] == 1   # type: ignore[typeddict-item]


def test_the_types_name_every_field_the_store_checks() -> None:
    assert set(Finding.__annotations__) == set(records.ROW_FIELDS) == set(records.ROW.fields)
    assert set(Analysis.__annotations__) == set(records.ANALYSIS.fields) == {"rows", "series", "provenance"}
    assert set(RunInfo.__annotations__) == set(records.PROVENANCE_RUN.fields)
    assert Analysis.__required_keys__ == frozenset() and RunInfo.__required_keys__ == frozenset()


def test_an_empty_analysis_saves_as_an_empty_object(tmp_path: Path) -> None:
    """The run and sweep suites derive nothing: their files keep ``"analysis": {}``."""
    store = Store(tmp_path / "results.json", "run")
    assert store.analysis == {}
    store.save()
    assert json.loads((tmp_path / "results.json").read_text())["analysis"] == {}
    assert Store.read(tmp_path / "results.json").analysis == {}
