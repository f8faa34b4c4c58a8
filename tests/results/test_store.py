"""The one results store (compare/results/store.py): a file read, validated and upgraded, saved to
the same bytes; records keyed by cell (a later record of a cell wins, in a merge too); a file of
another suite, version or shape refused in one line naming the file; every write atomic.

(Hostile paths, symbolic links and record-built array names: tests/results/test_store_paths.py.)"""
from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from conftest import PUBLISHED_STORES, published_store

from compare.files import TEMP_MARK, TEMP_SUFFIX
from compare.results import store as store_mod
from compare.results.environment import RunEnvironment, machine, same_machine
from compare.results.record import FORMAT_VERSION, Record
from compare.results.stamps import unstamped
from compare.results.store import (SUITES, Store, StoreError, jsonable, read_bounded, remove_stale_temps,
                                   run_environments)

ROOT = Path(__file__).resolve().parents[2]
SITE = ROOT / "tests" / "data" / "site"
PUBLISHED = sorted({*ROOT.glob("docs/results/*/results.json"), *ROOT.glob("docs/results/*/sweep.json"),
                    *ROOT.glob("docs/results/*/stress.json"), *ROOT.glob("docs/results/*/*/sweep.json")})
SITE_RECORDS = json.loads((SITE / "results.json").read_text())["records"]


SUITE_FILES = ("results.json", "sweep.json", "stress.json")
MACHINES = sorted({p.parent for p in PUBLISHED})


# the published stores, read once per test process (seconds each: several tests read each one)
read_published, SHARED = published_store, PUBLISHED_STORES


def ids(paths: list[Path]) -> list[str]:
    return [str(p.relative_to(ROOT)) for p in paths]


def small_store(path: Path, n: int = 4, host: str = "a") -> Store:
    return Store(path, "run", [{"hostname": host}], [Record.from_json(json.loads(json.dumps(r)))
                                                     for r in SITE_RECORDS[:n]])


@SHARED
@pytest.mark.parametrize("folder", MACHINES, ids=ids(MACHINES))
def test_a_machine_folder_holds_the_runs_of_one_machine(folder: Path) -> None:
    """A report compares like with like: every run in a machine's stores names one machine (GPU
    models, else the CPU model and, where recorded, its family and model; a run whose environment
    was not kept names none)."""
    envs = [e for f in folder.glob("*.json") if f.name in SUITE_FILES
            for entry in read_published(f).runs for e in run_environments(entry) if e.get("cpu") or e.get("gpus")]
    apart = sorted({machine(a) for a in envs for b in envs if not same_machine(a, b)})
    assert not apart, f"{folder.relative_to(ROOT)} mixes machines: {apart}"


@SHARED
@pytest.mark.parametrize("path", PUBLISHED, ids=ids(PUBLISHED))
def test_a_published_store_saves_to_the_same_bytes(path: Path) -> None:
    """Files the store wrote (docs/results) come back byte for byte after a load and a save."""
    assert read_published(path).to_json() == path.read_text()


# Runs stored from here on name a commit whose files they ran (session 21 made that checkable on a
# lent machine); older entries stay, named "dirty" or "unknown" on their pages, until remeasured.
CLEAN_FROM = "2026-11-27T12:00:00+00:00"


@SHARED
@pytest.mark.parametrize("path", PUBLISHED, ids=ids(PUBLISHED))
def test_a_published_run_from_an_uncommitted_tree_is_refused(path: Path) -> None:
    """No run entry stored since CLEAN_FROM comes from a dirty tree or one whose state is unknown."""
    late = [e for entry in read_published(path).runs for e in run_environments(entry)
            if str(e.get("created", "")) >= CLEAN_FROM]
    assert [e["created"] for e in late if e.get("git_dirty") is not False or not e.get("git_commit")] == []


RESULTS = sorted(ROOT.glob("docs/results/*/results.json"))


def not_clean(entries: list) -> list:
    """The run entries that do not name a checked clean commit (their start times)."""
    return [e.get("created") for e in entries if e.get("git_dirty") is not False or not e.get("git_commit")]


@SHARED
@pytest.mark.parametrize("path", RESULTS, ids=ids(RESULTS))
def test_every_published_run_figure_names_a_clean_commit(path: Path) -> None:
    """A results store's figures name a commit someone can check out: every record names its run,
    and every run entry is of a checked clean commit (older records live in evidence/, not here)."""
    s = read_published(path)
    assert [r.key for r in s.records if not r.run] == []
    assert not_clean(s.runs) == []
    named = {str(r.run["created"]) for r in s.records if r.run}
    assert {str(e.get("created")) for e in s.runs} == named        # no entry that no record names


@SHARED
@pytest.mark.parametrize("path", PUBLISHED, ids=ids(PUBLISHED))
def test_every_published_record_names_a_run_of_its_store(path: Path) -> None:
    """Every record of every published store (results, sweep, stress) names the run that measured
    it: an entry of the store's runs (a merged entry's environments too), by start and commit; a
    record stored before its suite stamped records, whose run the store's evidence could not tell
    (compare/suites/stamping.py), says so explicitly (its pages: "run unknown")."""
    s = read_published(path)
    assert unstamped(s.records, s.runs) == []


