"""Numba's CUDA kernels beyond the generic parity suite (its CPU checks: tests/backends/test_numba.py):
run for correctness (never timed) under the CUDA simulator in a subprocess, the batched projectile
kernel lowered by the real CUDA target (no GPU needed), the package's lazy import, graph capture on
one stream, and the CPU without numba-cuda.
"""
from __future__ import annotations

import json
import re
import subprocess
import sys
import textwrap

import pytest

import backends
from compare.running import cells
from conftest import ROOT

pytestmark = pytest.mark.numba
pytest.importorskip("numba")


# ---- CUDA kernels under the simulator -----------------------------------------------------------
SIMULATED = textwrap.dedent("""
    import json
    import backends, scenarios
    b = backends.get("numba")
    out = {"available": b.available(), "cases": []}
    for name, overrides in json.loads(CASES):
        sc = scenarios.get(name)
        for precision in ("float64", "float32"):
            p = sc.params(overrides)
            inputs = sc.inputs(p, precision)
            k = b.kernel(name)(p, inputs, "cuda", precision, "default")
            b.synchronize("cuda", k.run())
            b.synchronize("cuda", k.run())          # repeatable
            o = k.outputs()
            c = sc.check(p, inputs, o, sc.oracle(p, inputs, precision), precision)
            batch = getattr(p, "batch", 1)
            rows = []    # a batch: does each row equal the single-trajectory kernel bit for bit?
            for r in range(batch if batch > 1 else 0):
                p1 = sc.params({**overrides, "batch": 1})
                k1 = b.kernel(name)(p1, {**inputs, "v0": inputs["v0"][r], "target": inputs["target"][r]},
                                    "cuda", precision, "default")
                b.synchronize("cuda", k1.run())
                rows.append(all((o[n][:, r] if n == "loss_history" else o[n][r]).tobytes() == a.tobytes()
                                for n, a in k1.outputs().items()))
            out["cases"].append({"case": f"{name}-{overrides}-{precision}", "ok": bool(c.ok),
                                 "batch": batch, "rows_equal_single": rows,
                                 "error": float(c.error), "tolerance": float(c.tolerance),
                                 "dtypes": sorted({str(v.dtype) for v in o.values()}),
                                 "info": k.info()})
    print("RESULT" + json.dumps(out))
""")
SIM_CASES = [("saxpy", {"n": 37}), ("saxpy", {"n": 37, "inputs": "random"}),
             ("sdf", {"width": 11, "height": 7}), ("particles", {"n": 37, "steps": 20}),
             ("particles", {"n": 37, "steps": 20, "record_every": 6}),
             ("projectile", {"contact": "none", "steps": 15, "iters": 3}),
             ("projectile", {"contact": "hard", "steps": 80, "iters": 3}),
             ("projectile", {"contact": "soft", "steps": 80, "iters": 3}),
             # batched: one thread per trajectory; B = 130 > THREADS_PER_BLOCK needs two blocks
             ("projectile", {"contact": "none", "batch": 5, "steps": 7, "iters": 3}),
             ("projectile", {"contact": "hard", "batch": 5, "steps": 80, "iters": 3}),
             ("projectile", {"contact": "soft", "batch": 5, "steps": 80, "iters": 3}),
             ("projectile", {"contact": "none", "batch": 130, "steps": 7, "iters": 1})]


# numba-cuda is in the cuda extras; its simulator needs none of the CUDA libraries (.ci/run's tier)
NUMBA_CUDA = ("numba-cuda not installed: its CUDA simulator and CUDA target run these tests without "
              "a GPU (install: pip install numba-cuda; a GPU machine: pip install -e '.[cuda]')")


def test_cuda_kernels_under_simulator() -> None:
    pytest.importorskip("numba_cuda", reason=NUMBA_CUDA)
    env = {**cells.worker_env(), "NUMBA_ENABLE_CUDASIM": "1"}
    script = f"CASES = {json.dumps(json.dumps(SIM_CASES))}\n" + SIMULATED
    proc = subprocess.run([sys.executable, "-c", script], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=600, stdin=subprocess.DEVNULL)
    line = next((r for r in proc.stdout.splitlines() if r.startswith("RESULT")), None)
    assert line, proc.stderr[-3000:]
    result = json.loads(line[len("RESULT"):])
    assert result["available"]["cuda"] == "CUDA simulator (correctness only)"   # never timed
    assert len(result["cases"]) == 2 * len(SIM_CASES)
    for case in result["cases"]:
        assert case["ok"], case
        assert case["dtypes"] == [case["case"].rsplit("-", 1)[1]], case
        batch, info = case["batch"], case["info"]
        assert case["rows_equal_single"] == [True] * (batch if batch > 1 else 0), case
        if batch > 1:     # one thread per trajectory, the fewest blocks that cover the batch
            assert info["tape_layout"] == "(steps, batch)", info
            tpb = info["threads_per_block"]
            assert info["blocks"] * tpb >= batch > (info["blocks"] - 1) * tpb, info


