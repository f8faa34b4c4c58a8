"""compare/suites/stress_context.py: the cells, rows and lanes every stress experiment gets."""
from __future__ import annotations

import numpy as np
import pytest

import scenarios
from backends.base import Device
from compare.results.record import Record
from compare.spec import Cell
from compare.stress.numerics import Row
from compare.stress.projectile_tasks import Task
from compare.suites import stress_context as context
from compare.suites.stress_context import Ctx, lane
from scenarios.base import ParamError, Precision


def test_spec_is_a_cell_timed_once_with_warm_caches():
    """Stress figures are not timings: the first call and one timed call, no warm-ups, kernel
    caches warm, the wall clock, no throughput regime; the overrides resolved by the scenario."""
    cell = Ctx.spec("particles", "numpy", "cpu", "float32", {"n": 16, "steps": 40, "bounce": 1.05})
    assert isinstance(cell, Cell)
    assert (cell.warmup, cell.repeat, cell.min_time, cell.cache, cell.timer, cell.throughput) == \
        (0, 1, 0.0, "warm", "wall", False)
    assert cell.device is Device.CPU and cell.precision is Precision.FLOAT32 and cell.variant == "default"
    assert cell.params == scenarios.get("particles").params({"n": 16, "steps": 40, "bounce": 1.05})
    assert (cell.params.n, cell.params.steps, cell.params.bounce) == (16, 40, 1.05)


def test_spec_is_the_cell_the_engine_made_of_the_old_spec_dict():
    """The dict the suite used to hand the engine decodes to the same cell: nothing run changes."""
    params = {"contact": "hard", "lr": 0.08, "iters": 20}
    old = {"scenario": "projectile", "backend": "numba", "device": "cpu", "precision": "float32",
           "variant": "default", "params": params, "quick": False, "warmup": 0, "repeat": 1, "min_time": 0.0,
           "cache": "warm", "timer": "wall", "throughput": False}
    new = Ctx.spec("projectile", "numba", "cpu", "float32", params)
    assert Cell.from_dict(old) == new and new.key() == Cell.from_dict(old).key()


def test_spec_refuses_an_unknown_parameter():
    with pytest.raises(ParamError, match="unknown parameter"):
        Ctx.spec("particles", "numpy", "cpu", "float32", {"nope": 1})


def test_row_makes_plain_values_and_strings():
    row = Ctx.row("e", "numpy", Device.CPU, Precision.FLOAT64, "s", "f", np.float32(0.5), "ok", None)
    assert row == Row("e", "numpy", "cpu", "float64", "s", "f", 0.5, "ok", "")
    assert type(row.value) is float and type(row.device) is str and type(row.precision) is str
    assert type(Ctx.row("e", "b", "cpu", "-", "s", "f", np.int64(3), "ok").value) is int


def test_a_skipped_row_names_its_reason():
    probes = {"numpy": {"available": {"cpu": None, "cuda": "no CUDA device"}}}
    ctx = Ctx(["numpy"], ["cpu", "cuda"], True, 1, 1.0, probes)
    assert ctx.skip_rows("races") == [Row("races", "numpy", "cuda", "-", "-", "-", None, "skipped",
                                          "no CUDA device")]
    assert ctx.targets() == [("numpy", "cpu", "default")]


def test_label_and_error_row_of_a_cell():
    cell = Ctx.spec("saxpy", "numba", "cpu", "float32", {"n": 64}, "fastmath")
    assert Ctx.label(cell) == "numba/cpu/fastmath"
    assert Ctx.label(Ctx.spec("saxpy", "numba", "cpu", "float32", {"n": 64})) == "numba/cpu"
    rec = Record("saxpy", "numba", "cpu", "float32", "error", variant="fastmath", reason="worker died")
    ctx = Ctx(["numba"], ["cpu"], True, 1, 1.0, {})
    assert ctx.error_row("ulps", cell, "saxpy", rec) == Row("ulps", "numba", "cpu", "float32", "saxpy", "cell",
                                                            None, "error", "worker died")


