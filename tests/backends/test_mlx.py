"""MLX-specific checks beyond the generic parity suite: outputs in the cell's precision (float64
really computed in float64, MLX's float32-rounding exp/sin worked around), AD gradients against
the closed form and float64 finite differences (single and vmapped batch), trajectories, a timed
call that really computes under lazy evaluation, a copy into new memory, compiled functions
traced once (also across set_input), the on-disk kernel cache, and the device/precision reasons."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import scenarios
from compare.running import cells
from compare.spec import Cell
from conftest import require_device, run_script
from oracle_checks import FRAMES, assert_frames_match_the_oracle
from scenarios.projectile import CONSTANTS
from scenarios.projectile_adjoint import closed_form, finite_difference_gradient, loss_of

pytestmark = pytest.mark.mlx

SMALL = {"saxpy": {"n": 257, "inputs": "random", "seed": 3}, "sdf": {"width": 5, "height": 3},
         "particles": {"n": 33, "steps": 57}, "projectile": {"contact": "soft", "iters": 2},
         "launch": {"n": 3}, "copy": {"n": 1000}}


def _run(scenario: str, precision: str, params: dict, device: str = "cpu"):
    require_device("mlx", device)
    # warm: MLX's default kernel cache, shared with the parity suite (a cold cell recompiles
    # every fused kernel with g++); test_cold_cache_compiles_into_the_cells_directory covers cold
    spec = {"scenario": scenario, "backend": "mlx", "device": device, "precision": precision,
            "params": params, "quick": True, "repeat": 1, "min_time": 0.0, "cache": "warm"}
    record, outputs = cells.run(Cell.from_dict(spec), timeout=900)
    assert record["status"] == "ok", \
        f"{record['status']}: {record.get('reason')}\n{record.get('traceback', '')}"
    return record, outputs


def _oracle_constants(params: dict, precision: str = "float64"):
    sc = scenarios.get("projectile")
    p = sc.params(params, quick=True)
    inputs = sc.inputs(p, precision)
    c = {k: float(inputs[k]) for k in CONSTANTS}
    tgt = inputs["target"].astype(np.float64)
    c["target_x"], c["target_y"] = tgt[..., 0], tgt[..., 1]
    return p, inputs, c


@pytest.mark.parametrize("precision", ["float64", "float32"])
@pytest.mark.parametrize("scenario", list(SMALL))
def test_outputs_have_the_cells_precision(scenario, precision):
    record, outputs = _run(scenario, precision, SMALL[scenario])
    assert {k: v.dtype for k, v in outputs.items()} == {k: np.dtype(precision) for k in outputs}
    assert record["info"]["launch"] == "mx.async_eval per run()"


def test_float64_is_computed_in_float64():
    """mx.array turns float64 NumPy arrays into float32 unless told: the float64 cell must not."""
    _, out = _run("saxpy", "float64", SMALL["saxpy"])
    assert np.any(out["out"] != out["out"].astype(np.float32).astype(np.float64))


def test_float64_exp_and_sin_are_float64_accurate():
    """backends.mlx.exp/sin (pow and the tan half-angle identity) in float64, against NumPy;
    MLX's own mx.exp/mx.sin round through float32 on the x86-64 CPU (docs/findings.md)."""
    res = run_script("mlx", """
        import numpy as np, mlx.core as mx
        from backends.mlx import exp, sin
        mx.set_default_device(mx.cpu)          # float64 is CPU-only (a CUDA build refuses it)
        x = np.linspace(-30.0, 5.0, 20001)
        s = np.linspace(-8.0, 8.0, 20001)
        e = np.array(exp(mx.array(x, dtype=mx.float64)))
        t = np.array(sin(mx.array(s, dtype=mx.float64)))
        print("RESULT" + json.dumps({
            "exp_rel": float(np.max(np.abs(e - np.exp(x)) / np.exp(x))),
            "sin_abs": float(np.max(np.abs(t - np.sin(s)))),
            "dtypes": [str(e.dtype), str(t.dtype)],
            "f32_exp_is_mx_exp": bool(np.array_equal(np.array(exp(mx.array(x, dtype=mx.float32))),
                                                     np.array(mx.exp(mx.array(x, dtype=mx.float32)))))}))
    """)
    assert res["dtypes"] == ["float64", "float64"]
    assert res["exp_rel"] <= 40 * 2.0 ** -52          # |x| u from rounding e, plus pow's own
    assert res["sin_abs"] <= 4 * 2.0 ** -53
    assert res["f32_exp_is_mx_exp"]


