"""Warp-specific checks beyond the generic parity suite (in process, CPU, small sizes).

1. The checkpointed projectile (variant "checkpoint") gives the plain tape's outputs bit for bit,
   with a ragged last segment, while keeping O(steps/K + K) states per trajectory; a control
   without the backward-pass recompute differs, so the comparison can fail.
2. The projectile's "tape_zero" and "unrolled" variants give the default's outputs bit for bit
   (unrolled: one segment and several, a ragged last one); controls: an unrolled kernel Warp emits
   as a dynamic loop, and a descent that never clears v's gradient, differ. After a backward pass
   every gradient but v's is zero (what the default's clearing relies on), and ``design_bytes`` is
   the bytes of the arrays each path allocates. Through the worker, every variant passes the oracle
   check of the parity suite's projectile cases in float64 with the default's outputs.
   The step is one wp.func (no other function of the module computes with its constants) that
   both kernels call, in the operation order of a scalar reference: the float64 and float32
   losses are its bits (controls: a copy of the step, and a reference in another order, are seen).
3. Batched trajectories are independent: permuting the batch permutes every output bit for bit.
4. ``set_input("v0", ...)`` reruns at the new v0 exactly as a kernel built with it.
"""
from __future__ import annotations

import ast
import ctypes
import ctypes.util
import dataclasses
import inspect
import textwrap

import numpy as np
import pytest

import backends
import scenarios
from conftest import ran, require_device, run_cases
from test_parity import CASES

# the tests that build kernels in this process share one xdist worker: Warp starts once, and each
# unrolled kernel compiles once (a test's own xdist_group mark, the closer, places it elsewhere)
pytestmark = [pytest.mark.warp, pytest.mark.xdist_group("warp-in-process")]
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


# float32's segmented unrolled kernels (UNROLL_MAX 16) of no or soft contact compile for this test
# alone: the long tier runs them; the fast tier keeps float64's of each contact (segments are cut
# alike in both precisions) and hard contact's float32 ones (test_design_bytes_are_the_arrays_allocated
# compiles them)
VARIANT_CASES = [pytest.param(v, m, c, p, id=f"{v}-{m}-{c}-{p}",
                              marks=[pytest.mark.slow] if (m, p) == (16, "float32") and c != "hard" else [])
                 for p in ("float64", "float32") for c in ("none", "hard", "soft")
                 for v, m in (("tape_zero", None), ("unrolled", None), ("unrolled", 16))]


@pytest.mark.parametrize("variant,unroll_max,contact,precision", VARIANT_CASES)
def test_variant_is_the_default_bit_for_bit(variant, unroll_max, contact, precision, monkeypatch):
    from backends.warp import projectile
    if unroll_max:      # 50 steps in segments of at most 16: 13, 13, 13, 11 (two kernels)
        monkeypatch.setattr(projectile, "UNROLL_MAX", unroll_max)
    p = SC.params({**SMALL, "contact": contact})
    plain, other = build(p, precision), build(p, precision, variant)
    assert same_bits(plain.outputs(), other.outputs()) == []
    info = other.info()
    assert info["path"] == variant
    if variant == "unrolled":
        nseg = 4 if unroll_max else 1
        assert other.seg_steps == ([13, 13, 13, 11] if unroll_max else [50])
        assert other.work == [] and [a.shape for a in other.ends] == ([(3, 5)] * 4 if unroll_max else [])
        assert (info["arrays_kept"], info["arrays_with_grad"]) == (7 + 4 * (nseg > 1), 2 + 4 * (nseg > 1))
        assert info["states_kept_per_trajectory"] == nseg - 1
    else:
        assert info["gradients_cleared"] == "tape.zero()"


def test_unrolled_as_a_dynamic_loop_is_wrong():
    """Control: the same kernel with max_unroll below its steps is emitted as a dynamic loop, whose
    loop-carried locals Warp does not differentiate: same loss, another gradient."""
    from backends.warp import projectile

    class Dynamic(projectile.Kernel):
        def __init__(self, params, inputs, device, precision, variant):
            real = projectile._unrolled
            projectile._unrolled = lambda s, n, c: real(s, n, c, max_unroll=n - 1)
            try:
                super().__init__(params, inputs, device, precision, variant)
            finally:
                projectile._unrolled = real

    p = SC.params({**SMALL, "contact": "hard"})
    good, bad = build(p, "float64", "unrolled"), build(p, "float64", "unrolled", cls=Dynamic)
    assert same_bits(good.outputs(), bad.outputs())[:2] == ["grad", "loss_history"]
    assert good.outputs()["loss"].tobytes() == bad.outputs()["loss"].tobytes()


