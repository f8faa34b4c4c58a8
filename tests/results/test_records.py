"""Hostile results files (issue 30, item 1): every file a reader takes goes through one validating
loader (``Store.read`` -> ``compare.results.records``), so a record of the right schema but wrong inner
types, ranges or shapes is one line naming the file, the record and the field (exit 2, nothing
written), never a traceback after ``--out`` was half rewritten.

A table of hand-made corruptions of the site's test store (tests/data/site), each fed to every
reader of its suite in this process; a property test that mutates valid files and random bytes
(a clean load followed by a successful site build, or a clean refusal); every committed store
still loads; and the picture path allocates nothing from a record's sizes that its saved arrays
do not match.
"""
from __future__ import annotations

import contextlib
import copy
import hashlib
import io
import json
import os
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import adversarial
from conftest import PUBLISHED_STORES, ROOT, published_store

from compare import cli
from compare.results.store import Store, StoreError, array_file, load_arrays, save_arrays

SITE = ROOT / "tests" / "data" / "site"
FILES = {"run": "results.json", "sweep": "sweep.json", "stress": "stress.json"}
BASE = {suite: json.loads((SITE / name).read_text()) for suite, name in FILES.items()}
DELETE = object()          # a case's value: remove the key instead


# ---- helpers ---------------------------------------------------------------------------------
def run_main(argv: list[str]) -> tuple[int, list[str]]:
    """compare.cli.main in this process: (exit status, stderr lines); an exception propagates."""
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        rc = cli.main(argv)
    return rc, [ln for ln in err.getvalue().splitlines() if ln.strip()]


def snapshot(root: Path) -> dict[str, tuple[int, int, str]]:
    return {str(p.relative_to(root)): (p.stat().st_size, p.stat().st_mtime_ns,
                                       hashlib.sha256(p.read_bytes()).hexdigest())
            for p in sorted(root.rglob("*")) if p.is_file()}


def record(doc: dict[str, Any], pick: Callable[[dict[str, Any]], bool]) -> dict[str, Any]:
    return next(r for r in doc["records"] if pick(r))


def ok(kind: str | None = None, scenario: str | None = None) -> Callable[[dict[str, Any]], Any]:
    """The first ok, timed record (of a sweep kind, of a scenario) of a file."""
    def at(doc: dict[str, Any]) -> dict[str, Any]:
        return record(doc, lambda r: r["status"] == "ok" and r.get("time") is not None
                      and (kind is None or (r.get("tags") or {}).get("sweep") == kind)
                      and (scenario is None or r["scenario"] == scenario))
    return at


def at(*path: Any) -> Callable[[dict[str, Any]], Any]:
    def get(doc: dict[str, Any]) -> Any:
        for k in path:
            doc = doc[k]
        return doc
    return get


def lr_row(doc: dict[str, Any]) -> dict[str, Any]:
    """A projectile-lr finding whose setting its page's matrix parses (added to the file)."""
    row = dict(doc["analysis"]["rows"][0], experiment="projectile-lr", setting="gd, lr=fast, contact=hard")
    doc["analysis"]["rows"].append(row)
    return row


