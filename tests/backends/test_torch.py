"""PyTorch-specific checks beyond the generic parity suite: the cell's dtype holds whatever torch's
global default dtype is, TF32 is off and recorded, the compile variant computes what eager
computes, v0/target are replaced in place, a missing torch is a skip naming the install command,
the CUDA-only variants (compile_graphs, particles' graph) compute what their ungraphed twins do,
and (on CUDA) graph replays and events."""
from __future__ import annotations

import importlib.metadata
import sys

import numpy as np
import pytest

import backends
import scenarios
from compare.running import engine
from compare.spec import Cell
from conftest import require_device

pytestmark = pytest.mark.torch

SMALL = {"saxpy": {"n": 257, "inputs": "random", "seed": 3}, "sdf": {"width": 5, "height": 3},
         "particles": {"n": 33, "steps": 57, "record_every": 7},
         "projectile": {"contact": "soft", "steps": 20, "iters": 2, "batch": 5}}
# compile against eager, float64: the forward is the same elementwise arithmetic; the compiled
# backward (AOTAutograd/Inductor) may order the adjoint's products differently, so the projectile
# gets the parity suite's float64 level (scenario distance: loss and gradient).
TIGHT = {"saxpy": 0.0, "sdf": 1e-13, "particles": 0.0, "projectile": 1e-12}

_cells: dict = {}


def _spec(scenario, precision, variant, device="cpu"):
    return {"scenario": scenario, "backend": "torch", "device": device, "precision": precision,
            "variant": variant, "params": SMALL[scenario], "quick": True, "repeat": 1,
            "min_time": 0.0, "cache": "warm", "throughput": False}


def cells(precision, variant, device="cpu"):
    """Every SMALL scenario of one precision and variant, in one worker process (cached)."""
    require_device("torch", device)
    key = (precision, variant, device)
    if key not in _cells:
        specs = [_spec(s, precision, variant, device) for s in SMALL]
        results = engine.run_cells([Cell.from_dict(s) for s in specs], timeout=900, share_process=True)
        _cells[key] = dict(zip(SMALL, results))
    return _cells[key]


def _torch():
    require_device("torch", "cpu")
    import torch
    return torch


@pytest.mark.xdist_group("torch-cells")            # cells()' cache: its cells run once
@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_outputs_have_the_cells_precision_and_tf32_is_recorded_off(precision):
    for scenario, (record, outputs) in cells(precision, "default").items():
        assert record.status == "ok", (scenario, record.reason, record.traceback or "")
        assert {k: v.dtype for k, v in outputs.items()} == {k: np.dtype(precision) for k in outputs}
        info = record.info
        assert info["tf32_matmul"] is False and info["tf32_cudnn"] is False, info
        assert info["float32_matmul_precision"] == "highest"
        # the installed build (the metadata may drop the local tag, e.g. +cu130)
        assert record.versions["torch"].split("+")[0] == importlib.metadata.version("torch").split("+")[0]
        # an eager cell neither imports Inductor (seconds a cell) nor reports its switches
        assert "inductor_division_rounding" not in info and "dynamo_fail_on_recompile_limit_hit" not in info


@pytest.mark.parametrize("default", ["float64", "float32"])
def test_global_default_dtype_does_not_leak_into_a_cell(default):
    """Kernels set every dtype themselves: with torch's default dtype set to the other precision,
    a float32 cell still computes in float32 and a float64 cell in float64 (not widened)."""
    torch = _torch()
    b = backends.get("torch")
    sc = scenarios.get("projectile")
    precision = "float32" if default == "float64" else "float64"
    before = torch.get_default_dtype()
    torch.set_default_dtype(getattr(torch, default))
    try:
        b.setup("cpu", precision, "default")
        p = sc.params(SMALL["projectile"], quick=True)
        k = b.kernel("projectile")(p, sc.inputs(p, precision), "cpu", precision, "default")
        k.run()
        want = getattr(torch, precision)
        assert {t.dtype for t in (k.v, k.history, k.grad0, *k.c.values())} == {want}
        out = k.outputs()
    finally:
        torch.set_default_dtype(before)
    assert all(a.dtype == np.dtype(precision) for a in out.values())
    if precision == "float64":        # computed in float64, not float32 widened afterwards
        assert np.any(out["grad"] != out["grad"].astype(np.float32).astype(np.float64))
    assert sc.check(p, sc.inputs(p, precision), out, sc.oracle(p, sc.inputs(p, precision), precision), precision).ok


