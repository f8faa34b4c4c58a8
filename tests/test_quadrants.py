"""Quadrants-specific checks beyond the generic parity suite.

1. variants: the default is IEEE (fast_math=False; Quadrants' own default is True, as Taichi's);
   the fast-math variant runs and reports a finite error; importing the backend package does not
   import Quadrants;
2. precision and operation order: outputs carry the cell's dtype and agree with Warp's float32
   output to a couple of ulps;
3. autodiff: the fused rollout (one launch, step loop reversed through Quadrants' launch-time
   sized adstacks) against one launch per step, single and batched; every batch row against its
   own single-trajectory run, and set_input; no steps limit: a long rollout with a contact on
   every step (the deepest adstacks) stays fused and exact;
4. the guard decisions: the three Taichi 1.7 autodiff bugs the Taichi port guards against
   (docs/findings.md) are absent from the installed Quadrants, which is why this port carries
   none of the guards. The reproducers are the ones docs/findings.md prints, run as they are; if
   a Quadrants upgrade brings a bug back, this test fails before the port's gradients go wrong.
Anything that initialises Quadrants runs in a subprocess or a worker (qd.init is process-global).
"""
from __future__ import annotations

import json
import math
import re
import subprocess
import sys

import numpy as np
import pytest

import backends
from compare import cells
from conftest import ROOT, require_device, run_script, shared_cell

pytestmark = pytest.mark.quadrants

SMALL = {"saxpy": {"n": 257, "inputs": "random", "seed": 3}, "sdf": {"width": 11, "height": 7},
         "particles": {"n": 33, "steps": 57, "record_every": 7},
         "projectile": {"contact": "soft", "iters": 3}}


def _cells() -> list:
    """Every cell the tests marked xdist_group("quadrants-cells") run through the worker."""
    return ([("quadrants", s, "float32", SMALL[s], "cpu", "fastmath") for s in ("sdf", "projectile")]
            + [("quadrants", s, p, o, "cpu", "default") for s, o in SMALL.items()
               for p in ("float64", "float32")]
            + [(b, s, "float32", o, "cpu", "default") for b in ("quadrants", backends.reference())
               for s, o in VS_WARP])


def _run(scenario: str, precision: str, params: dict, device: str = "cpu",
         variant: str = "default", backend: str = "quadrants") -> tuple[dict, dict]:
    """One cell through the worker path; the module's cells share a worker process per
    precision and variant (conftest.shared_cell), each test asserts on its own."""
    return shared_cell("quadrants-cells", _cells(), backend, scenario, precision, params, device, variant)


def _script(body: str, device: str = "cpu") -> dict:
    """Run ``body`` in a fresh interpreter (its own qd.init); it prints RESULT<json>."""
    return run_script("quadrants", body, device)


# ---- 1. variants --------------------------------------------------------------------------------
@pytest.mark.xdist_group("quadrants-cells")
@pytest.mark.parametrize("scenario", ["sdf", "projectile"])
def test_fastmath_variant_runs_and_reports_a_finite_error(scenario):
    record, outputs = _run(scenario, "float32", SMALL[scenario], variant="fastmath")
    assert record["info"]["fast_math"] is True
    assert math.isfinite(record["error"]["vs_oracle"])      # within tolerance or not: reported
    assert all(np.all(np.isfinite(v)) for v in outputs.values())


@pytest.mark.xdist_group("quadrants-cells")
@pytest.mark.parametrize("scenario", list(SMALL))
def test_default_variant_is_not_fast_math(scenario):
    record, _ = _run(scenario, "float32", SMALL[scenario])
    assert record["status"] == "ok"
    assert record["info"]["fast_math"] is False


def test_unknown_variant_is_refused_before_quadrants_starts():
    with pytest.raises(ValueError, match="variant"):
        backends.get("quadrants").setup("cpu", "float32", "fast")


def test_package_import_does_not_import_quadrants():
    code = "import sys, backends.quadrants; print('quadrants' in sys.modules)"
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=cells.worker_env(),
                          capture_output=True, text=True, timeout=120)
    assert proc.stdout.strip().splitlines()[-1] == "False", proc.stderr[-2000:]


