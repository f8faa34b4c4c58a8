"""Triton-specific checks beyond the generic parity suite (which runs Triton's CUDA cells on a GPU).

Triton compiles for GPUs only; on a machine without one this file checks what can be checked:
1. the package imports without triton, the CPU is never offered to ``compare`` (its reason names
   the interpreter), ``compare list`` shows why, and a CPU run skips Triton's cells with it;
2. the kernels compiled for sm_90 here (Triton's own LLVM and ptxas need no GPU): the float32 PTX
   has no double arithmetic (sinf's own range reduction aside), division and square root are the
   IEEE instructions (not Triton's approximate defaults), FMAs are contracted, libdevice does not
   flush subnormals, and SAXPY moves 16 bytes per access;
3. under ``TRITON_INTERPRET=1`` (Triton's interpreter, NumPy on the CPU, never timed): the parity
   cases at small sizes through the real worker path against the float64 oracle in both
   precisions and, in float64, against Warp's CPU output at the parity suite's level; batch rows
   are single trajectories bit for bit; set_input reruns at new inputs; the hand adjoint agrees
   with float64 central differences and the scenario's closed form / float64 adjoint;
4. on a GPU (skipped here): every scenario through the worker with events, graph replay and the
   memory figure, batch row 0 against batch = 1, set_input with graph replay.
"""
from __future__ import annotations

import functools
import importlib.util
import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import backends
import scenarios
from compare.running import cells
from compare.spec import Cell
from conftest import ROOT, availability
from hand_adjoint import GPU_CASES, assert_gpu_cell_with_events_graph_and_memory, row0_and_replay

pytestmark = pytest.mark.triton

BACKEND = backends.get("triton")
TIGHT_VS_WARP = {"saxpy": 1e-15, "sdf": 1e-13, "particles": 1e-12, "projectile": 1e-12}   # test_parity's
SMALL = {"steps": 80, "iters": 3}           # the projectile under the interpreter (contacts still fire)
INTERP_CASES = [
    ("saxpy", {}), ("saxpy", {"n": 1}), ("saxpy", {"n": 257, "inputs": "random", "seed": 3}),
    ("sdf", {}), ("sdf", {"width": 2, "height": 3}),
    ("particles", {"n": 200, "steps": 100}), ("particles", {"n": 33, "steps": 57, "record_every": 7}),
    ("launch", {}), ("copy", {"n": 1003}),
    ("projectile", {"contact": "none", **SMALL}), ("projectile", {"contact": "hard", **SMALL}),
    ("projectile", {"contact": "soft", **SMALL}), ("projectile", {"steps": 7, "iters": 0}),
    ("projectile", {"contact": "none", "batch": 37, **SMALL}),
    ("projectile", {"contact": "hard", "batch": 37, **SMALL}),
    ("projectile", {"contact": "soft", "batch": 37, **SMALL}),
]


def env(interpret: bool) -> dict[str, str]:
    e = {k: v for k, v in cells.worker_env("triton").items() if k != "TRITON_INTERPRET"}
    return {**e, "TRITON_INTERPRET": "1"} if interpret else e


def need_triton() -> None:
    if importlib.util.find_spec("triton") is None or importlib.util.find_spec("torch") is None:
        pytest.skip("triton or torch not installed (pip install -e '.[triton]')")


def script(body: str, interpret: bool, timeout: int = 900) -> dict:
    """Run ``body`` in a fresh interpreter (Triton reads TRITON_INTERPRET when it decorates the
    kernels); it prints RESULT<json>."""
    need_triton()
    code = "import json\nimport numpy as np\nimport backends, scenarios\n" + textwrap.dedent(body)
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env(interpret), capture_output=True,
                          text=True, timeout=timeout, stdin=subprocess.DEVNULL)
    line = next((r for r in proc.stdout.splitlines() if r.startswith("RESULT")), None)
    assert line, proc.stderr[-3000:]
    return json.loads(line[len("RESULT"):])


