"""The record's typed parts (compare.results.record_parts): attributes for readers, the same JSON back."""
from __future__ import annotations

import json
import math
from pathlib import Path

from compare.measuring import timing
from compare.results.record import Check, Memory, Record, Regime, Timing
from compare.results.record_parts import (Converged, HostFunction, HostProfile, Noise, NoiseReason, ReferenceInfo,
                                          Throughput)
from compare.results.store import Store
from scenarios.base import Precision

ROOT = Path(__file__).resolve().parents[2]


def test_a_stored_record_reads_by_attribute_and_writes_the_same_object() -> None:
    store = Store.read(ROOT / "docs" / "results" / "cpu" / "results.json")
    rec = next(r for r in store.records if r.status == "ok" and r.time and r.time.throughput)
    assert isinstance(rec.time, Timing) and isinstance(rec.time.throughput, Regime)
    assert isinstance(rec.error, Check) and isinstance(rec.memory, Memory)
    assert rec.time.throughput.median_s == rec.time["throughput"]["median_s"] > 0
    assert rec.error.tolerance == rec.error.get("tolerance") and rec.precision is Precision(rec.precision)
    raw = json.loads((ROOT / "docs" / "results" / "cpu" / "results.json").read_text())["records"]
    assert [r.to_json() for r in store.records] == raw
    assert [list(r.to_json()["time"] or {}) for r in store.records] == [list(r.get("time") or {}) for r in raw]


def test_a_part_built_in_code_keeps_its_keys_their_order_and_its_nulls() -> None:
    c = Check.from_json({"vs_oracle": 0.5, "tolerance": 1.0, "vs_reference": None, "metric": "m", "extra_fig": [1, 2],
                         "checked_items": "all"})
    assert list(c) == ["vs_oracle", "tolerance", "vs_reference", "metric", "extra_fig", "checked_items"]
    assert c.vs_reference is None and "vs_reference" in c and "reference" not in c and c.reference is None
    assert c.details == {"extra_fig": (1, 2)}
    assert c.to_json() == {"vs_oracle": 0.5, "tolerance": 1.0, "vs_reference": None, "metric": "m",
                           "extra_fig": [1, 2], "checked_items": "all"}
    assert c == {**c.to_json(), "extra_fig": (1, 2)}


def test_the_timing_protocol_returns_regimes() -> None:
    thr = timing.pipelined(lambda: None, lambda r: None, batch_s=1e-4, repeat=3, max_time=0.5)
    null = timing.null_call(lambda r: None, calls=20)
    assert isinstance(thr, Regime) and isinstance(null, Regime) and null.repeats == 20
    assert thr.k and thr.k >= 1 and list(thr)[:4] == ["median_s", "iqr_s", "min_s", "repeats"]
    t = Timing.of(first_call_s=0.1, median_s=0.01, iqr_s=0.0, min_s=0.01, repeats=3, throughput=thr)
    assert t.regime("throughput") is thr and t.regime("noise") is None and t.graph is None


def test_a_record_built_in_code_takes_parts_or_their_json() -> None:
    time = {"first_call_s": 0.1, "median_s": 0.01, "iqr_s": 0.0, "min_s": 0.01, "repeats": 3,
            "latency": {"median_s": 0.01}}
    a = Record("saxpy", "numpy", "cpu", Precision.FLOAT32, "ok", time=Timing.from_json(time))
    b = Record("saxpy", "numpy", "cpu", "float32", "ok", time=time)  # type: ignore[arg-type]
    assert a == b and isinstance(b.time, Timing) and b.time.latency and b.time.latency.median_s == 0.01
    assert b.precision is Precision.FLOAT32 and math.isnan(Timing().median_s)


def test_the_throughput_noise_and_host_profile_blocks_read_by_attribute() -> None:
    """Every stored run record: its throughput, noise and host profile are typed parts, and the
    record writes back the object it was read from."""
    path = ROOT / "docs" / "results" / "h100" / "results.json"
    store = Store.read(path)
    raw = json.loads(path.read_text())["records"]
    assert [r.to_json() for r in store.records] == raw
    judged = [r for r in store.records if r.throughput and r.throughput.hw_fraction is not None]
    assert judged and all(isinstance(r.throughput, Throughput) for r in judged)
    r = judged[0]
    assert r.throughput is not None and r.throughput.hw_fraction == r.throughput["hw_fraction"]
    assert r.throughput.floor_kind == r.throughput.get("floor_kind") and isinstance(r.throughput.floor, str)
    noisy = [r.time.noise for r in store.records if r.time and r.time.noise]
    assert noisy and all(isinstance(n, Noise) and isinstance(n.reasons, tuple) for n in noisy)
    assert all(isinstance(x, NoiseReason) and isinstance(x.why, str) for n in noisy for x in n.reasons or ())
    profiled = [r.time.host_profile for r in store.records if r.time and r.time.host_profile]
    assert profiled and all(isinstance(p, HostProfile) for p in profiled)
    assert all(isinstance(f, HostFunction) and isinstance(f.function, str) for p in profiled for f in p.top or ())


def test_a_stored_converged_block_is_the_sweeps_converged_part() -> None:
    path = ROOT / "docs" / "results" / "h100" / "sweep.json"
    store = Store.read(path)
    conv = [r.converged for r in store.records if r.converged is not None]
    assert conv and all(isinstance(c, Converged) and c.metric for c in conv)
    assert all(isinstance(c.reference, ReferenceInfo) for c in conv)
    assert [r.to_json() for r in store.records] == json.loads(path.read_text())["records"]


def test_a_converged_part_built_in_code_has_the_formats_key_order() -> None:
    info = ReferenceInfo("a note", dt=0.01, steps=300)
    c = Converged(0.5, "rms", info)
    assert json.dumps(c.to_json()) == json.dumps(
        {"error": 0.5, "metric": "rms", "reference": {"dt": 0.01, "steps": 300, "note": "a note"}})
    m = Converged.measured({"rms": 0.25, "error": 0.5}, "max", info)
    assert list(m) == ["error", "rms", "metric", "reference"] and m.figures == {"rms": 0.25}
    rec = Record("sdf", "numpy", "cpu", Precision.FLOAT64, "ok", converged=m.to_json())   # as the sweep stores it
    assert isinstance(rec.converged, Converged) and rec.converged.reference == info
    assert rec.to_json()["converged"] == m.to_json()