def test_gradient_without_contact_is_the_closed_form():
    _, outputs = _run("projectile", "float64", {"contact": "none", "iters": 0})
    p, inputs, c = _oracle_constants({"contact": "none", "iters": 0})
    loss, grad = closed_form(c, p.steps, inputs["v0"].astype(np.float64))
    np.testing.assert_allclose(outputs["grad"], grad, rtol=1e-13)
    assert float(outputs["loss"]) == pytest.approx(float(loss), rel=1e-13)


@pytest.mark.parametrize("batch", [1, 37])
@pytest.mark.parametrize("contact", ["hard", "soft"])
def test_gradient_matches_finite_differences_of_the_oracle(contact, batch):
    """mx.value_and_grad (vmapped for a batch) against float64 central differences (Richardson)
    of the oracle's loss, every trajectory."""
    params = {"contact": contact, "iters": 0, "batch": batch}
    _, outputs = _run("projectile", "float64", params)
    p, inputs, c = _oracle_constants(params)
    v0 = inputs["v0"].astype(np.float64)
    fd = finite_difference_gradient(c, contact, p.steps, v0)
    grad = outputs["grad"]
    scale = np.max(np.abs(fd), axis=-1, keepdims=True)
    assert grad.shape == fd.shape
    assert np.all(np.abs(grad - fd) <= 1e-6 * np.abs(fd) + 1e-9 * scale), (grad, fd)
    np.testing.assert_allclose(outputs["loss"], loss_of(c, contact, p.steps, v0), rtol=1e-13)


def test_particle_trajectory_frames_match_the_oracle():
    assert_frames_match_the_oracle(_run("particles", "float64", FRAMES)[1])


LAZY = """
import mlx.core as mx
import numpy as np
be = backends.get("mlx"); be.setup(DEVICE, "float32", "default")
sc = scenarios.get("{scenario}")
p = sc.params({params})
k = be.kernel("{scenario}")(p, sc.inputs(p, "float32"), DEVICE, "float32", "default")
be.synchronize(DEVICE, k.run())
nbytes = {nbytes}
def grown(make):
    # two results alive, then the stream drained without evaluating either result
    k.out = None                      # the kernel's last result is not part of the baseline
    mx.synchronize(); base = mx.get_active_memory()
    r1 = make(); r2 = make()
    mx.synchronize()
    out = mx.get_active_memory() - base
    del r1, r2
    return out
res = {{"run": grown(k.run), "nbytes": nbytes}}
if hasattr(k, "program"):     # control: the same compiled call without run()'s async_eval
    res["lazy"] = grown(lambda: k.program({args}))
print("RESULT" + json.dumps(res))
"""


@pytest.mark.parametrize("scenario,params,nbytes,args", [
    ("saxpy", {"n": 1 << 18}, 4 << 18, "k.a, k.x, k.y"),
    ("copy", {"n": 1 << 18}, 4 << 18, ""),
])
def test_a_timed_call_really_computes(scenario, params, nbytes, args):
    """Each run() is started by mx.async_eval: two back-to-back calls whose results are never
    evaluated (the pipelined regime) both compute once the stream is drained. The control shows
    what the test detects: the compiled call alone builds a graph and computes nothing."""
    res = run_script("mlx", LAZY.format(scenario=scenario, params=params, nbytes=nbytes, args=args))
    assert res["run"] >= 2 * res["nbytes"], res
    if "lazy" in res:
        assert res["lazy"] < res["nbytes"], res


def test_copy_writes_new_memory():
    res = run_script("mlx", """
        import mlx.core as mx
        be = backends.get("mlx"); be.setup(DEVICE, "float64", "default")
        sc = scenarios.get("copy"); p = sc.params({"n": 1 << 16})
        k = be.kernel("copy")(p, sc.inputs(p, "float64"), DEVICE, "float64", "default")
        mx.synchronize(); base = mx.get_active_memory()
        r = k.run(); be.synchronize(DEVICE, r)
        print("RESULT" + json.dumps({"grown": mx.get_active_memory() - base, "same": r is k.x}))
    """)
    assert not res["same"] and res["grown"] >= 8 << 16