LOOP = """
import torch, triton, triton.language as tl
@triton.jit
def count(out, n):
    acc = 0.0
    for _ in range(n):          # a loop bound from a runtime argument, as every scenario's kernel has
        acc += 1.0
    tl.store(out, acc)
o = torch.zeros(1)
try:
    count[(1,)](o, 3)
    err = None
except Exception as e:          # the probe reports, the tests decide
    err = repr(e)
print("RESULT" + json.dumps({"error": err, "triton": triton.__version__, "numpy": np.__version__}))
"""


@functools.cache
def interpreter_refusal() -> str | None:
    """Why this Triton's interpreter cannot run a loop under the installed NumPy, or None: older
    Triton interpreters (3.6 on the lent GPU image) convert a loop bound with int() of a
    one-element array, which NumPy 2.4 refuses; newer ones squeeze it first. Any other failure
    is left to the tests."""
    got = script(LOOP, interpret=True)
    if got["error"] and "only 0-dimensional arrays can be converted" in got["error"]:
        return (f"Triton {got['triton']}'s interpreter cannot run a loop under NumPy {got['numpy']} "
                f"(int() of a one-element array; newer Triton squeezes it: pip install -U triton); "
                f"its compiled CUDA kernels are unaffected")
    return None


def need_interpreter() -> None:
    if why := interpreter_refusal():
        pytest.skip(why)