STEP_CONSTANTS = {"dt", "gravity", "bounce", "damping", "stiffness", "softness"}


def step_arithmetic(source: str) -> tuple[list[str], set[str]]:
    """(functions but ``step`` that compute with the step's constants: a copy of its arithmetic,
    functions that call ``step``) in ``source``, each function's own body, nested ones apart."""
    copies, callers = [], set()
    for f in (n for n in ast.walk(ast.parse(source)) if isinstance(n, ast.FunctionDef)):
        todo, own = list(f.body), []
        while todo:
            node = todo.pop()
            if not isinstance(node, ast.FunctionDef):
                own.append(node)
                todo.extend(ast.iter_child_nodes(node))
        ops = [n for n in own if isinstance(n, (ast.BinOp, ast.UnaryOp, ast.Compare))]
        if f.name != "step" and any(isinstance(m, ast.Name) and m.id in STEP_CONSTANTS
                                    for op in ops for m in ast.walk(op)):
            copies.append(f.name)
        if any(isinstance(n, ast.Call) and getattr(n.func, "id", None) == "step" for n in own):
            callers.add(f.name)
    return copies, callers


def test_the_step_is_one_function_both_kernels_call():
    from backends.warp import projectile
    source = inspect.getsource(projectile)
    assert step_arithmetic(source) == ([], {"segment", "rollout"})
    step = textwrap.dedent(inspect.getsource(projectile._step)).replace("def step(", "def copy(")
    assert step_arithmetic(source + step)[0] == ["copy"]        # control: a second definition


LIBM = ctypes.CDLL(ctypes.util.find_library("m"))


def reference_losses(p, ins, precision: str, reorder: bool = False) -> np.ndarray:
    """Each trajectory's loss at v0 from scalar steps in the shared step's operation order (with
    ``reorder``, another: the control), rounding each operation to ``precision``; exp and log
    are the C library's, which Warp's CPU kernels call."""
    t, suffix = (np.float32, "f") if precision == "float32" else (np.float64, "")
    exp, log = getattr(LIBM, "exp" + suffix), getattr(LIBM, "log" + suffix)
    for fn in (exp, log):
        fn.restype = ctypes.c_float if suffix else ctypes.c_double
        fn.argtypes = [fn.restype]
    c = {k: t(float(ins[k])) for k in STEP_CONSTANTS}
    out = []
    for (vx, vy), (tx, ty) in zip(ins["v0"].astype(t), ins["target"].astype(t)):
        x = y = t(0.0)
        for _ in range(p.steps):
            acc = c["gravity"]
            if p.contact == "soft":
                z = -y / c["softness"]
                sp = max(z, t(0.0)) + t(log(float(t(1.0) + t(exp(float(-abs(z)))))))
                k_sp = (c["stiffness"] * c["softness"]) * sp if reorder else c["stiffness"] * (c["softness"] * sp)
                acc = c["gravity"] + k_sp
            vy = vy + acc * c["dt"]
            x_next = x + vx * c["dt"]
            y = y + vy * c["dt"]
            if p.contact == "hard" and y < t(0.0):
                y, vy, vx = t(0.0), -c["bounce"] * vy, c["damping"] * vx
            x = x + vx * c["dt"] if reorder else x_next         # reorder: x after the bounce
        out.append((x - tx) * (x - tx) + (y - ty) * (y - ty))
    return np.array(out, dtype=t)


@pytest.mark.parametrize("precision", ["float64", "float32"])
@pytest.mark.parametrize("contact", ["none", "hard", "soft"])
def test_the_step_has_the_reference_operation_order(contact, precision):
    p = SC.params({**SMALL, "contact": contact})
    ins = SC.inputs(p, precision)
    for variant in ("default", "unrolled"):         # the segment kernel's path and the unrolled one
        loss = build(p, precision, variant).outputs()["loss"]
        assert loss.tobytes() == reference_losses(p, ins, precision).tobytes(), variant
    if contact != "none":       # control: another order gives other bits
        assert loss.tobytes() != reference_losses(p, ins, precision, reorder=True).tobytes()


@pytest.mark.parametrize("variant", ["default", "checkpoint", "unrolled"])
def test_after_a_backward_pass_only_v_has_a_gradient(variant, monkeypatch):
    """What clearing only v's gradient relies on: Warp's adjoint of a store zeroes the gradient it
    reads, so every array written on the tape ends the backward pass with a zero gradient. A
    descent that never clears v's (the control) differs from the default."""
    from backends.warp import projectile
    monkeypatch.setattr(projectile, "UNROLL_MAX", 16)
    assert projectile.CONSUMES_GRADIENTS
    k = build(SC.params({**SMALL, "contact": "soft"}), "float64", variant)
    k._forward()
    k.tape.backward(grads={k.loss: k.seed})
    assert np.any(k.v.grad.numpy() != 0)
    held = [a for a in (k.loss, *k.ends, *k.work) if np.any(a.grad.numpy() != 0)]
    assert held == [] and k.accumulated() == [k.v.grad]

    class NoClear(projectile.Kernel):
        def _clear(self):
            pass
    p = SC.params({**SMALL, "contact": "soft"})
    assert "loss_history" in same_bits(build(p, "float64").outputs(), build(p, "float64", cls=NoClear).outputs())