CLEAN = [p for m in ("cpu", "xeon") for p in sorted(ROOT.glob(f"docs/results/{m}/*.json"))
         if p.name in ("sweep.json", "stress.json")]


@SHARED
@pytest.mark.parametrize("path", CLEAN, ids=ids(CLEAN))
def test_the_cpu_stores_sweeps_and_stress_name_clean_commits(path: Path) -> None:
    """The two CPU stores' sweep and stress files were measured again from clean commits: every
    sweep record names its run (a stress row names its experiment, whose run the merge keeps), and
    every run (a stress file: every part its merge names) is of a checked clean commit. The
    H100's keep older runs until measured again (docs/measurement.md)."""
    s = read_published(path)
    assert s.suite == "stress" or [r.key for r in s.records if not r.run] == []
    prov = s.analysis.get("provenance") or {}
    parts = [e for v in prov.values() for e in (v if isinstance(v, list) else [v])]
    entries = [*s.runs, *parts]
    assert entries and not_clean(entries) == []


@SHARED
def test_measurement_md_counts_the_h100_sweep_and_stress_runs_as_the_stores_do() -> None:
    """docs/measurement.md's counts of the H100 sweep and stress stores' run entries that are not
    of a checked clean commit, held against the stores as they are measured again."""
    text = re.sub(r"\s+", " ", (ROOT / "docs" / "measurement.md").read_text(encoding="utf-8"))
    h100 = ROOT / "docs" / "results" / "h100"
    sweep, stress = read_published(h100 / "sweep.json"), read_published(h100 / "stress.json")
    prov = stress.analysis.get("provenance") or {}
    entries = [*stress.runs, *(e for v in prov.values() for e in (v if isinstance(v, list) else [v]))]
    dirty = sum(e.get("git_dirty") is True for e in sweep.runs)
    unknown = len(not_clean(sweep.runs)) - dirty
    assert f"dirty or unknown ({dirty} and {unknown} of its {len(sweep.runs)} run entries)" in text
    unknown = len(not_clean(entries))
    assert f"stress store's {len(entries)} run entries" in text
    assert f"are of unknown tree state and {len(entries) - unknown} of a checked clean commit" in text
    assert f", {unknown} (the older" in text


def test_a_saved_store_reads_back_and_saves_to_the_same_bytes(tmp_path: Path) -> None:
    path = tmp_path / "results.json"
    mine = small_store(path)
    mine.save()
    first = path.read_text()
    back = Store.read(path, "run")
    assert back.suite == "run" and back.runs == [{"hostname": "a"}] and back.upgraded_from is None
    assert back.records == mine.records and [r.key for r in back.records] == [r.key for r in mine.records]
    back.save()
    assert path.read_text() == first and json.loads(first)["format_version"] == FORMAT_VERSION
    assert [p.name for p in tmp_path.iterdir()] == ["results.json"]        # no temporary left


def test_a_later_record_of_a_cell_replaces_the_earlier_one(tmp_path: Path) -> None:
    s = small_store(tmp_path / "results.json")
    first = s.records[0]
    assert s.get(first.key) == first and s.get("no such key") is None
    later = first.replace(status="error", reason="rerun failed", time=None, error=None)
    s.put(later)
    assert len(s.records) == 4 and s.records[0] == later and s.get(first.key) == later


def test_merge_adds_runs_and_records_and_the_later_record_wins(tmp_path: Path) -> None:
    a = small_store(tmp_path / "a.json", n=3, host="a")
    b = Store(tmp_path / "b.json", "run", [{"hostname": "b"}],
              [a.records[1].replace(reason="the later one"), Record.from_json(json.loads(json.dumps(SITE_RECORDS[5])))])
    before = [r.key for r in a.records]
    a.merge(b)
    assert a.runs == [{"hostname": "a"}, {"hostname": "b"}]
    assert [r.key for r in a.records] == [*before, b.records[1].key]       # a replaced record keeps its place
    assert len(a.records) == 4 and a.records[1].reason == "the later one"


def test_a_store_of_another_suite_is_refused(tmp_path: Path) -> None:
    run = small_store(tmp_path / "results.json")
    with pytest.raises(StoreError, match="holds sweep results; cannot merge into run results"):
        run.merge(Store(tmp_path / "sweep.json", "sweep"))
    with pytest.raises(StoreError, match=r"results.json: holds run results, not sweep results$"):
        Store.read(SITE / "results.json", "sweep")
    with pytest.raises(ValueError, match="unknown suite 'bench'"):
        Store(tmp_path / "x.json", "bench")


def test_done_keeps_ok_mismatch_and_skipped_and_retries_errors(tmp_path: Path) -> None:
    s = small_store(tmp_path / "results.json", n=1)
    r = s.records[0]
    for status, kept in (("ok", True), ("mismatch", True), ("skipped", True), ("error", False)):
        s.put(r.replace(status=status))
        assert s.done(r.key) is kept, status
    assert not s.done("absent")