# (case, suite, where: doc -> the object holding the field, field, new value, words of the refusal)
CASES: list[tuple[str, str, Callable[[dict[str, Any]], Any], Any, Any, str]] = [
    ("latency-number", "run", ok(), ("time", "latency"), 5, "time.latency must be an object"),
    ("throughput-median-text", "run", ok(), ("time", "throughput", "median_s"), "fast", "time.throughput.median_s"),
    ("graph-median-list", "run", ok(), ("time", "graph", "median_s"), [], "time.graph.median_s"),
    ("ok-time-null", "run", ok(), ("time",), None, "needs both time and error"),
    ("ok-error-null", "run", ok(), ("error",), None, "needs both time and error"),
    ("median-zero", "run", ok(), ("time", "median_s"), 0, "time.median_s must be a finite number > 0"),
    ("median-missing", "run", ok(), ("time", "median_s"), DELETE, "time.median_s is missing"),
    ("first-call-negative", "run", ok(), ("time", "first_call_s"), -1.0, "time.first_call_s"),
    ("repeats-fraction", "run", ok(), ("time", "repeats"), 2.5, "time.repeats must be an integer"),
    ("latency-repeats-negative", "run", ok(), ("time", "latency", "repeats"), -3, "time.latency.repeats"),
    ("wall-list", "run", ok(), ("time", "wall"), [1, 2], "time.wall must be an object"),
    ("wall-iqr-missing", "run", ok(), ("time", "wall", "iqr_s"), DELETE, "time.wall.iqr_s is missing"),
    ("n-huge", "run", ok(scenario="saxpy"), ("params", "n"), 10**30, "params: n must be in"),
    ("n-negative", "run", ok(scenario="saxpy"), ("params", "n"), -5, "params: n must be in"),
    ("n-bool", "run", ok(scenario="saxpy"), ("params", "n"), True, "params: n must be an integer"),
    ("n-beyond-json", "run", ok(scenario="saxpy"), ("params", "n"), 10**400, "params: n must be in"),
    ("dt-negative", "run", ok(scenario="particles"), ("params", "dt"), -0.1, "params: dt must be finite and in (0, 1]"),
    ("throughput-median-null", "run", ok(), ("time", "throughput", "median_s"), None, "time.throughput.median_s"),
    ("dt-text", "run", ok(scenario="particles"), ("params", "dt"), "small", "params: dt must be a number"),
    ("params-list", "run", ok(), ("params",), [1], "'params' must be an object"),
    ("ok-params-missing", "run", ok(), ("params",), DELETE, "needs its params"),
    ("work-bytes-text", "run", ok(scenario="saxpy"), ("work", "bytes"), "many", "work.bytes"),
    ("device-bytes-list", "run", ok(), ("memory", "device_bytes"), [1], "memory.device_bytes"),
    ("hw-fraction-text", "run", ok(), ("throughput", "hw_fraction"), "high", "throughput.hw_fraction"),
    ("vs-oracle-object", "run", ok(), ("error", "vs_oracle"), {"a": 1}, "error.vs_oracle"),
    ("checked-items-number", "run", ok(), ("error", "checked_items"), 5, "error.checked_items"),
    ("gradient-rel-object", "run", ok(scenario="projectile"), ("gradient", "vs_oracle_rel"), {"x": 1},
     "gradient.vs_oracle_rel"),
    ("hardware-text", "run", ok(), ("hardware",), "h100", "hardware must be an object"),
    ("hardware-copy-text", "run", ok(), ("hardware", "copy_bytes_per_s"), "fast", "hardware.copy_bytes_per_s"),
    ("load-text", "run", ok(), ("host_load_1m",), "busy", "host_load_1m"),
    ("machine-number", "run", ok(), ("machine",), 7, "machine must be a string"),
    ("scenario-unknown", "run", ok(), ("scenario",), "warp_drive", "scenario 'warp_drive' is not one"),
    ("backend-path", "run", ok(), ("backend",), "../x", "backend must be a name"),
    ("precision-unknown", "run", ok(), ("precision",), "float16", "precision must be one of"),
    ("status-unknown", "run", ok(), ("status",), "fine", "status must be one of"),
    ("ok-error-empty", "run", ok(), ("error",), {}, "error.vs_oracle is missing"),
    ("ok-tolerance-null", "run", ok(), ("error", "tolerance"), None, "error.tolerance must be a number"),
    ("stress-ok-error-empty", "stress", ok(), ("error",), {}, "error.vs_oracle is missing"),
    ("gpus-text", "run", at("runs", 0), ("gpus",), "H100", "runs[0].gpus must be a list"),
    ("gpu-driver-missing", "run", at("runs", 0, "gpus", 0), ("driver",), DELETE, "runs[0].gpus[0].driver is missing"),
    ("package-number", "run", at("runs", 0), ("packages", "numpy"), 2, "runs[0].packages.numpy must be a string"),
    ("run-hardware-number", "run", at("runs", 0), ("hardware",), 5, "runs[0].hardware must be an object"),
    ("run-copy-text", "run", at("runs", 0), ("hardware", "cuda", "copy_bytes_per_s"), "x",
     "runs[0].hardware.cuda.copy_bytes_per_s"),
    ("git-dirty-text", "run", at("runs", 0), ("git_dirty",), "yes", "runs[0].git_dirty"),
    ("command-list", "run", at("runs", 0), ("command",), ["python"], "runs[0].command must be a string"),
    ("merged-run-gpus-text", "run", at("runs", 0), ("environments",), [{"gpus": "H100"}],
     "runs[0].environments[0].gpus must be a list"),
    ("run-list", "run", at("runs"), (0,), [], "'runs' must be a list of objects"),
    ("records-object", "run", at(), ("records",), {}, "'records' must be a list"),
    ("knob-text", "sweep", ok("scaling"), ("tags", "knob"), "batch", "tags.knob must be an object"),
    ("knob-value-negative", "sweep", ok("scaling"), ("tags", "knob", "value"), -1, "tags.knob.value"),
    ("knob-name-missing", "sweep", ok("scaling"), ("tags", "knob", "name"), DELETE, "tags.knob.name"),
    ("horizon-value-null", "sweep", ok("horizon"), ("tags", "knob", "value"), None, "tags.knob.value must be"),
    ("horizon-error-null", "sweep", ok("horizon"), ("error",), None, "needs both time and error"),
    ("sweep-kind-number", "sweep", ok("scaling"), ("tags", "sweep"), 5, "tags.sweep must be a string"),
    ("scaling-rss-missing", "sweep", ok("scaling"), ("memory", "peak_host_rss_bytes"), DELETE,
     "memory.peak_host_rss_bytes is missing"),
    ("scaling-work-missing", "sweep", ok("scaling"), ("work", "gradients"), DELETE, "work.gradients is missing"),
    ("converged-reference-null", "sweep", ok("error"), ("converged", "reference"), None, "converged.reference"),
    ("converged-metric-missing", "sweep", ok("error"), ("converged", "metric"), DELETE, "converged.metric is missing"),
    ("sweep-variant-null", "sweep", ok("horizon"), ("variant",), None, "'variant'"),
    ("sweep-gpus-bad", "sweep", at("runs", 0), ("gpus", 0), "gpu", "runs[0].gpus[0] must be an object"),
    ("rows-object", "stress", at("analysis"), ("rows",), {}, "analysis.rows must be a list"),
    ("row-text", "stress", at("analysis", "rows"), (0,), "x", "analysis.rows[0] must be an object"),
    ("row-verdict-null", "stress", at("analysis", "rows", 0), ("verdict",), None, "analysis.rows[0].verdict"),
    ("row-detail-missing", "stress", at("analysis", "rows", 0), ("detail",), DELETE,
     "analysis.rows[0].detail is missing"),
    ("row-value-object", "stress", at("analysis", "rows", 0), ("value",), {"a": 1}, "analysis.rows[0].value"),
    ("series-list", "stress", at("analysis"), ("series",), [], "analysis.series must be an object"),
    ("provenance-number", "stress", at("analysis", "provenance"), ("particles-dt",), 5,
     "analysis.provenance.'particles-dt'"),
    ("provenance-backends-text", "stress", at("analysis", "provenance", "particles-dt", 0), ("backends",), "warp",
     "backends must be a list"),
    ("lr-setting-unparsable", "stress", lr_row, ("setting",), "gd, lr=fast, contact=hard",
     "the 'projectile-lr' page cannot read this finding"),
    ("stress-median-text", "stress", ok(), ("time", "median_s"), "slow", "time.median_s"),
    ("analysis-list", "stress", at(), ("analysis",), [], "'analysis' must be an object"),
]