@pytest.mark.xdist_group("torch-cells")
def test_compile_variant_equals_eager():
    eager, comp = cells("float64", "default"), cells("float64", "compile")
    for scenario, (record, outputs) in comp.items():
        assert record.status == "ok", (scenario, record.reason, record.traceback or "")
        assert record.info["execution"].startswith("torch.compile(mode='default'")
        assert record.info["inductor_division_rounding"] is True     # IEEE division in Triton
        assert record.info["dynamo_fail_on_recompile_limit_hit"] is True   # no silent eager
        sc = scenarios.get(scenario)
        p = sc.params(SMALL[scenario], quick=True)
        ref = eager[scenario][1]
        d = sc.distance(p, sc.inputs(p, "float64"), outputs, ref)
        assert d <= TIGHT[scenario], f"{scenario}: compile vs eager differ by {d:.3g}"
        if TIGHT[scenario] == 0.0:
            assert all(outputs[k].tobytes() == ref[k].tobytes() for k in ref), scenario


def test_set_input_replaces_v0_and_target_in_place():
    torch = _torch()
    b = backends.get("torch")
    b.setup("cpu", "float64", "default")
    sc = scenarios.get("projectile")
    p = sc.params(SMALL["projectile"], quick=True)
    inputs = sc.inputs(p, "float64")
    k = b.kernel("projectile")(p, inputs, "cpu", "float64", "default")
    k.run()
    before = k.outputs()
    ptr = (k.v0.data_ptr(), k.target.data_ptr())
    new = {"v0": inputs["v0"] * 0.9, "target": inputs["target"] + 0.25}
    for name, value in new.items():
        k.set_input(name, value)
    k.run()
    assert (k.v0.data_ptr(), k.target.data_ptr()) == ptr          # the same tensors
    fresh = b.kernel("projectile")(p, {**inputs, **new}, "cpu", "float64", "default")
    fresh.run()
    got, want = k.outputs(), fresh.outputs()
    assert all(got[n].tobytes() == want[n].tobytes() for n in want)
    assert not np.any(got["loss"] == before["loss"])                  # it did change
    with pytest.raises(ValueError):
        k.set_input("v0", np.zeros((3, 2)))
    assert torch.is_tensor(k.v0)


def test_missing_torch_is_a_skip_naming_the_install_command(monkeypatch):
    monkeypatch.setitem(sys.modules, "torch", None)      # import torch -> ImportError
    avail = backends.get("torch").available()
    assert set(avail) == set(backends.DEVICES)
    for device, why in avail.items():
        assert why and "torch not importable" in why and "pip install -e '.[torch]'" in why, (device, why)


@pytest.mark.parametrize("gpus", [0, 1])
def test_the_install_hint_names_the_cpu_wheel_only_without_a_gpu(monkeypatch, gpus):
    """A bare `pip install torch` on a machine without an NVIDIA GPU pulls several GB of CUDA
    libraries: there the hint names PyTorch's CPU wheel first."""
    import backends.torch as bt
    monkeypatch.setitem(sys.modules, "torch", None)
    monkeypatch.setattr(bt, "visible_gpus", lambda: gpus)
    why = backends.get("torch").available()["cpu"]
    assert ("download.pytorch.org/whl/cpu" in why) == (gpus == 0), why
    assert why.endswith("pip install -e '.[torch]')"), why


def test_cpu_has_no_graph_capture_or_events():
    _torch()
    b = backends.get("torch")
    assert b.capture("cpu", lambda: None) is None
    assert b.event_timer("cpu") is None
    assert b.memory("cpu") == {}