# ---- 2. precision and operation order -----------------------------------------------------------
@pytest.mark.xdist_group("quadrants-cells")
@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_outputs_have_the_cells_precision(precision):
    for scenario in SMALL:
        _, outputs = _run(scenario, precision, SMALL[scenario])
        assert {k: v.dtype for k, v in outputs.items()} == {k: np.dtype(precision) for k in outputs}


VS_WARP = [("saxpy", {"n": 257, "inputs": "random", "seed": 3}), ("sdf", {}),
           ("particles", {"n": 33, "steps": 57, "record_every": 7}),
           ("projectile", {"contact": "hard"}), ("projectile", {"contact": "soft"})]


@pytest.mark.xdist_group("quadrants-cells")
@pytest.mark.parametrize("scenario,overrides", VS_WARP, ids=[f"{s}-{o}" for s, o in VS_WARP])
def test_float32_agrees_with_warp_to_two_ulps(scenario, overrides):
    """Same algorithm, same operation order, same precision: a float64 literal or a reordered
    expression would show. For the projectile only loss and gradient at v0 (the soft contact's
    descent amplifies one-ulp differences: scenarios/projectile.py)."""
    require_device(backends.reference(), "cpu")
    ours = _run(scenario, "float32", overrides)[1]
    ref = _run(scenario, "float32", overrides, backend=backends.reference())[1]
    for key in (("loss", "grad") if scenario == "projectile" else ref):
        assert ours[key].dtype == np.float32, key
        np.testing.assert_array_max_ulp(ours[key], ref[key], maxulp=2, dtype=np.float32)


# ---- 3. autodiff --------------------------------------------------------------------------------
PATHS = """
import numpy as np
from backends.quadrants.projectile import Kernel
PRECISION = %r
out = {}
b = backends.get("quadrants"); b.setup(DEVICE, PRECISION, "default")
sc = scenarios.get("projectile")
for contact in ("none", "hard", "soft"):
    for batch in (1, 37):             # 37: more trajectories than CPU threads, not a warp multiple
        p = sc.params({"contact": contact, "steps": 60, "iters": 3, "batch": batch})
        i = sc.inputs(p, PRECISION)
        res = {}
        for fused in (True, False):
            Kernel.fused = fused
            k = Kernel(p, i, DEVICE, PRECISION, "default")
            b.synchronize(DEVICE, k.run())
            o = k.outputs()
            res[fused] = (o, bool(sc.check(p, i, o, sc.oracle(p, i, PRECISION), PRECISION).ok), k.info())
        Kernel.fused = True
        (o, ok, info), (o_step, ok_step, info_step) = res[True], res[False]
        out[f"{contact}-{batch}"] = {
            "ok": [ok, ok_step], "fused_flags": [info["fused_rollout"], info_step["fused_rollout"]],
            "shapes": {n: [list(o[n].shape), list(o_step[n].shape)] for n in o},
            "identical": all(np.array_equal(o[n], o_step[n]) for n in o),
            "rel": max(float(np.max(np.abs(o[n] - o_step[n]) / np.maximum(np.abs(o_step[n]), 1e-300)))
                       for n in ("loss", "grad"))}
print("RESULT" + json.dumps(out))
"""


@pytest.mark.parametrize("precision", ["float64", "float32"])
@pytest.mark.parametrize("device", backends.DEVICES)
def test_fused_rollout_equals_one_launch_per_step(device, precision):
    """The fused backward pass (adstacks, plain exp, mutating-if contact) gives the gradients,
    losses and iterates of the plain per-step differentiation (no loop to reverse), for one
    trajectory and a batch: bitwise on the CPU; on CUDA, where FMAs are contracted kernel by
    kernel, to a few roundings. Both within the oracle's bounds."""
    r = _script(PATHS % precision, device)
    assert len(r) == 6
    for case, v in r.items():
        batch = int(case.rsplit("-", 1)[1])
        assert v["ok"] == [True, True], case
        assert v["fused_flags"] == [True, False], case
        b = [] if batch == 1 else [batch]
        assert v["shapes"] == {"loss": [b, b], "grad": [b + [2]] * 2,
                               "loss_history": [[4] + b] * 2, "v_final": [b + [2]] * 2}, case
        if device == "cpu":
            assert v["identical"], case
        else:
            assert v["rel"] <= (1e-12 if precision == "float64" else 1e-4), case


