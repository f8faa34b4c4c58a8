"""Taichi's own checks beyond the generic parity suite; those it shares with Quadrants (variants,
precision and the agreement with Warp, the fused rollout against one launch per step, batch rows
and set_input, with Taichi's own layouts and 32-bit refusal) are in tests/backends/test_taichi_family.py.

1. autodiff: the projectile gradient against float64 central differences of the oracle; the
   'checkpoint' variant against the uncheckpointed rollout, the guard that picks the fused or
   the per-step path from the configured adstack depth, and adstacks sized to each rollout;
2. no recompilation and repeatable outputs across run() calls; particle trajectory frames.
Anything that initialises Taichi runs in a subprocess or a worker (ti.init is process-global).
"""
from __future__ import annotations

import json
import math

import pytest

import backends
from oracle_checks import FD, FRAMES, assert_frames_match_the_oracle, assert_gradient_matches_finite_differences
from taichi_family import run, script

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
    params = next(o for o in FD if o["contact"] == contact)
    assert_gradient_matches_finite_differences(_run("projectile", "float64", params, device)[1], params)


CHECKPOINT = """
import numpy as np
import backends.taichi as bt
from backends.taichi.projectile import Kernel, fused_steps_limit
bt.AD_STACK_SIZE[DEVICE] = 40          # small stacks: a rollout longer than them is cheap
b = backends.get("taichi")
sc = scenarios.get("projectile")
out = {}
reference = {}                          # (contact, steps) -> the uncheckpointed outputs and path
for precision in (PRECISION,):
    b.setup(DEVICE, precision, "default")   # the variant's arithmetic is IEEE, as 'default'
    out["limit"] = fused_steps_limit()
    # (steps, forced segment length): 60 steps > the adstack limit (37), against the per-step
    # path: ceil(sqrt(60)) = 8 (uneven last segment) and 7; 23 steps under the limit, against the
    # fused rollout: 1 step per segment (every segment full); the forced lengths with the hard
    # contact only (the segment loop is the same for every contact). (A 100-step case, segments
    # of 10, added only another per-step reference: 60 is past the limit already.)
    for contact in ("none", "hard", "soft"):
        for steps, seg in ((60, None), (60, 7), (23, 1)):
            if seg is not None and contact != "hard":
                continue
            p = sc.params({"contact": contact, "steps": steps, "dt": 1.5 / steps, "iters": 3,
                           "batch": 37})
            i = sc.inputs(p, precision)
            Kernel.segment = seg
            kc = Kernel(p, i, DEVICE, precision, "checkpoint")
            Kernel.segment = None
            b.synchronize(DEVICE, kc.run())
            oc = kc.outputs()
            if (contact, steps) not in reference:      # same parameters and inputs: same rollout
                k = Kernel(p, i, DEVICE, precision, "default")
                b.synchronize(DEVICE, k.run())
                reference[contact, steps] = k.outputs(), k.info()["fused_rollout"]
            o, fused = reference[contact, steps]
            info = kc.info()
            out[f"{precision}-{contact}-{steps}-{seg}"] = {
                "ok": bool(sc.check(p, i, oc, sc.oracle(p, i, precision), precision).ok),
                "reference_fused": fused,
                "segment": [info["checkpoint_segment"], info["checkpoint_segments"]],
                "scratch_rows": kc.state[0].shape[0], "checkpoint_rows": kc.ck[0].shape[0],
                "identical": all(np.array_equal(o[n], oc[n]) for n in o),
                "rel": max(float(np.max(np.abs(o[n] - oc[n]) / np.maximum(np.abs(o[n]), 1e-300)))
                           for n in ("loss", "grad"))}
print("RESULT" + json.dumps(out))
"""