def corrupt(suite: str, where: Callable[[dict[str, Any]], Any], field: tuple[Any, ...], value: Any) -> dict[str, Any]:
    doc = copy.deepcopy(BASE[suite])
    obj = where(doc)
    for k in field[:-1]:
        obj = obj[k]
    if value is DELETE:
        del obj[field[-1]]
    else:
        obj[field[-1]] = value
    return doc


def readers(suite: str, f: Path, tmp: Path) -> list[list[str]]:
    """Every command that reads ``f`` (a fresh --out each), or, for --resume and stress's own
    file, the directory holding it as --out."""
    own = {"run": ["saxpy", "--quick", "--backends", "numpy", "--devices", "cpu", "--resume"],
           "sweep": ["sweep", "scaling", "--quick", "--backends", "numpy", "--devices", "cpu", "--resume"],
           "stress": ["stress", "--quick", "--only", "ulps", "--backends", "numpy", "--devices", "cpu"]}[suite]
    cmds = [["report", str(f), "--out", str(tmp / "o-report")], ["site", str(f), "--out", str(tmp / "o-site")],
            [*own, "--out", str(f.parent)]]
    if suite == "sweep":
        cmds.append(["sweep", "report", str(f), "--out", str(tmp / "o-sweep")])
    if suite == "stress":
        cmds.append(["stress", "--merge", str(f), "--out", str(tmp / "o-merge")])
    return cmds


