"""Warp-specific checks beyond the generic parity suite (in process, CPU, small sizes).

1. The checkpointed projectile (variant "checkpoint") gives the plain tape's outputs bit for bit,
   with a ragged last segment, while keeping O(steps/K + K) states per trajectory; a control
   without the backward-pass recompute differs, so the comparison can fail.
2. Batched trajectories are independent: permuting the batch permutes every output bit for bit.
3. ``set_input("v0", ...)`` reruns at the new v0 exactly as a kernel built with it.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import backends
import scenarios
from conftest import require_device

pytestmark = pytest.mark.warp
pytest.importorskip("warp")

BACKEND = backends.get("warp")
SC = scenarios.get("projectile")
# steps = 50: K = 8, segments 8 x 6 + 2 (a ragged last segment); several bounces/contacts in each
SMALL = {"steps": 50, "dt": 0.09, "iters": 3, "batch": 5}


@pytest.fixture(scope="module", autouse=True)
def _setup():
    require_device("warp", "cpu")
    BACKEND.setup("cpu", "float64", "default")


def build(params, precision, variant="default", inputs=None, cls=None):
    inputs = SC.inputs(params, precision) if inputs is None else inputs
    k = (cls or BACKEND.kernel("projectile"))(params, inputs, "cpu", precision, variant)
    k.run()
    return k


def same_bits(a: dict, b: dict) -> list[str]:
    """Names of the outputs that differ in shape, dtype or any bit."""
    return [n for n in a if np.asarray(a[n]).shape != np.asarray(b[n]).shape
            or np.asarray(a[n]).dtype != np.asarray(b[n]).dtype
            or np.asarray(a[n]).tobytes() != np.asarray(b[n]).tobytes()]


@pytest.mark.parametrize("precision", ["float64", "float32"])
@pytest.mark.parametrize("contact", ["none", "hard", "soft"])
def test_checkpoint_is_the_plain_tape(contact, precision):
    p = SC.params({**SMALL, "contact": contact})
    plain, ckpt = build(p, precision), build(p, precision, "checkpoint")
    assert same_bits(plain.outputs(), ckpt.outputs()) == []
    info = ckpt.info()
    assert (info["segments"], info["segment_steps"]) == (7, 8)
    assert ckpt.seg_steps == [8] * 6 + [2]
    # what is kept per trajectory: 7 end states and one (K+1)-step work buffer, not steps + 1
    assert [a.shape for a in ckpt.work + ckpt.ends] == [(9, 5)] * 4 + [(7, 5)] * 4
    assert [a.shape for a in plain.work] == [(51, 5)] * 4


def test_checkpoint_without_recompute_is_wrong():
    """Control: skipping the re-run of each segment before its adjoint (leaving the last segment's
    states in the work buffers) changes the gradient, so the bitwise test above can fail."""
    from backends.warp import projectile

    class NoRecompute(projectile.Kernel):
        def _recompute(self, j):
            return lambda: [a.grad.zero_() for a in self.work]

    p = SC.params({**SMALL, "contact": "soft"})
    good, bad = build(p, "float64", "checkpoint"), build(p, "float64", "checkpoint", cls=NoRecompute)
    assert "grad" in same_bits(good.outputs(), bad.outputs())


def test_batch_rows_are_independent():
    p = SC.params({**SMALL, "contact": "hard", "batch": 6})
    ins = SC.inputs(p, "float32")
    perm = np.array([3, 0, 5, 1, 4, 2])
    shuffled = {**ins, "v0": ins["v0"][perm], "target": ins["target"][perm]}
    a, b = build(p, "float32").outputs(), build(p, "float32", inputs=shuffled).outputs()
    a = {n: (v[:, perm] if n == "loss_history" else v[perm]) for n, v in a.items()}
    assert same_bits(a, b) == []


@pytest.mark.parametrize("batch", [1, 4])
def test_set_input_v0(batch):
    p = dataclasses.replace(SC.params({**SMALL, "contact": "soft"}), batch=batch)
    ins = SC.inputs(p, "float64")
    new_v0 = (ins["v0"] * 0.9 + 0.25).astype(ins["v0"].dtype)
    k = build(p, "float64")
    k.set_input("v0", new_v0)
    k.run()
    fresh = build(p, "float64", inputs={**ins, "v0": new_v0})
    assert same_bits(k.outputs(), fresh.outputs()) == []
    assert np.asarray(k.outputs()["grad"]).shape == SC.output_shapes(p)["grad"]


@pytest.mark.parametrize("device", ["cpu", "cuda"])
@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_saxpy_tile_variant_is_the_default_bit_for_bit(device, precision):
    """SAXPY's ``tile`` variant writes every element (full tiles, a partial last tile, fewer
    elements than one tile) with the default kernel's arithmetic."""
    require_device("warp", device)
    sc = scenarios.get("saxpy")
    assert BACKEND.variants_for("saxpy") == ("default", "tile", "record_cmd")
    from backends.warp.saxpy import TILE
    for n in (1, 5, TILE - 1, TILE, TILE + 1, 3 * TILE + 7):
        p = sc.params({"n": n, "inputs": "random", "seed": 11})
        inputs = sc.inputs(p, precision)
        out = {}
        for variant in ("default", "tile"):
            k = BACKEND.kernel("saxpy")(p, inputs, device, precision, variant)
            k.run()
            out[variant] = k.outputs()
        assert same_bits(out["default"], out["tile"]) == [], n


# each recorded scenario's small size and the Warp arrays its kernel writes (attribute names)
RECORDED = {"saxpy": ({"n": 1000, "inputs": "random", "seed": 3}, ("out",)),
            "sdf": ({"width": 33, "height": 17}, ("image",)),
            "particles": ({"n": 40, "steps": 30, "record_every": 7}, ("state", "traj")),
            "launch": ({"n": 5}, ("out",)), "copy": ({"n": 1001}, ("out",))}


@pytest.mark.parametrize("device", ["cpu", "cuda"])
@pytest.mark.parametrize("scenario", list(RECORDED))
def test_record_cmd_variant_replays_the_default_launch(device, scenario):
    """``record_cmd`` (a ``wp.Launch`` recorded once and replayed by every run) writes the default
    launch's outputs bit for bit, and writes them again at each call: the arrays it writes are
    set to NaN before each call, so a replay that launched nothing, or only once, fails."""
    require_device("warp", device)
    from backends.warp import RECORDABLE
    assert set(RECORDED) == set(RECORDABLE)
    assert "record_cmd" in BACKEND.variants_for(scenario)
    sc = scenarios.get(scenario)
    overrides, written = RECORDED[scenario]
    p = sc.params(overrides)
    inputs = sc.inputs(p, "float32")
    out = {}
    for variant in ("default", "record_cmd"):
        k = BACKEND.kernel(scenario)(p, inputs, device, "float32", variant)
        held = [getattr(k, name) for name in written]
        arrays = [a for h in held for a in (h if isinstance(h, list) else [h]) if a.size]
        for _ in range(2):
            for a in arrays:
                a.fill_(float("nan"))
            k.run()
            BACKEND.synchronize(device, None)
            out[variant] = k.outputs()
            assert all(np.isfinite(v).all() for v in out[variant].values()), variant
    assert same_bits(out["default"], out["record_cmd"]) == []