ROWS = """
import numpy as np
from backends.quadrants.projectile import Kernel
b = backends.get("quadrants"); b.setup(DEVICE, "float64", "default")
sc = scenarios.get("projectile")
out = {}
for contact in ("hard", "soft"):
    p = sc.params({"contact": contact, "steps": 60, "iters": 3, "batch": 37})
    i = sc.inputs(p, "float64")
    k = Kernel(p, i, DEVICE, "float64", "default")
    b.synchronize(DEVICE, k.run())
    o = k.outputs()
    p1 = sc.params({"contact": contact, "steps": 60, "iters": 3})
    rows = {}
    for row in (0, 17, 36):
        i1 = dict(sc.inputs(p1, "float64"), v0=i["v0"][row].copy(), target=i["target"][row].copy())
        k1 = Kernel(p1, i1, DEVICE, "float64", "default")
        b.synchronize(DEVICE, k1.run())
        o1 = k1.outputs()
        rows[row] = all(np.array_equal(o1[n], o[n][:, row] if n == "loss_history" else o[n][row])
                        for n in o1)
    v0 = (i["v0"] * 0.9)[::-1].copy()
    k.set_input("v0", v0)
    b.synchronize(DEVICE, k.run())
    o_set = k.outputs()
    k2 = Kernel(p, dict(i, v0=v0), DEVICE, "float64", "default")
    b.synchronize(DEVICE, k2.run())
    o2 = k2.outputs()
    try:
        k.set_input("v0", v0[0])
        refused = False
    except ValueError:
        refused = True
    out[contact] = {"rows": rows, "distinct": len({float(x) for x in o["loss"]}),
                    "set_input": all(np.array_equal(o_set[n], o2[n]) for n in o2),
                    "set_input_changed": not np.array_equal(o_set["grad"], o["grad"]),
                    "wrong_shape_refused": refused}
print("RESULT" + json.dumps(out))
"""


def test_each_batch_row_is_its_own_single_trajectory():
    """Each row of a batch (not only row 0) equals a single-trajectory run at that row's v0 and
    target bit for bit: per-thread adstacks, independent loss seeds, no row/column mix-up in the
    (steps + 1, B) layout. set_input replaces a batch's v0 in place."""
    r = _script(ROWS)
    for contact, v in r.items():
        assert v["rows"] == {"0": True, "17": True, "36": True}, contact
        assert v["distinct"] == 37, contact
        assert v["set_input"] and v["set_input_changed"], contact
        assert v["wrong_shape_refused"], contact


LONG = """
import numpy as np
from backends.quadrants.projectile import Kernel
b = backends.get("quadrants"); b.setup(DEVICE, "float64", "default")
sc = scenarios.get("projectile")
out = {}
# 5000 steps: beyond Taichi's default 32 entries and past its ad_stack_size of 4096 (CPU) / 1024
# (CUDA); vy0 = 0 with hard contact clamps on every step, soft contact penetrates on every step:
# the deepest adstacks. t_N = 2 s.
for contact, vy0 in (("hard", 0.0), ("hard", 6.5), ("soft", 6.5)):
    p = sc.params({"contact": contact, "steps": 5000, "dt": 2.0 / 5000, "iters": 1, "vy0": vy0,
                   "batch": 3})
    i = sc.inputs(p, "float64")
    if vy0 == 0.0:
        i["v0"][:, 1] = 0.0
    res = []
    for fused in (True, False):
        Kernel.fused = fused
        k = Kernel(p, i, DEVICE, "float64", "default")
        b.synchronize(DEVICE, k.run())
        res.append(k.outputs())
    Kernel.fused = True
    o, o_step = res
    out[f"{contact}-{vy0}"] = {"identical": all(np.array_equal(o[n], o_step[n]) for n in o),
                               "finite": all(bool(np.all(np.isfinite(o[n]))) for n in o),
                               "nonzero_grad": bool(np.all(np.abs(o["grad"][:, 0]) > 0))}
print("RESULT" + json.dumps(out))
"""


