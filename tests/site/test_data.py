"""compare/site/data.py: the stores of one machine and the figures of one record (fast tier)."""
from __future__ import annotations

import math
import shutil
from pathlib import Path

import pytest

from compare.results.record import Record
from compare.results.store import StoreError
from compare.running import repeats
from compare.site import data

STORE = Path(__file__).resolve().parents[2] / "tests" / "data" / "site"


def rec(scenario="saxpy", device="cuda", variant="default", **fields) -> Record:
    return Record(scenario=scenario, backend="warp", device=device, precision="float32", status="ok",
                  variant=variant, **fields)


def test_load_reads_every_suite_of_a_folder():
    m = data.load([STORE])
    assert m.run and m.sweep and m.stress is not None and m.runs
    assert m.primary_device == "cuda" and m.devices()[0] == "cuda"
    assert "H100" in m.name() and m.name() == m.gpu_name()
    assert m.records[:len(m.sweep)] == list(m.sweep)          # sweep first: the run's record wins
    assert {"warp", "jax", "cupy"} <= set(m.frameworks)


def test_load_refuses_a_folder_without_a_store(tmp_path):
    with pytest.raises(StoreError, match="no results.json"):
        data.load([tmp_path])


def test_a_bad_publish_log_is_refused(tmp_path):
    shutil.copy(STORE / "results.json", tmp_path)
    (tmp_path / data.PUBLISH_LOG).write_text('{"parts": 3}')
    with pytest.raises(StoreError, match="not a publish log"):
        data.load([tmp_path])
    (tmp_path / data.PUBLISH_LOG).write_text('{"parts": []}')
    assert data.load([tmp_path]).publish == {"parts": []}


@pytest.mark.parametrize("x,expected", [(1, 1.0), (2.5, 2.5), (True, None), ("nan", None), (math.inf, None),
                                        (None, None)])
def test_num_is_a_finite_float_or_none(x, expected):
    assert data.num(x) == expected


def test_timing_of_one_process_is_the_median_and_its_quartiles():
    t = data.timing(rec(time={"median_s": 2e-6, "iqr_s": 1e-6, "repeats": 50,
                              "latency": {"median_s": 2e-6, "iqr_s": 1e-6, "repeats": 50}}), "latency")
    assert (t.median, t.repeats, t.processes, t.ci) == (2e-6, 50, 1, None)
    assert (t.lo, t.hi) == pytest.approx((1.5e-6, 2.5e-6))
    assert data.timing(rec(), "latency") is None
    assert data.timing(rec(time={"first_call_s": 0.5}), "first").median == 0.5


def test_first_result_is_setup_plus_first_call_or_nothing():
    assert data.first_result(rec(time={"setup_s": 1.0, "first_call_s": 0.25})).median == 1.25
    assert data.first_result(rec(time={"first_call_s": 0.25})) is None


def processes(lo, hi, n=6):
    cover = repeats.interval([float(i) for i in range(n)])[2]
    return {"median_s": 1e-3, "iqr_s": 0, "processes": {"count": n, "latency": {
        "values": [1e-3] * n, "median_s": 1e-3, "ci_lo_s": lo, "ci_hi_s": hi, "confidence": cover}}}


def test_across_processes_gives_an_interval_and_flags_a_wide_one():
    t = data.timing(rec(time=processes(0.95e-3, 1.05e-3)), "latency")
    assert t.processes == 6 and t.ci == (0.95e-3, 1.05e-3) and not t.noisy
    wide = data.timing(rec(time=processes(0.5e-3, 1.05e-3)), "latency")
    assert "processes disagree" in wide.noisy
    two = data.timing(rec(time=processes(0.99e-3, 1.01e-3, n=2)), "latency")
    assert two.ci is None and "confidence" in two.noisy           # too few processes: no interval
    assert data.process_count(rec(time=processes(0.9e-3, 1.1e-3))) == 6 and data.process_count(rec()) == 1


def test_per_call_counts_a_graph_variant_in_every_regime():
    """A framework's own graph variant is a launch path its user writes: it counts on every row
    (docs/ports.md), its pipelined calls standing for the replay the harness cannot capture."""
    t = {"median_s": 1e-3, "iqr_s": 0, "latency": {"median_s": 1e-3, "iqr_s": 0},
         "throughput": {"median_s": 4e-4, "iqr_s": 0}}
    assert data.per_call(rec(variant="graph", time=t), "graph").median == 4e-4
    assert data.per_call(rec(variant="graph", time=t), "latency").median == 1e-3
    assert data.per_call(rec(time=t), "throughput").median == 4e-4


def test_size_and_defaults():
    assert data.size(rec(params={"n": 10})) == 10.0 and data.size(rec(params={"batch": 4})) == 4.0
    assert data.size(rec("sdf", params={"width": 8, "height": 4})) == 32.0 and data.size(rec()) == 0.0
    d = data.defaults("saxpy")
    assert d and data.at_defaults(rec(params=d)) and data.at_defaults(rec(params={}))
    assert not data.at_defaults(rec(params={**d, "n": d["n"] + 1}))
    assert data.defaults("no-such-scenario") == {}


