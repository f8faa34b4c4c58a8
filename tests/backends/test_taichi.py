"""Taichi's own checks beyond the generic parity suite; those it shares with Quadrants (variants,
precision and the agreement with Warp, the fused rollout against one launch per step, batch rows
and set_input, with Taichi's own layouts and 32-bit refusal) are in tests/backends/test_taichi_family.py.

1. autodiff: the projectile gradient against float64 central differences of the oracle; the
   'checkpoint' variant against the uncheckpointed rollout, the guard that picks the fused or
   the per-step path from the configured adstack depth, and adstacks sized to each rollout (the
   three read one process's kernels: ADSTACK);
2. no recompilation and repeatable outputs across run() calls; particle trajectory frames.
Anything that initialises Taichi runs in a subprocess or a worker (ti.init is process-global).
"""
from __future__ import annotations

import json
import math

import pytest

import backends
from oracle_checks import FRAMES, assert_frames_match_the_oracle, assert_gradient_matches_finite_differences
from taichi_family import GRADIENT, run, script

ADSTACK_MARGIN = 3     # backends/taichi/projectile.py's (read without importing Taichi here)

pytestmark = pytest.mark.taichi


def _run(scenario: str, precision: str, params: dict, device: str = "cpu") -> tuple[dict, dict]:
    """A cell of the group taichi-cells (tests/taichi_family.py), which tests/backends/test_taichi_family.py shares."""
    return run("taichi", scenario, precision, params, device)


def _script(body: str, device: str = "cpu", **constants) -> dict:
    """Run ``body`` in a fresh interpreter (its own ti.init); it prints RESULT<json>."""
    return script("taichi", body, device, **constants)


# ---- 1. autodiff --------------------------------------------------------------------------------
@pytest.mark.xdist_group("taichi-cells")
@pytest.mark.parametrize("device", backends.DEVICES)
@pytest.mark.parametrize("contact", ["hard", "soft"])
def test_gradient_matches_finite_differences_of_the_oracle(contact, device):
    params = next(o for o in GRADIENT if o["contact"] == contact)
    assert_gradient_matches_finite_differences(_run("projectile", "float64", params, device)[1], params)