def test_open_reads_the_suites_file_only_when_kept(tmp_path: Path) -> None:
    assert Store.open(tmp_path, "sweep").records == [] and Store.open(tmp_path, "sweep").path == tmp_path / "sweep.json"
    small_store(tmp_path / "results.json").save()
    assert len(Store.open(tmp_path, "run").records) == 4
    assert Store.open(tmp_path, "run", keep=False).records == []
    assert SUITES == {"run": "results.json", "sweep": "sweep.json", "stress": "stress.json"}


@pytest.mark.parametrize("text,needle", [
    ("[1, 2]", "not a results file (top level is list, not an object)"),
    ('{"hello": 1}', "not a results file (no format_version, records or rows)"),
    ('{"format_version": 9, "suite": "run", "runs": [], "records": []}', "format_version 9 is not supported"),
    ('{"format_version": 2, "suite": "bench", "runs": [], "records": []}', "unknown suite 'bench'"),
    ('{"format_version": 2, "suite": "run", "runs": [1], "records": []}', "'runs' must be a list of objects"),
    ('{"format_version": 2, "suite": "run", "runs": [], "records": {}}', "'records' must be a list"),
    ('{"format_version": 2, "suite": "run", "runs": [], "records": [], "analysis": []}', "'analysis' must be an object"),
    ("{not json", "not JSON"),
    (b"\xff\xfe", "cannot read"),
])
def test_a_file_that_is_not_a_store_is_one_line_naming_it(tmp_path: Path, text: str | bytes, needle: str) -> None:
    path = tmp_path / "results.json"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    with pytest.raises(StoreError) as exc:
        Store.read(path)
    msg = str(exc.value)
    assert needle in msg and str(path) in msg and "\n" not in msg, msg
    with pytest.raises(StoreError, match="no such file"):
        Store.read(tmp_path / "missing.json")


def test_the_store_names_the_file_and_the_record(tmp_path: Path) -> None:
    doc = json.loads((SITE / "results.json").read_text())
    i = next(i for i, r in enumerate(doc["records"]) if r["status"] == "ok" and r.get("time"))
    doc["records"][i]["error"]["tolerance"] = [1]
    (tmp_path / "results.json").write_text(json.dumps(doc))
    with pytest.raises(StoreError) as exc:
        Store.read(tmp_path / "results.json")
    assert str(exc.value) == (f"{tmp_path / 'results.json'}: record {i}: "
                              "record field error.tolerance must be a number or null, got [1]")


def test_a_file_past_the_size_bound_is_refused_unread(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "results.json"
    path.write_text(" " * (2 * 2**20 + 1))
    assert len(read_bounded(path, 3 * 2**20)) == 2 * 2**20 + 1
    with pytest.raises(StoreError, match="larger than 2 MiB"):
        read_bounded(path, 2 * 2**20)
    monkeypatch.setattr(store_mod, "MAX_FILE_BYTES", 2**20)
    with pytest.raises(StoreError, match="larger than 1 MiB"):
        Store.read(path)


def test_jsonable_gives_plain_json_and_names_non_finite_floats() -> None:
    got = jsonable({1: np.float32(0.5), "a": (np.int64(3), np.bool_(True)), "b": np.arange(2.0),
                    "c": [math.nan, -math.inf, np.float64(math.inf)], "d": True})
    assert got == {"1": 0.5, "a": [3, True], "b": [0.0, 1.0], "c": ["nan", "-inf", "inf"], "d": True}
    assert type(got["a"][0]) is int and type(got["a"][1]) is bool and type(got["1"]) is float
    json.dumps(got, allow_nan=False)


def test_saving_writes_non_finite_figures_as_strings(tmp_path: Path) -> None:
    s = Store(tmp_path / "stress.json", "stress", analysis={"series": {"x": {"y": [1.0, math.nan]}}})
    s.save()
    assert json.loads((tmp_path / "stress.json").read_text())["analysis"]["series"]["x"]["y"] == [1.0, "nan"]


def test_stale_temporaries_are_removed_and_nothing_else(tmp_path: Path) -> None:
    (tmp_path / "plots").mkdir()
    left = [tmp_path / f".results.json{TEMP_MARK}ab12{TEMP_SUFFIX}",
            tmp_path / "plots" / f".speed.png{TEMP_MARK}x{TEMP_SUFFIX}"]
    users = [tmp_path / "notes.tmp", tmp_path / f".results.json.ab12{TEMP_SUFFIX}", tmp_path / "results.json"]
    for p in left + users:
        p.write_text("x")
    assert sorted(remove_stale_temps(tmp_path)) == sorted(left)
    assert not any(p.exists() for p in left) and all(p.exists() for p in users)


def test_a_merged_entry_stands_for_the_runs_it_merged() -> None:
    a: RunEnvironment = {"hostname": "a"}
    b: RunEnvironment = {"hostname": "b"}
    merged: RunEnvironment = {"merged_from": ["x", "y"], "environments": [a, {"environments": [b]}]}
    assert run_environments(merged) == [a, b] and run_environments(a) == [a]