def test_no_steps_limit_the_long_rollout_stays_fused_and_exact():
    """No ad_stack_size and no fallback: a 5000-step rollout (Taichi's port would leave the fused
    path past 4094 steps; Taichi's own default overflows past 32) with a contact on every step
    gives the per-step path's outputs bit for bit."""
    r = _script(LONG)
    for case, v in r.items():
        assert v == {"identical": True, "finite": True, "nonzero_grad": True}, case


# ---- 4. guard decisions: the Taichi 1.7 bugs are absent -----------------------------------------
def _findings_reproducers() -> dict[str, str]:
    """The reproducers docs/findings.md prints: ```python blocks whose first line is
    '# reproducer: NAME'."""
    text = (ROOT / "docs" / "findings.md").read_text()
    blocks = re.findall(r"```python\n(# reproducer: (\S+)\n.*?)```", text, flags=re.S)
    return {name: code for code, name in blocks}


AD_BUGS = ["adstack-overflow", "reassignment-pushes", "exp-backup"]


@pytest.mark.parametrize("name", AD_BUGS)
def test_taichi_autodiff_bug_is_absent_in_quadrants(name, tmp_path):
    """Each reproducer prints one line per case ending in OK (oracle's gradient) or WRONG, or
    fails loudly. Under Quadrants (adstack on, as the backend initialises it) every case is OK:
    the reason this port carries none of the Taichi port's guards."""
    require_device("quadrants", "cpu")
    code = _findings_reproducers()[name]
    path = tmp_path / f"{name}.py"
    path.write_text(code)
    proc = subprocess.run([sys.executable, str(path), "quadrants"], cwd=tmp_path,
                          env=cells.worker_env(), capture_output=True, text=True, timeout=600,
                          stdin=subprocess.DEVNULL)
    verdicts = [ln for ln in proc.stdout.splitlines() if ln.endswith(("OK", "WRONG"))]
    assert proc.returncode == 0 and verdicts, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert all(ln.endswith("OK") for ln in verdicts), "\n".join(verdicts)


def test_adstack_bound_must_be_readable_by_the_sizer(tmp_path):
    """Why the port reads the step count from a field: with the adstack on, a loop bounded by a
    kernel scalar argument is refused at compile time (loudly; Taichi 1.7 compiled it and
    overflowed silently), and the same loop bounded by a 0-d i32 field differentiates exactly.
    (A file, not ``python -c``: Quadrants reads a kernel's source through inspect.)"""
    require_device("quadrants", "cpu")
    script = tmp_path / "bound.py"
    script.write_text('''
import json
import quadrants as qd
qd.init(arch=qd.cpu, default_fp=qd.f64, ad_stack_experimental_enabled=True, offline_cache=False)
x = qd.field(float, (), needs_grad=True)
loss = qd.field(float, (), needs_grad=True)
n_f = qd.field(qd.i32, ())

@qd.kernel
def by_arg(n: qd.i32):
    for _ in range(1):
        y = x[None]
        for s in range(n):
            y = y + 0.1 * qd.sin(y)
        loss[None] = y

@qd.kernel
def by_field():
    for _ in range(1):
        y = x[None]
        for s in range(n_f[None]):
            y = y + 0.1 * qd.sin(y)
        loss[None] = y

out = {}
x[None] = 0.3
n_f[None] = 40
by_arg(40)
loss.grad[None] = 1.0
try:
    by_arg.grad(40)
    out["arg"] = "compiled"
except Exception as exc:
    out["arg"] = str(exc)
x.grad[None] = 0.0
by_field()
loss.grad[None] = 1.0
by_field.grad()
out["field"] = x.grad[None]
print("RESULT" + json.dumps(out))
''')
    proc = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=cells.worker_env(),
                          capture_output=True, text=True, timeout=600, stdin=subprocess.DEVNULL)
    line = next((ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT")), None)
    assert line, proc.stderr[-3000:]
    r = json.loads(line[len("RESULT"):])
    assert "unresolved" in r["arg"], r["arg"]
    y, want = 0.3, 1.0
    for _ in range(40):
        want *= 1.0 + 0.1 * math.cos(y)
        y = y + 0.1 * math.sin(y)
    assert r["field"] == pytest.approx(want, rel=1e-13)