# ---- 1. import, reasons, listing, skipped cells -----------------------------------------------
def test_package_imports_without_triton_and_says_why() -> None:
    """Importing the package imports neither triton nor torch; without triton every device says
    why, CUDA with the install command; the CPU reason always names the interpreter."""
    code = ("import sys, json, backends\n"
            "frameworks = [m for m in ('triton', 'torch') if sys.modules.get(m) is not None]\n"
            "print(json.dumps([backends.get('triton').available(), frameworks]))\n")
    for hide in ("", "import sys; sys.modules['triton'] = None\n"):
        proc = subprocess.run([sys.executable, "-c", hide + code], cwd=ROOT, env=env(False),
                              capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr
        avail, frameworks = json.loads(proc.stdout.strip().splitlines()[-1])
        assert frameworks == []
        assert "interpreter (TRITON_INTERPRET=1" in avail["cpu"] and "not timed" in avail["cpu"]
        if hide:
            assert avail["cuda"].startswith("triton not importable"), avail
            assert "pip install -e '.[triton]'" in avail["cuda"]


def test_backend_facts() -> None:
    assert (BACKEND.name, BACKEND.package, BACKEND.gradient_method) == ("triton", "triton", "adjoint")
    others = [b for n, b in backends.BACKENDS.items() if n != "triton"]
    assert BACKEND.color and BACKEND.color not in {b.color for b in others}
    assert all(BACKEND.has_kernel(s) for s in scenarios.SCENARIOS)
    assert BACKEND.variants_for("saxpy") == ("default",)
    assert BACKEND.event_timer("cpu") is None and BACKEND.capture("cpu", lambda: None) is None
    assert BACKEND.memory("cpu") == {}
    assert set(BACKEND.cache_environment(ROOT)) == {"TRITON_CACHE_DIR", "CUDA_CACHE_PATH"}


def test_interpreter_is_never_offered_for_timing() -> None:
    """Under TRITON_INTERPRET=1 neither device is offered: the CPU never is, and CUDA would run
    the interpreter, not compiled kernels."""
    got = script("print('RESULT' + json.dumps(backends.get('triton').available()))", interpret=True)
    assert "interpreter" in got["cpu"]
    assert got["cuda"].startswith("TRITON_INTERPRET=1 is set")


def test_compare_list_and_a_cpu_run_skip_triton_with_the_reason(tmp_path, compare_list) -> None:
    proc = compare_list
    line = next(r for r in proc.stdout.splitlines() if r.strip().startswith("triton "))
    assert "gradient=adjoint" in line and "cpu: Triton compiles for GPUs only" in line, line
    proc = subprocess.run([sys.executable, "-m", "compare", "saxpy", "--backends", "triton,numpy", "--devices",
                           "cpu", "--precision", "float32", "--quick", "--repeat", "1", "--out", str(tmp_path),
                           "--no-plots"], cwd=ROOT, env=env(False), capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    recs = {r["backend"]: r for r in json.loads((tmp_path / "results.json").read_text())["records"]}
    assert recs["numpy"]["status"] == "ok", recs["numpy"]
    assert recs["triton"]["status"] == "skipped" and "interpreter" in recs["triton"]["reason"], recs["triton"]


# ---- 2. PTX compiled here -----------------------------------------------------------------------
PTX = """
import re
import triton
from triton.backends.compiler import GPUTarget
from triton.compiler import ASTSource
from backends.triton import launch_options, saxpy, sdf, particles, projectile
OPS = re.compile(r"\\b(div|sqrt|rcp|fma|ld\\.global|st\\.global)(\\.[\\w]+)*")

def ops(fn, sig, constexprs, aligned=()):
    attrs = {(fn.arg_names.index(a),): [["tt.divisibility", 16]] for a in aligned}
    src = ASTSource(fn, {**sig, **{k: "constexpr" for k in constexprs}}, constexprs, attrs)
    ptx = triton.compile(src, target=GPUTarget("cuda", 90, 32), options=launch_options()).asm["ptx"]
    lines = [l.strip() for l in ptx.splitlines() if l.strip() and not l.strip().startswith((".", "//"))]
    return {"ops": sorted({m.group(0) for l in lines for m in OPS.finditer(l)}),
            "f64": sorted({l.split()[0] for l in lines if ".f64" in l.split()[0]})}

out = {}
for prec, t in (("float32", "fp32"), ("float64", "fp64")):
    P = "*" + t
    out["saxpy-" + prec] = ops(saxpy.saxpy_kernel, dict(a_ptr=P, x_ptr=P, y_ptr=P, out_ptr=P, n="i32"),
                               {"BLOCK_SIZE": 1024}, aligned=("a_ptr", "x_ptr", "y_ptr", "out_ptr", "n"))
    out["sdf-" + prec] = ops(sdf.sdf_kernel, dict(image_ptr=P, width="i32", height="i32"),
                             {"BLOCK_H": 8, "BLOCK_W": 128})
    names = particles.particles_kernel.arg_names
    out["particles-" + prec] = ops(particles.particles_kernel, {**{a: P for a in names[:11]}, "n": "i32",
                                   "steps": "i32", "record_every": "i32"}, {"RECORD": True, "BLOCK": 128})
    names = projectile.projectile_kernel.arg_names
    sig = {**{a: P for a in names[:8]}, "hit_ptr": "*u8", "batch": "i32", "steps": "i32", "iters": "i32"}
    for c, v in projectile.CONTACT.items():
        out[f"projectile-{c}-" + prec] = ops(projectile.projectile_kernel, sig, {"CONTACT": v, "BLOCK": 128})
print("RESULT" + json.dumps(out))
"""
# sinf's slow path (Payne-Hanek reduction of huge arguments) in libdevice multiplies in double
SINF_REDUCTION = {"cvt.rn.f64.s64", "mul.f64", "cvt.rn.f32.f64"}


@pytest.fixture(scope="module")
def ptx() -> dict:
    return script(PTX, interpret=False)


@pytest.mark.xdist_group("triton-ptx")
@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_ptx_precision_ieee_division_and_fma(ptx, precision) -> None:
    t = "f32" if precision == "float32" else "f64"
    for name, got in ptx.items():
        if not name.endswith(precision):
            continue
        ops = set(got["ops"])
        assert f"fma.rn.{t}" in ops, (name, ops)                    # contraction on, as NVRTC's default
        assert not any(".ftz" in o for o in ops if o.startswith(("div", "sqrt", "fma"))), (name, ops)
        assert not any(o.startswith(("div.full", "div.approx", "sqrt.approx")) for o in ops), (name, ops)
        if precision == "float64":
            assert got["f64"], name                                 # the probe sees doubles
        elif name.startswith("sdf"):
            assert set(got["f64"]) <= SINF_REDUCTION, got["f64"]
        else:
            assert not got["f64"], (name, got["f64"])
    for name in (f"sdf-{precision}", f"projectile-soft-{precision}"):
        assert f"div.rn.{t}" in ptx[name]["ops"], name              # libdevice's IEEE division
    assert f"sqrt.rn.{t}" in ptx[f"sdf-{precision}"]["ops"]


@pytest.mark.xdist_group("triton-ptx")
@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_ptx_saxpy_moves_16_bytes_per_access(ptx, precision) -> None:
    lanes = "v4.b32" if precision == "float32" else "v2.b64"
    ops = set(ptx[f"saxpy-{precision}"]["ops"])
    assert f"ld.global.{lanes}" in ops and f"st.global.{lanes}" in ops, ops


# ---- 3. the kernels under the interpreter ---------------------------------------------------------
_runs: dict = {}


def interp_cells(backend: str, precision: str) -> dict:
    """Every INTERP_CASES cell of one backend and precision through the worker, one process."""
    key = (backend, precision)
    if key not in _runs:
        need_triton()
        need_interpreter()
        if backend != "triton" and availability(backend).get("cpu"):
            pytest.skip(f"{backend}/cpu: {availability(backend)['cpu']}")
        specs = [{"scenario": s, "backend": backend, "device": "cpu", "precision": precision, "params": o,
                  "quick": True, "repeat": 1, "warmup": 0, "min_time": 0.0, "cache": "warm",
                  "throughput": False} for s, o in INTERP_CASES]
        old = os.environ.get("TRITON_INTERPRET")
        os.environ["TRITON_INTERPRET"] = "1"          # the workers inherit it (cells.worker_env)
        try:
            results = cells.run_batch([Cell.from_dict(s) for s in specs], timeout=900)
        finally:
            os.environ.pop("TRITON_INTERPRET") if old is None else os.environ.__setitem__("TRITON_INTERPRET", old)
        _runs[key] = dict(zip(range(len(INTERP_CASES)), results))
    return _runs[key]


@pytest.mark.xdist_group("triton-interpreted")      # interp_cells' cache: its cells run once
@pytest.mark.parametrize("precision", ["float64", "float32"])
@pytest.mark.parametrize("case", range(len(INTERP_CASES)),
                         ids=[f"{s}-" + ",".join(f"{k}={v}" for k, v in o.items()) for s, o in INTERP_CASES])
def test_interpreted_parity(case: int, precision: str) -> None:
    scenario, overrides = INTERP_CASES[case]
    record, out = interp_cells("triton", precision)[case]
    assert record["status"] == "ok", f"{record['status']}: {record.get('reason')}\n{record.get('traceback', '')}"
    assert record["error"]["vs_oracle"] <= record["error"]["tolerance"]
    assert {str(a.dtype) for a in out.values()} == {precision}
    if precision == "float64" and scenario in TIGHT_VS_WARP:
        ref_rec, ref_out = interp_cells(backends.reference(), "float64")[case]
        assert ref_rec["status"] == "ok", ref_rec.get("reason")
        sc = scenarios.get(scenario)
        p = sc.params(overrides, quick=True)
        d = sc.distance(p, sc.inputs(p, "float64"), out, ref_out)
        assert d <= TIGHT_VS_WARP[scenario], f"float64 triton vs {backends.reference()} differ by {d:.3g}"


ADJOINT = """
sc, b = scenarios.get("projectile"), backends.get("triton")
def build(over, precision, inputs=None):
    p = sc.params(over)
    i = sc.inputs(p, precision) if inputs is None else inputs
    k = b.kernel("projectile")(p, i, "cpu", precision, "default"); k.run()
    return p, i, k
res = {"fd": [], "rows": [], "set_input": None}
h = 1e-6
for contact in ("none", "hard", "soft"):
    for v0 in ((2.0, 6.5), (1.3, 8.1)):
        over = {"contact": contact, "iters": 0, "vx0": v0[0], "vy0": v0[1]}
        p, inputs, k = build(over, "float64")
        grad = k.outputs()["grad"]
        # the five points of a central difference as one batch (rows are single runs: see below)
        pts = np.array([v0, *(np.array(v0) + s * h * e for e in np.eye(2) for s in (1, -1))])
        tgt = np.tile([p.target_x, p.target_y], (5, 1))
        kb = build({**over, "batch": 5}, "float64", {**inputs, "v0": pts, "target": tgt})[2]
        loss = kb.outputs()["loss"]
        fd = [(loss[1] - loss[2]) / (2 * h), (loss[3] - loss[4]) / (2 * h)]
        res["fd"].append({"case": [contact, v0], "grad": grad.tolist(), "fd": fd,
                          "oracle": sc.oracle(p, inputs, "float64")["grad"].tolist(), "row0": kb.outputs()["grad"][0].tolist(),
                          "fired": bool(k.arrays["hit"].numpy().any()), "below": bool((k.arrays["ys"].numpy() < 0).any())})
for precision in ("float64", "float32"):
    for contact in ("hard", "soft"):
        over = {"contact": contact, "batch": 6, "steps": 80, "iters": 3}
        p, inputs, k = build(over, precision)
        out = k.outputs()
        same = []
        for r in range(p.batch):
            _, _, one = build({**over, "batch": 1}, precision, {**inputs, "v0": inputs["v0"][r], "target": inputs["target"][r]})
            same.append(all((out[n][:, r] if n == "loss_history" else out[n][r]).tobytes() == a.tobytes()
                            for n, a in one.outputs().items()))
        res["rows"].append({"case": [precision, contact], "same": same, "distinct": len({tuple(g) for g in out["grad"]})})
over = {"contact": "soft", "batch": 4, "steps": 80, "iters": 3}
p, inputs, k = build(over, "float64")
new = {**inputs, "v0": inputs["v0"] * np.array([1.1, 0.9]) + 0.05, "target": inputs["target"][::-1].copy()}
k.set_input("v0", new["v0"]); k.set_input("target", new["target"]); k.run()
fresh = build(over, "float64", new)[2]
res["set_input"] = all(k.outputs()[n].tobytes() == a.tobytes() for n, a in fresh.outputs().items())
try:
    k.set_input("lr", np.array(0.1)); res["refuses_lr"] = False
except NotImplementedError:
    res["refuses_lr"] = True
print("RESULT" + json.dumps(res))
"""


@pytest.fixture(scope="module")
def adjoint() -> dict:
    need_interpreter()
    return script(ADJOINT, interpret=True)


@pytest.mark.xdist_group("triton-adjoint")
def test_adjoint_matches_central_differences_and_the_closed_form(adjoint) -> None:
    assert len(adjoint["fd"]) == 6
    for case in adjoint["fd"]:
        grad, fd, oracle = (np.array(case[k]) for k in ("grad", "fd", "oracle"))
        np.testing.assert_allclose(grad, fd, rtol=1e-6, atol=1e-6 * np.abs(grad).max(), err_msg=str(case["case"]))
        np.testing.assert_allclose(grad, oracle, rtol=1e-12, atol=1e-12, err_msg=str(case["case"]))
        assert case["row0"] == case["grad"], case["case"]
        contact = case["case"][0]
        assert case["fired"] == (contact == "hard"), case     # the contact fires: the test means something
        if contact == "soft":
            assert case["below"], "the projectile must penetrate the soft ground"


@pytest.mark.xdist_group("triton-adjoint")
def test_batch_rows_are_single_trajectories_bit_for_bit(adjoint) -> None:
    assert len(adjoint["rows"]) == 4
    for case in adjoint["rows"]:
        assert case["same"] == [True] * 6 and case["distinct"] == 6, case


@pytest.mark.xdist_group("triton-adjoint")
def test_set_input_reruns_at_the_new_inputs(adjoint) -> None:
    assert adjoint["set_input"] and adjoint["refuses_lr"]


# ---- 4. on a GPU ------------------------------------------------------------------------------------
def require_gpu() -> None:
    why = availability("triton").get("cuda")
    if why:
        pytest.skip(f"Triton's compiled kernels run on a CUDA GPU only; {why}")


@pytest.mark.parametrize("precision", ["float64", "float32"])
@pytest.mark.parametrize("scenario,overrides", GPU_CASES, ids=[f"{s}-{o}" for s, o in GPU_CASES])
def test_gpu_cell_with_events_graph_and_memory(scenario, overrides, precision) -> None:
    require_gpu()
    assert_gpu_cell_with_events_graph_and_memory("triton", scenario, overrides, precision)


GPU_SCRIPT = row0_and_replay("triton", 300)


def test_gpu_batch_row0_set_input_and_graph_replay() -> None:
    require_gpu()
    res = script(GPU_SCRIPT, interpret=False)
    assert all(res.values()), res