def test_l2_is_the_records_then_the_runs_then_the_stated_bound():
    r = rec(hardware={"l2_bytes": 50e6})
    assert data.l2_bytes(r) == (50e6, "l2_bytes")
    assert data.l2_bytes(rec(), [{"gpus": [{"name": "x", "l2_cache_size": 40e6}]}]) == (40e6, "l2_cache_size")
    assert data.l2_bytes(rec(), [{"gpus": [{"name": "NVIDIA H100 80GB"}]}])[0] == data.L2_BOUND["H100"]
    assert data.l2_bytes(rec(), []) is None and data.l2_bytes(rec(device="cpu", hardware={"l2_bytes": 1})) is None


@pytest.mark.parametrize("fraction,work,device,label", [
    (0.8, 1e6, "cuda", "cache"),           # fits the L2
    (0.8, 1e9, "cuda", ""),                # a plain fraction
    (1.1, 1e9, "cuda", "above copy"),      # beyond the L2 and above the copy
    (1.1, None, "cuda", "cache"),          # above the copy, working set unknown
    (1.1, 1e9, "cpu", "above copy"),
])
def test_fraction_label(fraction, work, device, label):
    r = rec(device=device, throughput={"hw_fraction": fraction}, work={"bytes": work} if work else {},
            hardware={"l2_bytes": 50e6} if device == "cuda" else None)
    assert data.fraction_label(r) == label
    assert data.fraction_label(rec()) == ""


@pytest.mark.parametrize("cpu,cores,name", [
    ("Intel(R) Xeon(R) Processor", 2, "Intel Xeon (2 cores)"),
    ("AMD EPYC", 2, "AMD EPYC (2 cores)"),
    ("Intel(R) Core(TM) i7-8700 CPU @ 3.20GHz", 12, "Intel Core i7-8700 CPU @ 3.20GHz (12 cores)"),
    ("AMD Ryzen 9 7950X 16-Core Processor", 32, "AMD Ryzen 9 7950X 16-Core (32 cores)"),
])
def test_the_cpu_is_named_without_trademark_signs(cpu, cores, name):
    m = data.Machine((), (), (), None, ({"cpu": cpu, "cores": cores},), None)
    assert m.cpu_name() == name and m.name() == name       # the default title of a CPU store


def test_floors_are_the_figure_over_its_own_runs_launch_floor():
    """Latency over the run's launch + synchronise, pipelined calls over its pipelined launch; graph
    replay has no such unit; a record without a yardstick (or with a null or zero floor) none."""
    one = lambda m: {"median_s": m, "iqr_s": m / 10, "repeats": 50}  # noqa: E731
    time = {**one(30e-6), "latency": one(30e-6), "throughput": {**one(12e-6), "k": 100}, "graph": one(5e-6)}
    r = rec(time=time, hardware={"launch_latency_s": 10e-6, "launch_pipelined_s": 4e-6})
    assert data.floors(r, "latency") == pytest.approx(3.0)
    assert data.floors(r, "throughput") == pytest.approx(3.0)
    assert data.floors(r, "graph") is None
    assert data.floors(rec(time=time), "latency") is None
    assert data.floors(rec(time=time, hardware={"launch_latency_s": None, "launch_pipelined_s": 0.0}), "latency") is None
    assert data.floors(rec(time=time, hardware={"launch_pipelined_s": 0.0}), "throughput") is None
    assert data.floors(rec(hardware={"launch_latency_s": 10e-6}), "latency") is None     # nothing timed


def test_a_cells_own_floor_is_the_divisor_where_the_record_has_one():
    """``cell_floor.before`` (probed beside the cell) wins over the run's yardstick, per regime; a
    probe without that figure (failed, cut short) leaves the run's yardstick; ``after`` never divides."""
    one = lambda m: {"median_s": m, "iqr_s": m / 10, "repeats": 50}  # noqa: E731
    time = {**one(30e-6), "latency": one(30e-6), "throughput": {**one(12e-6), "k": 100}}
    hw = {"launch_latency_s": 10e-6, "launch_pipelined_s": 4e-6}
    own = {"before": {"latency_s": 15e-6, "pipelined_s": 6e-6}, "after": {"latency_s": 1e-6, "pipelined_s": 1e-6}}
    r = rec(time=time, hardware=hw, cell_floor=own)
    assert data.floor_of(r, "latency") == (15e-6, True) and data.floor_of(r, "throughput") == (6e-6, True)
    assert data.floors(r, "latency") == pytest.approx(2.0) and data.floors(r, "throughput") == pytest.approx(2.0)
    assert data.own_floor(r, "latency") and not data.own_floor(r, "graph") and not data.own_floor(None, "latency")
    half = rec(time=time, hardware=hw, cell_floor={"before": {"latency_s": 15e-6, "error": "cut"}})
    assert data.floor_of(half, "latency") == (15e-6, True) and data.floor_of(half, "throughput") == (4e-6, False)
    failed = rec(time=time, hardware=hw, cell_floor={"before": {"error": "OSError: no driver"}, "after": None})
    assert data.floors(failed, "latency") == pytest.approx(3.0) and not data.own_floor(failed, "latency")
    # a cell's own floor without a run's yardstick still gives the unit; neither: none
    assert data.floors(rec(time=time, cell_floor=own), "throughput") == pytest.approx(2.0)
    assert data.floor_of(rec(time=time), "latency") is None