def test_lanes_keep_one_gpu_item_per_backend_and_let_cpu_items_overlap():
    gpu_cell = Ctx.spec("saxpy", "numba", "cuda", "float32", {"n": 64})
    assert lane(gpu_cell) == ("numba", "cuda") and lane(Ctx.spec("saxpy", "numba", "cpu", "float32", {})) is None
    assert lane(("warp", "cuda", "default", "float32")) == ("warp", "cuda") and lane(("warp", "cpu")) is None
    task = Task("scan", "torch", "cuda", "float32", ("hard",), 60.0, scans={"s": [6.5]})
    assert lane(task) == ("torch", "cuda")
    assert lane(Task("scan", "oracle64", "host", "float64", ("hard",), 60.0)) is None


def test_pool_map_runs_one_gpu_item_per_backend_at_a_time():
    import threading
    import time
    ctx = context.Ctx(["a", "b"], ["cpu", "cuda"], True, 8, 1.0, {})
    items = [(b, d, str(i)) for i in range(4) for b in ("a", "b") for d in ("cpu", "cuda")]
    busy: dict = {}
    peak: dict = {}
    lock = threading.Lock()

    def fn(it):
        key = it[:2]
        with lock:
            busy[key] = busy.get(key, 0) + 1
            peak[key] = max(peak.get(key, 0), busy[key])
        time.sleep(0.02)
        with lock:
            busy[key] -= 1
        return it[2]

    assert ctx.map(fn, items) == [it[2] for it in items]    # order kept
    assert peak[("a", "cuda")] == peak[("b", "cuda")] == 1
    assert peak[("a", "cpu")] > 1                                          # CPU items overlap


def test_targets_leave_out_variants_the_framework_lacks_on_a_device_and_say_why():
    """A variant a backend declares unavailable on a device (a capability, e.g. graphs on CUDA
    only) is no target there: its stress rows are 'skipped' with the reason, never CRASHED."""
    import backends
    limited = [(b, v, d) for b, be in backends.BACKENDS.items() for v in be.variants for d in ("cpu", "cuda")
               if be.variant_unavailable(v, d)]
    if not limited:
        pytest.skip("no backend declares a variant unavailable on a device")
    b, v, d = limited[0]
    probes = {b: {"available": {"cpu": None, "cuda": None}}}
    ctx = context.Ctx([b], [d], True, 1, 1.0, probes)
    assert (b, d, v) not in ctx.targets(variants=True) and (b, d, "default") in ctx.targets(variants=True)
    skips = ctx.skip_rows("ulps", variants=True)
    assert [(r.backend, r.device, r.setting, r.verdict) for r in skips] == [(b, d, f"variant={v}", "skipped")]
    assert skips[0].detail == backends.get(b).variant_unavailable(v, d)
    assert ctx.skip_rows("ulps") == []


def test_precisions_a_framework_lacks_on_a_device_are_skipped_rows_not_errors():
    """A precision a backend declares unavailable on a device (MLX: no float64 on a GPU) is never
    asked for there: the experiments take ``ctx.precisions`` and skip_rows says why, once per
    backend, device and precision."""
    import backends
    limited = [(b, p, d) for b, be in backends.BACKENDS.items() for p in ("float32", "float64")
               for d in ("cpu", "cuda") if be.precision_unavailable(p, d)]
    if not limited:
        pytest.skip("no backend declares a precision unavailable on a device")
    b, p, d = limited[0]
    probes = {b: {"available": {"cpu": None, "cuda": None}}}
    ctx = context.Ctx([b], [d], False, 1, 1.0, probes)
    both = ("float32", "float64")
    assert p not in ctx.precisions(b, d, both) and len(ctx.precisions(b, d, both)) == 1
    skips = ctx.skip_rows("particles-dt", precisions=both)
    assert [(r.backend, r.device, r.precision, r.verdict) for r in skips] == [(b, d, p, "skipped")]
    assert skips[0].detail == backends.get(b).precision_unavailable(p, d)
    assert ctx.skip_rows("particles-dt") == []