def test_cuda_graph_replays_and_events_reproduce_eager():
    """CUDA: a captured run() replayed gives the eager outputs (v0 replaced in place between
    replays is seen), events time a call, and the allocator's peak is reported."""
    require_device("torch", "cuda")
    import torch
    b = backends.get("torch")
    b.setup("cuda", "float32", "default")
    sc = scenarios.get("projectile")
    p = sc.params({**SMALL["projectile"], "contact": "hard"}, quick=True)
    inputs = sc.inputs(p, "float32")
    k = b.kernel("projectile")(p, inputs, "cuda", "float32", "default")
    k.run()
    b.synchronize("cuda", None)
    eager = k.outputs()
    replay = b.capture("cuda", k.run)
    k.set_input("v0", inputs["v0"] * 0.5)
    replay()
    b.synchronize("cuda", None)
    moved = k.outputs()
    k.set_input("v0", inputs["v0"])
    timer = b.event_timer("cuda")
    timer.start(); replay(); timer.stop()
    b.synchronize("cuda", None)
    assert timer.elapsed_s() > 0
    again = k.outputs()
    assert all(again[n].tobytes() == eager[n].tobytes() for n in eager)
    assert not np.array_equal(moved["grad"], eager["grad"])
    assert b.memory("cuda")["device_peak_bytes"] > 0
    assert torch.backends.cuda.matmul.allow_tf32 is False


def test_graph_variants_are_cuda_only():
    b = backends.get("torch")
    for variant in ("compile_graphs", "graph"):
        assert "CUDA only" in b.variant_unavailable(variant, "cpu")
        assert b.variant_unavailable(variant, "cuda") is None
    assert b.variant_unavailable("compile", "cpu") is None
    assert "graph" in b.variants_for("particles") and "graph" not in b.variants_for("saxpy")
    assert "compile_graphs" in b.variants_for("projectile")


def test_rollout_blocks_split_at_frames():
    from backends.torch.particles import runs
    assert runs(57, 7, 25) == [(7, True)] * 8 + [(1, False)]
    assert runs(57, 0, 25) == [(25, False), (25, False), (7, False)]
    assert runs(60, 30, 25) == [(25, False), (5, True)] * 2
    assert runs(5, 9, 25) == [(5, False)]
    assert sum(n for n, _ in runs(300, 0, 25)) == 300


def test_long_rollouts_compile_a_few_segments_cut_at_frames():
    """A compiled rollout's calls cover its blocks in order, each at most SEGMENT steps of whole
    frame intervals, so however many steps it runs only a few distinct segments compile; the
    default rollout (300 steps) is one call."""
    from backends.torch.particles import BLOCK, SEGMENT, runs, segments
    assert segments(runs(300, 0, BLOCK), SEGMENT) == [runs(300, 0, BLOCK)]
    assert segments([], SEGMENT) == [[]]
    for steps, every in [(19405, 0), (6669, 0), (2400, 70), (1000, 400), (57, 7), (5, 9)]:
        plan = runs(steps, every, BLOCK)
        parts = segments(plan, SEGMENT)
        assert [e for p in parts for e in p] == plan
        assert len({tuple(p) for p in parts[1:]}) <= 2, (steps, every)       # the first, a full one, the last
        for p in parts:
            assert sum(n for n, _ in p) <= max(SEGMENT, every)
            assert not every or p is parts[-1] or p[-1][1]                    # ends on a kept frame
    assert [sum(n for n, _ in p) for p in segments(runs(2400, 70, BLOCK), SEGMENT)] == [280] * 8 + [160]


@pytest.mark.parametrize("segment", [300, 20])
@pytest.mark.parametrize("params", [{"n": 33, "steps": 57, "record_every": 7}, {"n": 33, "steps": 57}])
def test_compile_graphs_arithmetic_equals_eager_on_the_cpu(params, segment, monkeypatch):
    """The compile_graphs kernels built on the CPU (where reduce-overhead has nothing to graph, so
    the cell itself is unavailable) run the compiled rollout's arithmetic: blocks of several
    lengths (25, 7 and 1 steps), frames between them, in one compiled call or (SEGMENT 20) in
    several, the state cloned between them, the default's results bit for bit."""
    _torch()
    monkeypatch.setattr("backends.torch.particles.SEGMENT", segment)
    out, k = particle_runs(params, "cpu", "float64", ("default", "compile_graphs"), runs=2)
    assert k.info()["execution"].startswith("torch.compile(mode='reduce-overhead'")
    assert ("host loop over" in k.info()["loop"]) is (segment == 20)
    assert same_arrays(out["compile_graphs"][-1], out["default"][-1])