def test_set_input_reuses_the_compiled_iteration():
    """set_input on a batch: new v0 rows, no new trace, the results of a fresh kernel."""
    res = run_script("mlx", """
        import numpy as np
        from backends.mlx.projectile import Kernel
        be = backends.get("mlx"); be.setup(DEVICE, "float64", "default")
        sc = scenarios.get("projectile")
        p = sc.params({"contact": "hard", "batch": 5, "iters": 3, "steps": 40})
        i = sc.inputs(p, "float64")
        k = Kernel(p, i, DEVICE, "float64", "default")
        be.synchronize(DEVICE, k.run()); before = k.outputs()
        traces = k.info()["traces"]
        be.synchronize(DEVICE, k.run())
        v1 = np.ascontiguousarray(i["v0"][::-1])
        k.set_input("v0", v1)
        be.synchronize(DEVICE, k.run()); after = k.outputs()
        fresh = Kernel(p, {**i, "v0": v1}, DEVICE, "float64", "default")
        be.synchronize(DEVICE, fresh.run())
        try:
            k.set_input("v0", v1[:2]); refused = False
        except ValueError:
            refused = True
        print("RESULT" + json.dumps({
            "traces": [traces, k.info()["traces"]], "moved": bool(np.any(after["grad"] != before["grad"])),
            "same_as_fresh": all(after[n].tobytes() == a.tobytes() for n, a in fresh.outputs().items()),
            "refused": refused}))
    """)
    # traced in the first run only (twice: an input that is a compiled call's unevaluated
    # output is a new signature to MLX); later runs and a new v0 replay the traces
    first, last = res["traces"]
    assert 1 <= first <= 2 and last == first
    assert res["moved"] and res["same_as_fresh"] and res["refused"]


def test_cold_cache_compiles_into_the_cells_directory(tmp_path):
    """cache_environment points MLX's kernel cache (temp_directory_path()/mlx) into the cell's
    directory: a cold first call compiles with g++ there, not in a shared cache."""
    import os
    import shutil
    import subprocess
    import sys
    import backends
    from conftest import ROOT
    require_device("mlx", "cpu")
    if not shutil.which("g++"):
        pytest.skip("no g++: MLX cannot fuse on the CPU (install: apt-get install -y g++)")
    env = {**cells.worker_env(), **backends.get("mlx").cache_environment(tmp_path)}
    Path(env["TMPDIR"]).mkdir(parents=True)
    code = ("import mlx.core as mx\nmx.set_default_device(mx.cpu)\nf = mx.compile(lambda x: x * 3.0 + 1.0)\n"
            "print(f(mx.arange(5, dtype=mx.float32)).tolist())")
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    built = list(Path(env["TMPDIR"]).rglob("*.so"))
    assert built and all(str(b).startswith(str(tmp_path)) for b in built), os.listdir(tmp_path)
    # the CUDA JIT's PTX cache too, whatever MLX_PTX_CACHE_DIR the user had set
    assert Path(env["MLX_PTX_CACHE_DIR"]).parent == tmp_path


def test_devices_and_precisions_say_why():
    import backends
    from backends.mlx import CUDA_INSTALL
    be = backends.get("mlx")
    assert be.precision_unavailable("float64", "cuda").startswith("MLX has no float64 on a GPU")
    assert be.precision_unavailable("float64", "cpu") is None
    assert be.precision_unavailable("float32", "cuda") is None
    with pytest.raises(RuntimeError, match="no float64 on a GPU"):
        be.setup("cuda", "float64", "default")
    assert "mlx[cuda12]" in CUDA_INSTALL and "pip uninstall -y mlx-cpu" in CUDA_INSTALL
    avail = be.available()
    if avail["cpu"] and "not importable" in avail["cpu"]:
        assert "pip install -e '.[mlx]'" in avail["cpu"]
        pytest.skip(f"MLX not installed: {avail['cpu']}")
    assert avail["cpu"] is None
    if avail["cuda"] and "mlx-cuda" not in avail["cuda"]:     # a CPU (or Metal) build
        assert "has no CUDA backend" in avail["cuda"] and CUDA_INSTALL in avail["cuda"]
    elif avail["cuda"]:
        assert "sees no usable GPU" in avail["cuda"]


def test_findings_reproducer_still_needs_the_workaround():
    """docs/findings.md #8 run against the installed MLX: its float64 mx.exp/sin/cos still round
    through float32 (else the workaround in backends/mlx can go) and the workaround is exact."""
    import re
    import subprocess
    import sys
    from conftest import ROOT
    require_device("mlx", "cpu")
    text = (ROOT / "docs" / "findings.md").read_text()
    blocks = re.findall(r"```python\n(# reproducer: (\S+)\n.*?)```", text, flags=re.S)
    code = {name: body for body, name in blocks}["mlx-float64-transcendentals"]
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=cells.worker_env(),
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = dict(line.split(" ", 1) for line in proc.stdout.splitlines())
    assert all(lines[k].endswith("OK") for k in ("pow(e,", "2t/(1+t*t)")), proc.stdout
    fixed = [k for k in ("mx.exp", "mx.sin", "mx.cos") if lines[k].endswith("OK")]
    assert not fixed, f"MLX now computes float64 {fixed} in float64: drop backends.mlx.exp/sin"


