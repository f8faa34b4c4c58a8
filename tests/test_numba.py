"""Numba-specific checks beyond the generic parity suite.

1. float32 discipline: the float32 specialisations compile to code without any double arithmetic
   (Python float literals would promote to float64), and agree with Warp's float32 output;
2. the hand-written projectile adjoint against float64 central finite differences;
3. the CUDA kernels, run for correctness (never timed) under the CUDA simulator in a subprocess.
"""
from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import backends
import scenarios
from compare import cells
from conftest import ROOT, require_device

pytestmark = pytest.mark.numba
pytest.importorskip("numba")

BACKEND = backends.get("numba")
TINY = {"saxpy": {"n": 37}, "sdf": {"width": 11, "height": 7},
        "particles": {"n": 37, "steps": 20, "record_every": 6},
        "projectile": {"contact": "soft", "steps": 80, "iters": 3}}


def build(scenario: str, overrides: dict, precision: str, variant: str = "default",
          inputs: dict | None = None):
    sc = scenarios.get(scenario)
    p = sc.params(overrides)
    inputs = sc.inputs(p, precision) if inputs is None else inputs
    k = BACKEND.kernel(scenario)(p, inputs, "cpu", precision, variant)
    k.run()
    return sc, p, inputs, k


def llvm_ir(kernel, precision: str) -> tuple[str, str]:
    """(signature, LLVM IR) of the kernel's specialisation for ``precision``: the compiled body,
    the parfor gufunc and inlined helpers; without the CPython wrapper, whose unboxing of a
    float32 argument goes through PyFloat_AsDouble, and without declarations."""
    (sig, ir), = [(sig, ir) for sig, ir in kernel.fn.inspect_llvm().items()
                  if ("float32" in str(sig)) == (precision == "float32")]
    bodies = [f for f in ir.split("\ndefine ")[1:] if "@_ZN7cpython" not in f.split("(", 1)[0]]
    return str(sig), "\n".join(f.split("\n}", 1)[0] for f in bodies)


# ---- 1. float32 discipline -----------------------------------------------------------------------
@pytest.mark.parametrize("variant", BACKEND.variants)
@pytest.mark.parametrize("scenario", list(TINY))
def test_float32_has_no_double_arithmetic(scenario: str, variant: str) -> None:
    sig, ir = llvm_ir(build(scenario, TINY[scenario], "float32", variant)[3], "float32")
    assert "float64" not in sig
    assert " double " not in ir, [line for line in ir.splitlines() if " double " in line][:5]


@pytest.mark.parametrize("scenario", list(TINY))
def test_float64_ir_probe_sees_doubles(scenario: str) -> None:
    """The probe above is meaningful: the float64 specialisation is full of doubles."""
    assert " double " in llvm_ir(build(scenario, TINY[scenario], "float64")[3], "float64")[1]


F32_VS_WARP = [("saxpy", {}), ("saxpy", {"n": 257, "inputs": "random", "seed": 3}), ("sdf", {}),
               ("particles", {}), ("particles", {"n": 33, "steps": 57, "record_every": 7}),
               ("projectile", {"contact": "none"}), ("projectile", {"contact": "hard"}),
               ("projectile", {"contact": "soft"})]
MAX_ULP = 2


@pytest.mark.parametrize("scenario,overrides", F32_VS_WARP,
                         ids=[f"{s}-{o}" for s, o in F32_VS_WARP])
def test_float32_agrees_with_warp(scenario: str, overrides: dict) -> None:
    """Same algorithm, same operation order: a couple of ulps at most (bitwise on x86 CPUs).

    For the projectile only loss and gradient at v0 are compared ulp-wise: the soft contact's
    gradient-descent history amplifies one-ulp differences enormously (see projectile.py).
    """
    require_device("numba", "cpu")
    require_device(backends.reference(), "cpu")
    outs = {}
    for name in ("numba", backends.reference()):
        spec = {"scenario": scenario, "backend": name, "device": "cpu", "precision": "float32",
                "params": overrides, "quick": True, "repeat": 1, "min_time": 0.0}
        record, outs[name] = cells.run(spec, timeout=600)
        assert record["status"] == "ok", record.get("reason")
    ours, ref = outs["numba"], outs[backends.reference()]
    keys = ("loss", "grad") if scenario == "projectile" else ref.keys()
    for key in keys:
        assert ours[key].dtype == np.float32, key
        np.testing.assert_array_max_ulp(ours[key], ref[key], maxulp=MAX_ULP, dtype=np.float32)


# ---- 2. the hand-written adjoint -----------------------------------------------------------------
@pytest.mark.parametrize("contact", ("none", "hard", "soft"))
@pytest.mark.parametrize("v0", ((2.0, 6.5), (1.3, 8.1)))
def test_adjoint_matches_central_differences(contact: str, v0: tuple[float, float]) -> None:
    overrides = {"contact": contact, "iters": 0, "vx0": v0[0], "vy0": v0[1]}
    sc, p, inputs, k = build("projectile", overrides, "float64")
    grad = k.outputs()["grad"]
    if contact == "hard":
        assert k.arrays["hit"].any(), "the contact must fire for the test to mean anything"
    if contact == "soft":
        assert (k.arrays["ys"] < 0).any(), "the projectile must penetrate the soft ground"

    def loss(v: np.ndarray) -> float:
        return float(build("projectile", overrides, "float64", inputs={**inputs, "v0": v})[3]
                     .outputs()["loss"])

    h = 1e-6
    fd = np.array([(loss(inputs["v0"] + h * e) - loss(inputs["v0"] - h * e)) / (2 * h)
                   for e in np.eye(2)])
    np.testing.assert_allclose(grad, fd, rtol=1e-6, atol=1e-6 * np.abs(grad).max())
    # and the scenario's float64 reference (closed form / python adjoint), to rounding
    np.testing.assert_allclose(grad, sc.oracle(p, inputs)["grad"], rtol=1e-12, atol=1e-12)


# ---- 3. CUDA kernels under the simulator -----------------------------------------------------------
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
            c = sc.check(p, inputs, o, sc.oracle(p, inputs), precision)
            out["cases"].append({"case": f"{name}-{overrides}-{precision}", "ok": bool(c.ok),
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
             ("projectile", {"contact": "soft", "steps": 80, "iters": 3})]


def test_cuda_kernels_under_simulator() -> None:
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


def test_package_import_does_not_import_numba() -> None:
    code = "import sys, backends.numba; print('numba' in sys.modules)"
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=cells.worker_env(),
                          capture_output=True, text=True, timeout=120)
    assert proc.stdout.strip().splitlines()[-1] == "False", proc.stderr[-2000:]