@pytest.mark.parametrize("case,suite,where,field,value,needle", CASES, ids=[c[0] for c in CASES])
def test_a_corrupted_field_is_one_line_naming_file_record_and_field(tmp_path: Path, case: str, suite: str,
                                                                   where: Any, field: tuple[Any, ...],
                                                                   value: Any, needle: str) -> None:
    store = tmp_path / "store"
    store.mkdir()
    f = store / FILES[suite]
    f.write_text(json.dumps(corrupt(suite, where, field, value)))
    with pytest.raises(StoreError, match=None) as exc:
        Store.read(f)
    assert needle in str(exc.value) and str(exc.value).startswith(f"{f}: "), str(exc.value)
    for argv in readers(suite, f, tmp_path):
        before = snapshot(tmp_path)
        rc, lines = run_main(argv)
        assert rc == 2 and len(lines) == 1 and needle in lines[0] and str(f) in lines[0], (argv, rc, lines)
        assert "Traceback" not in lines[0]
        assert snapshot(tmp_path) == before and not any(p.name.startswith("o-") for p in tmp_path.iterdir()), argv


def test_records_name_the_index(tmp_path: Path) -> None:
    doc = copy.deepcopy(BASE["run"])
    i = next(i for i, r in enumerate(doc["records"]) if r["status"] == "ok")
    doc["records"][i]["time"]["latency"] = 5
    (tmp_path / "results.json").write_text(json.dumps(doc))
    with pytest.raises(StoreError, match=rf"results.json: record {i}: time.latency must be an object, got 5$"):
        Store.read(tmp_path / "results.json")


COMMITTED = sorted({*ROOT.glob("docs/results/*/results.json"), *ROOT.glob("docs/results/*/sweep.json"),
                    *ROOT.glob("docs/results/*/stress.json"), *ROOT.glob("docs/results/*/*/sweep.json"),
                    ROOT / "tests/data/format1-sweep.json", *SITE.glob("*.json")})


@PUBLISHED_STORES       # the read test_store's tests of these files share (published_store)
@pytest.mark.parametrize("path", COMMITTED, ids=[str(p.relative_to(ROOT)) for p in COMMITTED])
def test_every_committed_store_still_loads(path: Path) -> None:
    s = published_store(path)
    assert s.records or s.analysis


# ---- the picture path: sizes come from the saved arrays, not from the record -----------------
def saxpy_store(tmp: Path, n: int, saved: int, **extra: Any) -> tuple[Path, dict[str, Any]]:
    """A run store with one ok float32 SAXPY record claiming ``n`` and arrays of ``saved`` elements."""
    rec = copy.deepcopy(ok(scenario="saxpy")(BASE["run"]))
    rec.update(precision="float32", variant="default", params={**rec["params"], "n": n, **extra})
    doc = {**BASE["run"], "records": [rec]}
    (tmp / "results.json").write_text(json.dumps(doc))
    save_arrays(tmp, rec, {"out": np.linspace(0, 1, saved, dtype=np.float32)})
    return tmp / "results.json", rec


@pytest.mark.parametrize("n,saved,extra,used", [(1000, 1000, {}, True), (2**31 - 1, 1000, {}, False),
                                                (10**8, 1000, {}, False), (1000, 999, {}, False),
                                                (1000, 1000, {"bogus": 1}, False)])
def test_saved_arrays_are_used_only_when_they_match_the_record(tmp_path: Path, n: int, saved: int,
                                                               extra: dict[str, Any], used: bool) -> None:
    """A parameter the scenario lacks loads (no reader resolves it) but keeps the arrays unused."""
    f, rec = saxpy_store(tmp_path, n, saved, **extra)
    got = load_arrays(tmp_path, Store.read(f).records[0].identity, ["out"])
    assert (got is not None) == used
    t0 = time.perf_counter()
    rc, lines = run_main(["report", str(f), "--out", str(tmp_path / "rep")])
    assert rc == 0, lines
    assert time.perf_counter() - t0 < 30 and (tmp_path / "rep" / "results.csv").is_file()
    assert (tmp_path / "rep" / "plots" / "saxpy.png").is_file() == used


def test_an_array_header_claiming_a_huge_shape_is_not_read(tmp_path: Path) -> None:
    """The header is read before the data: a small file whose header claims 2^31 elements (a
    record and arrays made to agree) is refused by the memory bound, never loaded."""
    f, rec = saxpy_store(tmp_path, 2**31 - 1, 4)
    npz = array_file(tmp_path, rec)
    import zipfile
    hdr = io.BytesIO()
    np.lib.format.write_array_header_1_0(hdr, {"descr": "<f4", "fortran_order": False, "shape": (2**31 - 1,)})
    with zipfile.ZipFile(npz, "w") as z:
        z.writestr("out.npy", np.lib.format.magic(1, 0) + hdr.getvalue() + b"\0" * 16)
    assert load_arrays(tmp_path, Store.read(f).records[0].identity, ["out"]) is None