LOWER = textwrap.dedent("""
    # Lower the batched CUDA projectile kernel through numba-cuda's real CUDA target (typing and
    # LLVM IR; turning IR into PTX needs NVVM, absent here). The device function asks the current
    # device for its compute capability: there is none, so it is told sm_90.
    import json, types as pytypes
    import numpy as np
    from numba import types
    import numba.cuda.dispatcher as dispatcher
    from numba.cuda.compiler import compile_cuda
    dispatcher.get_current_device = lambda: pytypes.SimpleNamespace(compute_capability=(9, 0))
    from backends.numba import projectile
    out = {}
    for precision, S in (("float32", types.float32), ("float64", types.float64)):
        for fastmath in (False, True):
            kernel = projectile.cuda_kernel(np.dtype(precision).type, fastmath)
            a2 = types.Array(S, 2, "C")
            sig = (types.int64,) * 3 + (S,) * 7 + (a2,) * 4 + (types.Array(types.boolean, 2, "C"), a2, a2)
            cres = compile_cuda(kernel.py_func, types.void, sig, fastmath=fastmath, cc=(9, 0))
            ir = cres.library.get_llvm_str()
            body = [line for line in ir.splitlines() if not line.startswith(("declare", "!", "attributes"))]
            out[f"{precision}-{fastmath}"] = {
                "double_ops": [line for line in body if " double " in line and "fptrunc double" not in line],
                "calls": sorted({line.split("@", 1)[1].split("(", 1)[0].strip('"') for line in body
                                 if " call " in line}),
            }
    print("RESULT" + json.dumps(out))
""")


def test_cuda_projectile_lowers_for_the_real_target() -> None:
    """The simulator runs Python, not the CUDA target: lower the batched kernel for real (typing,
    tuple-returning device function, column views of the (steps, B) tape, libdevice maths). The
    float32 kernel has no double arithmetic (the only doubles are S(...) constants folded to
    float) and calls float32 libdevice functions (the fast ones with fastmath); float64 calls the
    double ones."""
    pytest.importorskip("numba_cuda", reason=NUMBA_CUDA)
    env = {k: v for k, v in cells.worker_env().items() if k != "NUMBA_ENABLE_CUDASIM"}
    proc = subprocess.run([sys.executable, "-c", LOWER], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=600, stdin=subprocess.DEVNULL)
    line = next((r for r in proc.stdout.splitlines() if r.startswith("RESULT")), None)
    assert line, proc.stderr[-3000:]
    result = json.loads(line[len("RESULT"):])
    assert len(result) == 4
    # libdevice maths per (precision, fastmath): fastmath's float32 takes the fast intrinsics
    maths = {"float32-False": {"__nv_expf", "__nv_logf"},
             "float32-True": {"__nv_fast_expf", "__nv_fast_logf"},
             "float64-False": {"__nv_exp", "__nv_log"}, "float64-True": {"__nv_exp", "__nv_log"}}
    for case, r in result.items():
        assert maths[case] <= set(r["calls"]), (case, r["calls"])
        if case.startswith("float32"):
            assert r["double_ops"] == [], (case, r["double_ops"][:5])
        else:
            assert r["double_ops"], case


def test_package_import_does_not_import_numba() -> None:
    code = "import sys, backends.numba; print('numba' in sys.modules)"
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=cells.worker_env(),
                          capture_output=True, text=True, timeout=120)
    assert proc.stdout.strip().splitlines()[-1] == "False", proc.stderr[-2000:]


def test_graph_capture_is_cuda_only_and_kernels_share_one_stream() -> None:
    """Numba's graph regime is driver stream capture on the stream every CUDA kernel launches on
    (CUDA cannot capture the legacy default stream): none on the CPU, and every CUDA kernel file
    configures its launch with launch_stream() (or launches through copy.py's Kernel, which does)."""
    import backends
    be = backends.get("numba")
    assert be.capture("cpu", lambda: None) is None
    for f in sorted((ROOT / "backends" / "numba").glob("*.py")):
        text = f.read_text()
        # a file that launches through copy.py's Kernel (launch.py) is checked there
        if "cuda.jit" in text and "from .copy import Kernel" not in text:
            assert re.search(r"\[[^\[\]]*launch_stream\(\)\)?\]", text), \
                f"{f.name} launches CUDA kernels off launch_stream()"


WITHOUT_NUMBA_CUDA = textwrap.dedent("""
    # a CPU-only install: numba-cuda absent (an import of it fails), whatever this venv holds
    import json, sys
    sys.modules["numba_cuda"] = None
    import backends, scenarios
    b = backends.get("numba")
    sc = scenarios.get("saxpy")
    p = sc.params({"n": 37})
    inputs = sc.inputs(p, "float32")
    k = b.kernel("saxpy")(p, inputs, "cpu", "float32", "default")
    k.run()
    c = sc.check(p, inputs, k.outputs(), sc.oracle(p, inputs, "float32"), "float32")
    print("RESULT" + json.dumps({"available": b.available(), "ok": bool(c.ok)}))
""")


def test_without_numba_cuda_the_cpu_runs_and_cuda_names_the_extra() -> None:
    """numba-cuda is in the cuda extras: without it the CPU kernels still build and pass, and the
    cuda device is skipped in one line naming the install command (simulator set or not: Numba's
    own numba.cuda, where a release ships it, is not the target this port is written for)."""
    for sim in ("0", "1"):
        env = {**cells.worker_env(), "NUMBA_ENABLE_CUDASIM": sim}
        proc = subprocess.run([sys.executable, "-c", WITHOUT_NUMBA_CUDA], cwd=ROOT, env=env,
                              capture_output=True, text=True, timeout=300, stdin=subprocess.DEVNULL)
        line = next((r for r in proc.stdout.splitlines() if r.startswith("RESULT")), None)
        assert line, proc.stderr[-3000:]
        result = json.loads(line[len("RESULT"):])
        assert result["available"]["cpu"] is None and result["ok"], result
        why = result["available"]["cuda"]
        assert "numba-cuda" in why and "pip install -e '.[cuda]'" in why and "\n" not in why, why
