"""NumPy-specific checks beyond the generic parity suite.

1. ``run()`` allocates nothing that grows with the problem, at most NumPy's fixed iterator buffer
   (tracemalloc sees NumPy's data buffers; a control shows the probe catches an expression
   without ``out=``);
2. float32 is computed in float32: bit for bit Warp's float32 output where no transcendental is
   involved (a float64 computation rounded once would differ), not the float64 result rounded;
3. the batched projectile: every row equals the single-trajectory run at its own inputs bit for
   bit, and ``set_input`` reruns at the new inputs.
"""
from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

import backends
import scenarios
from conftest import require_device, shared_cell

pytestmark = pytest.mark.numpy

BACKEND = backends.get("numpy")


def build(scenario: str, overrides: dict, precision: str, inputs: dict | None = None):
    sc = scenarios.get(scenario)
    p = sc.params(overrides)
    inputs = sc.inputs(p, precision) if inputs is None else inputs
    k = BACKEND.kernel(scenario)(p, inputs, "cpu", precision, "default")
    k.run()
    return sc, p, inputs, k


def traced_peak(fn) -> int:
    """Peak bytes allocated (and traced) while ``fn`` runs."""
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        fn()
        return tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()


# ---- 1. no allocations in run() ----------------------------------------------------------------
LARGE = {"saxpy": {"n": 1 << 20}, "sdf": {"width": 512, "height": 512},
         "particles": {"n": 1 << 16, "steps": 4, "record_every": 2},
         "projectile-none": {"contact": "none", "batch": 1 << 16, "steps": 6, "iters": 2},
         "projectile-hard": {"contact": "hard", "batch": 1 << 16, "steps": 6, "iters": 2},
         "projectile-soft": {"contact": "soft", "batch": 1 << 16, "steps": 6, "iters": 2},
         "launch": {"n": 1 << 20}, "copy": {"n": 1 << 20}}
SMALL_BYTES = 16 * 1024      # views and Python objects
# A ufunc over broadcast operands (the SDF's row x column terms) runs through NumPy's iterator,
# which allocates a fixed buffer of np.getbufsize() elements per operand, whatever the array size.
ITER_BUFFER = 2 * np.getbufsize() * 8


@pytest.mark.parametrize("case", list(LARGE))
def test_run_allocates_nothing_large(case: str) -> None:
    *_, k = build(case.split("-")[0], LARGE[case], "float64")        # warm: first call done
    peak = traced_peak(k.run)
    data = sum(a.nbytes for a in k.outputs().values())
    assert data >= 8 * (SMALL_BYTES + ITER_BUFFER), "outputs must dwarf the bound"
    assert peak < SMALL_BYTES + ITER_BUFFER, f"{case}: run() allocated {peak} bytes"


def test_allocation_probe_sees_numpy_temporaries() -> None:
    """The probe above is meaningful: a*x + y without out= allocates two n-element arrays."""
    x = y = np.ones(1 << 20)
    assert traced_peak(lambda: 2.5 * x + y) >= x.nbytes


# ---- 2. float32 stays float32 ------------------------------------------------------------------
F32_VS_WARP = [("saxpy", {"n": 4097, "inputs": "random", "seed": 3}),
               ("particles", {"n": 33, "steps": 57, "record_every": 7}),
               ("projectile", {"contact": "none"}), ("projectile", {"contact": "hard", "batch": 5})]


@pytest.mark.xdist_group("numpy-cells")        # with the parity suite's numpy cells (conftest.run_cases)
@pytest.mark.parametrize("scenario,overrides", F32_VS_WARP, ids=[f"{s}-{o}" for s, o in F32_VS_WARP])
def test_float32_is_warps_float32_bit_for_bit(scenario: str, overrides: dict) -> None:
    """Same operations in the same order in float32: identical bits to Warp on the CPU (only the
    SDF's sin/exp and the soft contact's exp/log, NumPy's own SIMD float32 functions, differ)."""
    require_device("numpy", "cpu")
    require_device(backends.reference(), "cpu")
    outs = {}
    every = [(b, s, "float32", o, "cpu", "default") for b in ("numpy", backends.reference())
             for s, o in F32_VS_WARP]
    for name in ("numpy", backends.reference()):
        record, outs[name] = shared_cell("numpy-cells", every, name, scenario, "float32", overrides)
        assert record["status"] == "ok", record.get("reason")
    ours, ref = outs["numpy"], outs[backends.reference()]
    assert ours.keys() == ref.keys()
    for key in ref:
        assert ours[key].dtype == np.float32, key
        assert ours[key].tobytes() == ref[key].tobytes(), key


def test_saxpy_float32_is_not_the_float64_result_rounded() -> None:
    """fl32(fl32(a*x) + y) differs from fl32(a*x + y) computed in float64 in many elements: the
    kernel rounds twice in float32 (a float64 a or a Python-float promotion would round once)."""
    sc, p, inputs, k = build("saxpy", {"n": 4097, "inputs": "random", "seed": 3}, "float32")
    out = k.outputs()["out"]
    a, x, y = (np.asarray(inputs[n], np.float64) for n in ("a", "x", "y"))
    once = (a * x + y).astype(np.float32)
    twice = (np.float32(inputs["a"]) * inputs["x"]).astype(np.float32) + inputs["y"]
    assert twice.dtype == np.float32 and np.any(twice != once)     # the two really differ
    assert out.dtype == np.float32 and out.tobytes() == twice.tobytes()


# ---- 3. the batched projectile ------------------------------------------------------------------
BATCH = {"batch": 6, "steps": 80, "iters": 3}


@pytest.mark.parametrize("precision", ("float64", "float32"))
@pytest.mark.parametrize("contact", ("none", "hard", "soft"))
def test_batch_rows_are_single_trajectories(contact: str, precision: str) -> None:
    overrides = {"contact": contact, **BATCH}
    sc, p, inputs, k = build("projectile", overrides, precision)
    out = k.outputs()
    assert {n: (a.shape, a.dtype) for n, a in out.items()} == \
        {n: (shape, np.dtype(precision)) for n, shape in sc.output_shapes(p).items()}
    assert len({tuple(r) for r in out["grad"]}) == p.batch      # distinct trajectories
    if contact == "hard":
        assert k.hit.any(), "the contact must fire for the test to mean anything"
    if contact == "soft":
        assert (k.ys < 0).any(), "the projectile must penetrate the soft ground"
    for b in range(p.batch):
        one_in = {**inputs, "v0": inputs["v0"][b], "target": inputs["target"][b]}
        one = build("projectile", {**overrides, "batch": 1}, precision, inputs=one_in)[3].outputs()
        for name, a in one.items():
            row = out[name][:, b] if name == "loss_history" else out[name][b]
            assert row.tobytes() == a.tobytes(), (b, name)


@pytest.mark.parametrize("batch", (1, 5))
def test_set_input_reruns_at_the_new_inputs(batch: int) -> None:
    overrides = {"contact": "soft", "steps": 60, "iters": 3, "batch": batch}
    sc, p, inputs, k = build("projectile", overrides, "float64")
    before = k.outputs()
    new = {**inputs, "v0": inputs["v0"] * 1.1, "target": inputs["target"] + 0.25}
    k.set_input("v0", new["v0"])
    k.set_input("target", new["target"])
    k.run()
    got, fresh = k.outputs(), build("projectile", overrides, "float64", inputs=new)[3].outputs()
    assert not np.array_equal(got["grad"], before["grad"])
    for name, a in fresh.items():
        assert got[name].tobytes() == a.tobytes(), name
    with pytest.raises(NotImplementedError):
        k.set_input("lr", np.array(0.1))