@pytest.mark.parametrize("contact", ["hard", "soft"])
def test_step_variant_computes_the_defaults_results(contact):
    """Variant ``step`` (mx.compile of one step, the loop traced per call) runs the same
    operations as the whole-iteration compile: the same outputs bit for bit on the CPU, batched
    through vmap too. Its step runs in Python for every step of every evaluation (the loop is
    traced per call: the variant's cost), where the whole-iteration compile traces once or twice."""
    res = run_script("mlx", """
        import numpy as np
        from backends.mlx.projectile import Kernel
        be = backends.get("mlx"); be.setup(DEVICE, "float64", "default")
        sc = scenarios.get("projectile")
        p = sc.params({"contact": "CONTACT", "batch": 5, "iters": 3, "steps": 40})
        i = sc.inputs(p, "float64")
        out, traces = {}, []
        for variant in ("default", "step"):
            k = Kernel(p, i, DEVICE, "float64", variant)
            be.synchronize(DEVICE, k.run()); be.synchronize(DEVICE, k.run())
            out[variant] = k.outputs()
            traces.append(k.info()["traces"])
        print("RESULT" + json.dumps({
            "same": all(out["step"][n].tobytes() == a.tobytes() for n, a in out["default"].items()),
            "step_traces": traces[1]}))
    """.replace("CONTACT", contact))
    assert res["same"]
    assert res["step_traces"] == 40 * (3 + 1) * 2      # steps x evaluations x runs


def test_synchronize_waits_with_eval_alone():
    """synchronize(result) is mx.eval(result) alone (no mx.synchronize), and it waits: the stream
    has nothing left of a long run once it returns, so the values read after it are final; without
    a result it drains the stream with mx.synchronize."""
    res = run_script("mlx", """
        import time
        import numpy as np
        import mlx.core as mx
        be = backends.get("mlx"); be.setup(DEVICE, "float32", "default")
        sc = scenarios.get("particles")
        p = sc.params({"n": 1 << 18, "steps": 300})
        k = be.kernel("particles")(p, sc.inputs(p, "float32"), DEVICE, "float32", "default")
        be.synchronize(DEVICE, k.run()); first = k.outputs()
        real, calls = mx.synchronize, []
        mx.synchronize = lambda *a: (calls.append(1), real(*a))[1]
        t = time.perf_counter(); r = k.run(); launched = time.perf_counter() - t
        be.synchronize(DEVICE, r); waited = time.perf_counter() - t
        after_eval = len(calls)
        t = time.perf_counter(); real(); residual = time.perf_counter() - t
        same = all(np.array_equal(first[n], np.array(a)) for n, a in zip(("x", "y", "vx", "vy"), r))
        be.synchronize(DEVICE, None)
        print("RESULT" + json.dumps({"calls": [after_eval, len(calls)], "waited": waited,
                                     "launched": launched, "residual": residual, "same": same}))
    """)
    assert res["calls"] == [0, 1], res
    assert res["same"], res
    # eval returned after the work: the stream had (next to) nothing left to drain
    assert res["residual"] < 0.1 * res["waited"], res


@pytest.mark.parametrize("params", [{"n": 33, "steps": 57, "record_every": 7}, {"n": 1000, "steps": 40}])
def test_rollout_variant_computes_the_defaults_results(params):
    """Variant ``rollout`` (mx.compile of the whole rollout) runs the default's operations in its
    order: the same outputs bit for bit on the CPU (trajectories too), traced once or twice in the
    first run and never again (the default traces its step the same way)."""
    res = run_script("mlx", """
        from backends.mlx.particles import Kernel
        be = backends.get("mlx"); be.setup(DEVICE, "float64", "rollout")
        sc = scenarios.get("particles")
        p = sc.params(PARAMS)
        i = sc.inputs(p, "float64")
        out, traces = {}, []
        for variant in ("default", "rollout"):
            k = Kernel(p, i, DEVICE, "float64", variant)
            be.synchronize(DEVICE, k.run()); first = k.info()["traces"]
            be.synchronize(DEVICE, k.run()); be.synchronize(DEVICE, k.run())
            out[variant] = k.outputs()
            traces.append([first, k.info()["traces"]])
        print("RESULT" + json.dumps({
            "names": [sorted(out["default"]), sorted(out["rollout"])], "loop": k.info()["loop"],
            "same": all(out["rollout"][n].tobytes() == a.tobytes() for n, a in out["default"].items()),
            "traces": traces}))
    """.replace("PARAMS", repr(params)))
    assert res["names"][0] == res["names"][1] and ("traj_x" in res["names"][0]) == bool(params.get("record_every"))
    assert res["same"], res
    first, last = res["traces"][1]
    assert 1 <= first <= 2 and last == first, res
    assert "whole rollout" in res["loop"]


def test_rollout_is_a_particles_variant_only():
    import backends
    be = backends.get("mlx")
    assert "rollout" in be.variants_for("particles") and "rollout" not in be.variants_for("saxpy")