ADSTACK = """
import numpy as np
import backends.taichi as bt
from taichi.lang import impl
from backends.taichi.projectile import ADSTACK_MARGIN, Kernel, fused_steps_limit
out = {"ceiling": bt.AD_STACK_SIZE[DEVICE], "margin": ADSTACK_MARGIN}    # the device's, read first
bt.AD_STACK_SIZE[DEVICE] = 40          # small stacks: the limit is cheap to reach and to pass
b = backends.get("taichi")
b.setup(DEVICE, PRECISION, "default")   # the checkpoint variant's arithmetic is IEEE, as 'default'
sc = scenarios.get("projectile")
L = out["limit"] = fused_steps_limit()
out["setup_ceiling"] = b.ad_stack_limit
# name: (contact, steps, variant, forced path, forced segment, reference), built in this order,
# the deepest first, and launched in the reverse one (each kernel's depth is its own whatever
# the order). At the limit the guard's fused rollout against the per-step path forced; with the
# hard contact on the CPU (the guard's test) every trajectory but row 0 (the seed case: one
# bounce, airborne at the end) is thrown flat (vy0 = 0): the contact on every step, the deepest
# case for the adstacks (not on CUDA, where the paths differ by roundings: a gradient the clamp
# kills has no relative scale). Past the limit the guard's per-step path (it reads the steps
# only: one case). The checkpoint variant against the uncheckpointed rollout on both sides of
# the limit, every contact once (the segment loop is the same for every contact):
# ceil(sqrt(steps)) = 7 (an uneven last segment) and, forced, 1 (every segment full); the
# 23-step fused rollout is sized under the ceiling.
CASES = {"hard-L": ("hard", L, "default", None, None, "hard-L-per-step"),
         "hard-L-per-step": ("hard", L, "default", False, None, "hard-L"),
         "soft-L": ("soft", L, "default", None, None, "soft-L-per-step"),
         "soft-L-per-step": ("soft", L, "default", False, None, "soft-L"),
         "hard-L+1": ("hard", L + 1, "default", None, None, None),
         "none-23": ("none", 23, "default", None, None, "none-23-checkpoint"),
         "soft-L-checkpoint": ("soft", L, "checkpoint", None, None, "soft-L"),
         "hard-L+1-checkpoint": ("hard", L + 1, "checkpoint", None, None, "hard-L+1"),
         "none-23-checkpoint": ("none", 23, "checkpoint", None, 1, "none-23")}
built, oracles = {}, {}
for name, (contact, steps, variant, fused, segment, _) in CASES.items():
    # t_N = 2 s: row 0 (vy0 = 6.5) bounces once and is airborne at the end
    p = sc.params({"contact": contact, "steps": steps, "dt": 2.0 / steps, "iters": 2, "batch": 37})
    i = sc.inputs(p, PRECISION)
    if (contact, steps, DEVICE) == ("hard", L, "cpu"):
        i["v0"][1:, 1] = 0.0
    Kernel.fused, Kernel.segment = fused, segment
    built[name] = Kernel(p, i, DEVICE, PRECISION, variant), p, i
    Kernel.fused = Kernel.segment = None
outputs = {}
for launched, name in enumerate(reversed(CASES)):
    k, p, i = built[name]
    b.synchronize(DEVICE, k.run())
    compiled_for = impl.current_cfg().ad_stack_size      # what the launch just compiled with
    o = outputs[name] = k.outputs()
    contact, steps, variant, fused, segment, ref = CASES[name]
    if (contact, steps) not in oracles:                  # same parameters and inputs: same oracle
        oracles[contact, steps] = sc.oracle(p, i, PRECISION)
    info = k.info()
    out[name] = {
        "contact": contact, "steps": steps, "variant": variant, "forced_segment": segment,
        "reference": ref, "built": list(CASES).index(name), "launched": launched,
        "rollout": info["rollout"], "fused": info["fused_rollout"],
        "ad_stack_size": info["ad_stack_size"],
        "compiled_for": compiled_for if info["ad_stack_size"] is not None else None,
        "per_stack": info["design_bytes"].get("adstack_per_stack_per_thread"),
        "segment": [info.get("checkpoint_segment"), info.get("checkpoint_segments")],
        "scratch_rows": k.state[0].shape[0],
        "checkpoint_rows": k.ck[0].shape[0] if variant == "checkpoint" else None,
        "ok": bool(sc.check(p, i, o, oracles[contact, steps], PRECISION).ok)}
for name, v in CASES.items():
    ref = v[-1]
    if ref is not None:
        o, r = outputs[name], outputs[ref]
        out[name].update(
            identical=all(np.array_equal(o[n], r[n]) for n in o),
            rel=max(float(np.max(np.abs(o[n] - r[n]) / np.maximum(np.abs(r[n]), 1e-300)))
                    for n in ("loss", "grad")),
            rel_all=max(float(np.max(np.abs(o[n] - r[n]) / np.maximum(np.abs(o[n]), 1e-300))) for n in o))
print("RESULT" + json.dumps(out))
"""


_ADSTACK: dict[tuple[str, str], dict] = {}


def _adstack(device: str, precision: str) -> dict:
    """ADSTACK's results on ``device`` in ``precision``, one process for the three tests that read
    them (xdist_group taichi-adstack-scripts): the checks share its kernels, each its own cases."""
    if (device, precision) not in _ADSTACK:
        _ADSTACK[device, precision] = _script(ADSTACK, device, PRECISION=precision)
    return _ADSTACK[device, precision]


def _cases(r: dict) -> dict[str, dict]:
    """ADSTACK's entries per kernel (the others: the limit, the ceilings, the margin)."""
    return {name: v for name, v in r.items() if isinstance(v, dict)}