def particle_runs(params, device, precision, variants, runs):
    """Each variant's particle outputs after each of ``runs`` runs of one kernel, and the last
    variant's kernel."""
    b = backends.get("torch")
    sc = scenarios.get("particles")
    p = sc.params(params, quick=True)
    inputs = sc.inputs(p, precision)
    out = {}
    for variant in variants:
        b.setup(device, precision, variant)
        k = b.kernel("particles")(p, inputs, device, precision, variant)
        out[variant] = []
        for _ in range(runs):
            k.run()
            out[variant].append(k.outputs())
    return out, k


def same_arrays(a, b):
    return sorted(a) == sorted(b) and all(a[n].tobytes() == x.tobytes() for n, x in b.items())


@pytest.mark.parametrize("params", [{"n": 33, "steps": 57, "record_every": 7}, {"n": 33, "steps": 57}])
def test_cuda_compiled_segments_replay_as_graphs_and_compute_what_compile_computes(params, monkeypatch):
    """CUDA: a rollout of several compiled segments (SEGMENT 20) under compile_graphs, each output
    cloned out of the graphs' pool before the next replay, gives the compile variant's results bit
    for bit at every run, with no graph skipped."""
    require_device("torch", "cuda")
    monkeypatch.setattr("backends.torch.particles.SEGMENT", 20)
    out, k = particle_runs(params, "cuda", "float32", ("compile", "compile_graphs"), runs=3)  # warm-up, record, replay
    assert "host loop over" in k.info()["loop"] and k.info()["cudagraph_skips"] == 0
    assert all(same_arrays(got, want) for got, want in zip(out["compile_graphs"], out["compile"]))


def test_cuda_graph_variants_compute_what_their_twins_compute():
    """CUDA: compile_graphs replays Inductor's kernels as CUDA graphs (none skipped: a skip is an
    error there) and gives the compile variant's outputs bit for bit; particles' graph replays the
    eager rollout and gives the default's; neither lets the harness capture a graph around it."""
    require_device("torch", "cuda")
    specs = [(s, v) for s in ("saxpy", "particles", "projectile") for v in ("compile", "compile_graphs")]
    specs += [("particles", "default"), ("particles", "graph")]
    results = engine.run_cells([Cell.from_dict(_spec(s, "float32", v, "cuda")) for s, v in specs],
                               timeout=900, share_process=True)
    got = {}
    for (scenario, variant), (record, outputs) in zip(specs, results):
        assert record.status == "ok", (scenario, variant, record.reason, record.traceback or "")
        got[scenario, variant] = outputs
        if variant == "compile_graphs":
            assert record.info["execution"].startswith("torch.compile(mode='reduce-overhead'")
            assert record.info["cudagraph_skips"] == 0
    for scenario, graphed, twin in [("saxpy", "compile_graphs", "compile"), ("particles", "compile_graphs", "compile"),
                                    ("projectile", "compile_graphs", "compile"), ("particles", "graph", "default")]:
        a, b = got[scenario, graphed], got[scenario, twin]
        assert sorted(a) == sorted(b) and all(a[n].tobytes() == b[n].tobytes() for n in b), (scenario, graphed)
    b = backends.get("torch")
    b.setup("cuda", "float32", "graph")
    sc = scenarios.get("particles")
    p = sc.params(SMALL["particles"], quick=True)
    k = b.kernel("particles")(p, sc.inputs(p, "float32"), "cuda", "float32", "graph")
    with pytest.raises(RuntimeError, match="replays CUDA graphs itself"):
        b.capture("cuda", k.run)