# ---- property: mutated valid files and random bytes ----------------------------------------
def small(suite: str) -> dict[str, Any]:
    """A few records of each status and kind (a site build in about a second)."""
    doc = copy.deepcopy(BASE[suite])
    seen: dict[tuple[Any, ...], int] = {}
    keep = []
    for r in doc["records"]:
        k = (r["status"], r["scenario"], (r.get("tags") or {}).get("sweep"))
        seen[k] = seen.get(k, 0) + 1
        if seen[k] <= 2:
            keep.append(r)
    doc["records"] = keep
    if suite == "stress":
        doc["analysis"]["rows"] = doc["analysis"]["rows"][:12]
    return doc


SMALL = {suite: small(suite) for suite in FILES}


def _paths(x: Any, p: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    out = [p] if p else []
    items = x.items() if isinstance(x, dict) else enumerate(x[:4]) if isinstance(x, list) else ()
    for k, v in items:
        out += _paths(v, p + (k,))
    return out


PATHS = {suite: _paths(doc) for suite, doc in SMALL.items()}
json_values = st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=6),
                           lambda c: st.lists(c, max_size=3) | st.dictionaries(st.text(max_size=6), c, max_size=3),
                           max_leaves=6)


@st.composite
def mutated(draw: st.DrawFn) -> tuple[str, bytes]:
    suite = draw(st.sampled_from(sorted(FILES)))
    if draw(st.integers(0, 9)) == 0:
        return suite, draw(st.binary(max_size=64))
    doc = copy.deepcopy(SMALL[suite])
    for _ in range(draw(st.integers(1, 2))):
        path = draw(st.sampled_from(PATHS[suite]))
        parent = doc
        try:
            for k in path[:-1]:
                parent = parent[k]
            old = parent[path[-1]]
        except (KeyError, IndexError, TypeError):    # an earlier mutation removed it
            continue
        how = draw(st.sampled_from(("value", "delete", "type", "scale")))
        if how == "delete" and isinstance(parent, dict):
            del parent[path[-1]]
        elif how == "type":
            parent[path[-1]] = draw(st.sampled_from((None, str(old)[:8], [old], {"v": old}, 1, True)))
        elif how == "scale" and isinstance(old, (int, float)) and not isinstance(old, bool):
            parent[path[-1]] = old * draw(st.sampled_from((0, -1, 10**12, 1e-12, 1.5)))
        else:
            parent[path[-1]] = draw(json_values)
    text = json.dumps(doc)
    if draw(st.integers(0, 9)) == 0:
        text = text[: draw(st.integers(0, len(text)))]
    return suite, text.encode()


def _loads_and_builds_or_is_refused(tmp_path_factory: Any, case: tuple[str, bytes]) -> None:
    adversarial.case()
    suite, raw = case
    tmp = tmp_path_factory.mktemp("fuzz")
    f = tmp / FILES[suite]
    f.write_bytes(raw)
    try:
        Store.read(f)
    except StoreError as exc:
        msg = str(exc)
        assert "\n" not in msg and (msg.startswith(f"cannot read {f}") or msg.startswith(f"{f}: ")), msg
        return
    rc, lines = run_main(["site", str(f), "--out", str(tmp / "site")])
    assert rc == 0, lines
    assert (tmp / "site" / "index.html").is_file()


_FUZZ = dict(deadline=None, derandomize=True, database=None,
             suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


@pytest.mark.early
# a sample of the property (each example builds a site, ~0.8 s); its breadth, 200 examples of the
# same strategy, is the long tier's test_property_many_mutated_files
@settings(max_examples=5, **_FUZZ)
@given(case=mutated())
def test_property_a_mutated_file_loads_and_builds_a_site_or_is_refused(tmp_path_factory: Any,
                                                                       case: tuple[str, bytes]) -> None:
    _loads_and_builds_or_is_refused(tmp_path_factory, case)


@pytest.mark.slow                     # the long tier: more mutants of the same property
@settings(max_examples=200, **_FUZZ)
@given(case=mutated())
def test_property_many_mutated_files(tmp_path_factory: Any, case: tuple[str, bytes]) -> None:
    _loads_and_builds_or_is_refused(tmp_path_factory, case)


def test_the_loader_is_quick_on_the_largest_committed_store() -> None:
    big = max(COMMITTED, key=lambda p: p.stat().st_size)
    t0 = time.process_time()
    Store.read(big)
    assert time.process_time() - t0 < 10, f"{big}: {time.process_time() - t0:.1f} s"
    assert os.path.getsize(big) > 1e6