@pytest.mark.early
@pytest.mark.xdist_group("taichi-adstack-scripts")
# float32's is the long tier's (the same segments, the same checks)
@pytest.mark.parametrize("precision", ["float64", pytest.param("float32", marks=pytest.mark.slow)])
@pytest.mark.parametrize("device", backends.DEVICES)
def test_checkpoint_variant_equals_the_uncheckpointed_rollout(device, precision):
    """The 'checkpoint' variant (segments recomputed in the backward pass) gives the outputs of
    the fused rollout, and past the adstack depth those of the per-step path, while storing only
    the segment starts and one segment of scratch: bitwise on the CPU, to a few roundings on CUDA
    (different kernels, different FMA contraction); within the oracle's bounds."""
    r = _adstack(device, precision)
    limit, cases = r["limit"], _cases(r)
    assert limit == 40 - ADSTACK_MARGIN
    checkpointed = {n: v for n, v in cases.items() if v["variant"] == "checkpoint"}
    assert {v["contact"] for v in checkpointed.values()} == {"none", "hard", "soft"}
    # both sides of the limit: against the fused rollout and against the per-step path
    assert {cases[v["reference"]]["fused"] for v in checkpointed.values()} == {True, False}
    shapes = set()
    for case, v in checkpointed.items():
        steps, ref = v["steps"], cases[v["reference"]]
        k = v["forced_segment"] or math.isqrt(steps - 1) + 1
        m = -(-steps // k)
        shapes.add(steps % k == 0)
        assert v["rollout"] == "checkpoint" and v["segment"] == [k, m], case
        assert v["scratch_rows"] == k + 1 and v["checkpoint_rows"] == m + 1, case
        assert ref["variant"] == "default" and ref["steps"] == steps and ref["contact"] == v["contact"], case
        assert ref["fused"] == (steps <= limit), case
        assert v["ok"], case
        if device == "cpu":
            assert v["identical"], case
        else:
            assert v["rel"] <= (1e-12 if precision == "float64" else 1e-4), case
    assert shapes == {True, False}          # an uneven last segment, and every segment full


@pytest.mark.early
@pytest.mark.xdist_group("taichi-adstack-scripts")
def test_fused_rollout_only_where_the_adstacks_hold_it():
    """Past the configured depth Taichi overflows its adstacks silently (wrong gradients, a crash
    or a hang), so longer rollouts must take the per-step path. At the limit, even with a contact
    on every step in every trajectory of a batch but the seed row, the fused path equals the
    per-step one bitwise, within the oracle's bounds."""
    r = _adstack("cpu", "float64")
    limit, cases = r["limit"], _cases(r)
    assert limit == 40 - ADSTACK_MARGIN
    guard = {n: v for n, v in cases.items() if v["variant"] == "default" and v["steps"] in (limit, limit + 1)
             and "per-step" not in n}     # as the guard chooses (the others force the per-step path)
    assert sorted((v["steps"] - limit, v["contact"]) for v in guard.values()) == \
        [(0, "hard"), (0, "soft"), (1, "hard")]
    for case, v in guard.items():
        assert v["fused"] == (v["steps"] <= limit), case
        if v["fused"]:        # against the per-step path forced, on the same inputs
            ref = cases[v["reference"]]
            assert ref["rollout"] == "per_step", case
            assert (ref["steps"], ref["contact"]) == (v["steps"], v["contact"]), case
            assert v["identical"], case
        assert v["ok"], case


@pytest.mark.early
@pytest.mark.xdist_group("taichi-adstack-scripts")
@pytest.mark.parametrize("device", backends.DEVICES)
def test_adstacks_are_sized_to_the_rollout(device):
    """The backward kernel's adstacks hold steps + margin entries (the segment's steps for
    'checkpoint'), not the device's ceiling, whose local memory the CUDA driver would reserve for
    every resident thread; kernels of different depths in one process each get their own depth,
    whatever the order they are built and launched in, and give the outputs of another path (the
    per-step one, or fused against checkpointed): bitwise on the CPU; on CUDA, whose compiler
    contracts products and sums into FMAs kernel by kernel, to a few roundings (the bound of
    test_taichi_family's fused-against-per-step test)."""
    r = _adstack(device, "float64")
    margin, cases = r["margin"], _cases(r)
    assert margin == ADSTACK_MARGIN and r["ceiling"] == {"cpu": 4096, "cuda": 1024}[device]
    assert r["setup_ceiling"] == 40        # setup() passes the configured ceiling on
    depth = {}
    for case, v in cases.items():
        rollout = ("checkpoint" if v["variant"] == "checkpoint" else "per_step" if "per-step" in case
                   or v["steps"] > r["limit"] else "fused")
        assert v["rollout"] == rollout, case
        if rollout == "per_step":
            assert v["ad_stack_size"] is None and v["per_stack"] is None, case
            continue
        depth[case] = (v["segment"][0] if rollout == "checkpoint" else v["steps"]) + margin
        assert v["ad_stack_size"] == v["compiled_for"] == depth[case], case
        assert v["per_stack"] == 4 + 2 * 8 * depth[case], case
        other = cases[v["reference"]]
        assert other["rollout"] != rollout and other["steps"] == v["steps"], case
        if device == "cpu":
            assert v["identical"], case
        else:    # every output; loss and gradient only where the soft contact's descent amplifies roundings
            assert (v["rel"] if v["contact"] == "soft" else v["rel_all"]) <= 1e-12, case
    assert any(cases[c]["rollout"] == "fused" and d < r["setup_ceiling"] for c, d in depth.items())
    # a deeper kernel built before a shallower one and launched after it
    assert any(depth[a] > depth[b] and cases[a]["built"] < cases[b]["built"]
               and cases[a]["launched"] > cases[b]["launched"] for a in depth for b in depth)


# ---- 2. compilation, repeatability, trajectories ------------------------------------------------
RECOMPILE = """
import importlib, time
import numpy as np

def compiled(module):
    # Each @ti.kernel keeps its primal and adjoint instantiations, one per template-argument set.
    kernels = [v for v in vars(module).values() if getattr(v, "_is_wrapped_kernel", False)]
    return sum(len(k._primal.compiled_kernels) + len(k._adjoint.compiled_kernels) for k in kernels)

CASES = json.loads(CASES_JSON)
b = backends.get("taichi"); b.setup(DEVICE, "float32", "default")
out = {}
for name, overrides in CASES:
    sc = scenarios.get(name)
    p = sc.params(overrides)
    mod = importlib.import_module(f"backends.taichi.{name}")
    k = b.kernel(name)(p, sc.inputs(p, "float32"), DEVICE, "float32", "default")
    t0 = time.perf_counter(); b.synchronize(DEVICE, k.run()); first = time.perf_counter() - t0
    n_first, o_first = compiled(mod), k.outputs()
    later = []
    for _ in range(3):
        t0 = time.perf_counter(); b.synchronize(DEVICE, k.run())
        later.append(time.perf_counter() - t0)
    o_later = k.outputs()
    out[f"{name}-{overrides}"] = {
        "first": first, "later": min(later), "compiled": [n_first, compiled(mod)],
        "repeatable": all(np.array_equal(o_first[n], o_later[n]) for n in o_first)}
print("RESULT" + json.dumps(out))
"""
RECOMPILE_CASES = [("saxpy", {"n": 100_003}), ("sdf", {"width": 203, "height": 97}),
                   ("particles", {"n": 1000, "steps": 300, "record_every": 50}),
                   ("projectile", {"contact": "soft", "iters": 5})]


@pytest.mark.parametrize("device", backends.DEVICES)
def test_repeated_run_neither_recompiles_nor_changes_outputs(device):
    r = _script(RECOMPILE, device, CASES_JSON=json.dumps(RECOMPILE_CASES))
    for case, v in r.items():
        n_first, n_after = v["compiled"]
        assert n_first >= 1 and n_after == n_first, case       # no new instantiation per call
        assert v["later"] < v["first"] / 3, case                # the first call paid compilation
        assert v["repeatable"], case


@pytest.mark.xdist_group("taichi-cells")
def test_particle_trajectory_frames_match_the_oracle():
    assert_frames_match_the_oracle(_run("particles", "float64", FRAMES)[1])