@pytest.mark.early
@pytest.mark.xdist_group("taichi-adstack-scripts")     # _adstack_scripts' cache: one process
# float32's is the long tier's (the same segments, the same checks)
@pytest.mark.parametrize("precision", ["float64", pytest.param("float32", marks=pytest.mark.slow)])
@pytest.mark.parametrize("device", backends.DEVICES)
def test_checkpoint_variant_equals_the_uncheckpointed_rollout(device, precision):
    """The 'checkpoint' variant (segments recomputed in the backward pass) gives the outputs of
    the fused rollout, and past the adstack depth those of the per-step path, while storing only
    the segment starts and one segment of scratch: bitwise on the CPU, to a few roundings on CUDA
    (different kernels, different FMA contraction); within the oracle's bounds."""
    r = dict(_adstack_scripts(device, precision)["checkpoint"])
    limit = r.pop("limit")
    assert limit == 40 - ADSTACK_MARGIN and len(r) == 5 and all(case.startswith(precision) for case in r)
    assert {v["reference_fused"] for v in r.values()} == {True, False}     # both sides of the limit
    for case, v in r.items():
        _, _, steps, seg = case.split("-")
        steps = int(steps)
        k = {"None": math.isqrt(steps - 1) + 1, "7": 7, "1": 1}[seg]
        m = -(-steps // k)
        assert v["segment"] == [k, m], case
        assert v["scratch_rows"] == k + 1 and v["checkpoint_rows"] == m + 1, case
        assert v["reference_fused"] == (steps <= limit), case
        assert v["ok"], case
        if device == "cpu":
            assert v["identical"], case
        else:
            assert v["rel"] <= (1e-12 if case.startswith("float64") else 1e-4), case


GUARD = """
import numpy as np
import backends.taichi as bt
from backends.taichi.projectile import Kernel, fused_steps_limit
bt.AD_STACK_SIZE[DEVICE] = 40          # small stacks, so the boundary is cheap to reach
b = backends.get("taichi"); b.setup(DEVICE, "float64", "default")
sc = scenarios.get("projectile")
out = {"limit": fused_steps_limit()}
# vy0 = 0: the hard contact fires on every step, the deepest case for the adstacks. Past the
# limit one case: the guard reads the steps only, and the per-step path's outputs past it are
# CHECKPOINT's references (60 steps, every contact)
cases = (("hard", 6.5), ("hard", 0.0), ("soft", 6.5))
for steps in (fused_steps_limit(), fused_steps_limit() + 1):
    for contact, vy0 in (cases if steps == fused_steps_limit() else cases[:1]):
        # t_N = 2 s: with vy0 = 6.5 one bounce, airborne at the end
        p = sc.params({"contact": contact, "steps": steps, "dt": 2.0 / steps, "iters": 2,
                       "vy0": vy0, "batch": 3})
        i = sc.inputs(p, "float64")
        if vy0 == 0.0:
            i["v0"][:, 1] = 0.0        # every trajectory (thread) at the deepest case
        res = []
        for fused in (None, False):    # as the guard chooses, and forced per step
            Kernel.fused = fused
            k = Kernel(p, i, DEVICE, "float64", "default")
            b.synchronize(DEVICE, k.run())
            res.append((k.outputs(), k.info()["fused_rollout"]))
            # the guard chose the per-step path: forcing it would run the same kernels again
            # (their repeatability: test_repeated_run_neither_recompiles_nor_changes_outputs)
            if not res[0][1]:
                break
        Kernel.fused = None
        (o, fused), o_step = res[0], res[-1][0]
        out[f"{steps}-{contact}-{vy0}"] = {
            "fused": fused, "compared": len(res) == 2,     # identical: null where nothing was compared
            "identical": all(np.array_equal(o[n], o_step[n]) for n in o) if len(res) == 2 else None,
            "ok": bool(sc.check(p, i, o, sc.oracle(p, i, "float64"), "float64").ok)}
print("RESULT" + json.dumps(out))
"""


# ti.init and the small stacks of CHECKPOINT: both scripts run in one process (a start and the
# shared kernels' compilation saved), each on its own kernels, with its own results
_ADSTACK: dict[tuple[str, str], dict] = {}


def _adstack_scripts(device: str, precision: str) -> dict:
    """CHECKPOINT's results, and on the CPU in float64 GUARD's after them, from one process."""
    if (device, precision) not in _ADSTACK:
        def body(script: str) -> str:
            return script.replace('print("RESULT" + json.dumps(out))', "")
        guard = device == "cpu" and precision == "float64"
        code = (body(CHECKPOINT) + "checkpoint = out\n" + (body(GUARD) if guard else "out = None\n")
                + 'print("RESULT" + json.dumps({"checkpoint": checkpoint, "guard": out}))\n')
        _ADSTACK[device, precision] = _script(code, device, PRECISION=precision)
    return _ADSTACK[device, precision]


@pytest.mark.early
@pytest.mark.xdist_group("taichi-adstack-scripts")
def test_fused_rollout_only_where_the_adstacks_hold_it():
    """Past the configured depth Taichi overflows its adstacks silently (wrong gradients, a crash
    or a hang), so longer rollouts must take the per-step path. At the limit, even with a contact
    on every step in every trajectory of a batch, the fused path equals the per-step one
    bitwise."""
    r = dict(_adstack_scripts("cpu", "float64")["guard"])
    limit = r.pop("limit")
    assert limit == 40 - ADSTACK_MARGIN and len(r) == 4
    for case, v in r.items():
        steps, contact, vy0 = case.split("-")
        assert v["fused"] == (int(steps) <= limit), case
        assert v["compared"] == v["fused"], case          # fused against per step, where the guard chose fused
        assert v["identical"] is (True if v["compared"] else None), case
        if vy0 != "0.0":   # clamped on the last step: the check divides zero error by zero bound
            assert v["ok"], case


SIZED = """
import numpy as np
from taichi.lang import impl
from backends.taichi.projectile import ADSTACK_MARGIN, Kernel
b = backends.get("taichi"); b.setup(DEVICE, "float64", "default")
sc = scenarios.get("projectile")
p = {n: sc.params({"contact": "hard", "steps": n, "dt": 2.0 / n, "iters": 2, "batch": 37})
     for n in (30, 10, 61)}
i = {n: sc.inputs(q, "float64") for n, q in p.items()}
# the deeper kernel built first and launched last: its backward kernel must still be compiled for
# its own depth, not for the one the shallower kernel (built later, launched first) asked for
k = {n: Kernel(p[n], i[n], DEVICE, "float64", v) for n, v in ((30, "default"), (10, "default"),
                                                            (61, "checkpoint"))}
out = {}
for n in (10, 30, 61):
    b.synchronize(DEVICE, k[n].run())
    compiled_for = impl.current_cfg().ad_stack_size      # what the launches just compiled with
    Kernel.fused = False
    k_step = Kernel(p[n], i[n], DEVICE, "float64", "default")
    Kernel.fused = None
    b.synchronize(DEVICE, k_step.run())
    o, o_step = k[n].outputs(), k_step.outputs()
    info = k[n].info()
    out[n] = {"ad_stack_size": info["ad_stack_size"], "rollout": info["rollout"],
              "segment": info.get("checkpoint_segment"),
              "per_stack": info["design_bytes"]["adstack_per_stack_per_thread"],
              "per_step_stack": k_step.info()["ad_stack_size"], "compiled_for": compiled_for,
              "identical": all(np.array_equal(o[m], o_step[m]) for m in o),
              "rel": max(float(np.max(np.abs(o[m] - o_step[m]) / np.maximum(np.abs(o[m]), 1e-300)))
                         for m in o)}
out["margin"] = ADSTACK_MARGIN
out["ceiling"] = b.ad_stack_limit
print("RESULT" + json.dumps(out))
"""


@pytest.mark.parametrize("device", backends.DEVICES)
def test_adstacks_are_sized_to_the_rollout(device):
    """The backward kernel's adstacks hold steps + margin entries (the segment's steps for
    'checkpoint'), not the device's ceiling, whose local memory the CUDA driver would reserve for
    every resident thread; kernels of different depths in one process each get their own depth,
    whatever the order they are built and launched in, and give the per-step path's outputs: bitwise
    on the CPU; on CUDA, whose compiler contracts products and sums into FMAs kernel by kernel, to a
    few roundings (the bound of test_taichi_family's fused-against-per-step test)."""
    r = _script(SIZED, device)
    margin, ceiling = r.pop("margin"), r.pop("ceiling")
    assert margin == ADSTACK_MARGIN and ceiling == {"cpu": 4096, "cuda": 1024}[device]
    for n, v in r.items():
        depth = (v["segment"] if n == "61" else int(n)) + margin
        assert v["rollout"] == ("checkpoint" if n == "61" else "fused"), n
        assert v["segment"] == (8 if n == "61" else None), n
        assert v["ad_stack_size"] == v["compiled_for"] == depth, n
        assert v["per_stack"] == 4 + 2 * 8 * depth, n
        assert v["per_step_stack"] is None, n
        if device == "cpu":
            assert v["identical"], n
        else:
            assert v["rel"] <= 1e-12, n


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