@pytest.mark.parametrize("precision", ["float64", "float32"])
@pytest.mark.parametrize("variant,unroll_max", [("default", None), ("checkpoint", None), ("tape_zero", None),
                                                ("unrolled", None), ("unrolled", 16)])
def test_design_bytes_are_the_arrays_allocated(variant, unroll_max, precision, monkeypatch):
    from backends.warp import projectile
    import warp as wp
    if unroll_max:
        monkeypatch.setattr(projectile, "UNROLL_MAX", unroll_max)
    k = build(SC.params({**SMALL, "contact": "hard", "batch": 7}), precision, variant)
    held = [a for v in vars(k).values() for a in (v if isinstance(v, list) else [v]) if isinstance(a, wp.array)]
    allocated = sum(a.capacity + (a.grad.capacity if a.grad is not None else 0) for a in held)
    assert k.info()["design_bytes"] == allocated
    if variant == "default":     # the states' arrays dominate: 8 (steps + 2) B S
        assert allocated - 8 * (50 + 2) * 7 * (8 if precision == "float64" else 4) == (3 + 14) * 7 * (
            8 if precision == "float64" else 4)


def test_unrolled_on_cuda_agrees_and_reports_its_registers():
    """On a GPU FMA contraction may differ between the two kernels, so float64 agreement to the
    parity suite's tight level, not bits; info() reads the compiled functions' attributes."""
    require_device("warp", "cuda")
    p = SC.params({**SMALL, "contact": "hard", "batch": 64})
    ins = SC.inputs(p, "float64")
    out = {}
    for variant in ("default", "unrolled"):
        k = BACKEND.kernel("projectile")(p, ins, "cuda", "float64", variant)
        k.run()
        k.run()                         # the second call replays the captured graph
        BACKEND.synchronize("cuda", None)
        out[variant] = k.outputs()
    assert SC.distance(p, ins, out["unrolled"], out["default"]) <= 1e-12
    info = k.info()
    assert "cuda_attributes_error" not in info, info
    assert info["backward_registers_per_thread"] > 0 and info["local_reserved_bytes"] >= 0


PROJECTILE_CASES = [o for s, o in CASES if s == "projectile"]
ALL = tuple(range(len(PROJECTILE_CASES)))
# the unrolled variant compiles a kernel per case, in seconds that grow with its steps: the fast
# tier runs the 7-step case and a batch without contact, the long tier every case
# (test_variant_is_the_default_bit_for_bit holds each contact in both precisions to the default)
UNROLLED_FAST = tuple(PROJECTILE_CASES.index(o) for o in ({"steps": 7, "iters": 0}, {"contact": "none", "batch": 37}))


def worker_run(variant, which=ALL):
    """The parity suite's projectile cases ``which`` (indices), float64, through one worker process
    per variant (conftest.run_cases); the default's are the parity suite's own cells, which this
    xdist group has run already."""
    cases = [("warp", "projectile", "float64", PROJECTILE_CASES[i], "cpu", variant) for i in which]
    run_cases(cases)
    return [ran(c) for c in cases]


@pytest.mark.xdist_group("warp-cells")         # with the parity suite's warp cells
@pytest.mark.parametrize("variant,which", [("checkpoint", ALL), ("tape_zero", ALL), ("unrolled", UNROLLED_FAST),
                                           pytest.param("unrolled", ALL, marks=pytest.mark.slow)],
                         ids=["checkpoint", "tape_zero", "unrolled-short-and-batch", "unrolled"])
def test_variant_passes_the_parity_cases(variant, which):
    assert len(PROJECTILE_CASES) == 7 and len(which) >= 2
    ref = worker_run("default")
    for i, (rec, out) in zip(which, worker_run(variant, which)):
        overrides, (ref_rec, ref_out) = PROJECTILE_CASES[i], ref[i]
        assert rec.status == "ok" and ref_rec.status == "ok", (overrides, rec.reason, ref_rec.reason)
        assert rec.variant == variant
        assert rec.error["vs_oracle"] <= rec.error["tolerance"], overrides
        assert same_bits(out, ref_out) == [], overrides


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
