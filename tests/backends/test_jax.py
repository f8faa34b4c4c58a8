"""JAX-specific checks beyond the generic parity suite: precision really follows the cell (the
x64 flag is per process), AD gradients agree with finite differences of the float64 oracle,
trajectories, donation, the rematerialisation option of the projectile (and its "checkpoint"
variant), and the batched projectile's compiled program being reused across set_input."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from compare.running import cells
from compare.spec import Cell
from conftest import ROOT, require_device, shared_cell
from oracle_checks import FD, FRAMES, assert_frames_match_the_oracle, assert_gradient_matches_finite_differences

pytestmark = pytest.mark.jax

# small cells, each one of the parity suite's cases (tests/backends/test_parity.py): the parity
# suite's worker processes give them (conftest.run_cases), no other process starts for them
SMALL = {"saxpy": {"n": 257, "inputs": "random", "seed": 3}, "sdf": {"width": 2, "height": 3},
         "particles": {"n": 33, "steps": 57, "record_every": 7}, "projectile": {"contact": "soft"}}


def _run(scenario: str, precision: str, params: dict, device: str = "cpu", variant: str = "default"):
    require_device("jax", device)
    spec = {"scenario": scenario, "backend": "jax", "device": device, "precision": precision,
            "variant": variant, "params": params, "quick": True, "repeat": 1, "min_time": 0.0}
    record, outputs = cells.run(Cell.from_dict(spec), timeout=600)
    assert record["status"] == "ok", \
        f"{record['status']}: {record.get('reason')}\n{record.get('traceback', '')}"
    return record, outputs


CELLS = ([("jax", s, p, o, "cpu", "default") for s, o in SMALL.items() for p in ("float64", "float32")]
         + [("jax", "projectile", "float64", o, "cpu", "default") for o in FD]
         + [("jax", "particles", "float64", FRAMES, "cpu", "default")])


def _shared(scenario: str, precision: str, params: dict) -> tuple[dict, dict]:
    """A cell of CELLS: they share a worker process per precision (conftest.shared_cell)."""
    record, outputs = shared_cell("jax-cells", CELLS, "jax", scenario, precision, params)
    assert record["status"] == "ok", \
        f"{record['status']}: {record.get('reason')}\n{record.get('traceback', '')}"
    return record, outputs


@pytest.mark.xdist_group("jax-cells")
@pytest.mark.parametrize("precision", ["float64", "float32"])
@pytest.mark.parametrize("scenario", list(SMALL))
def test_outputs_have_the_cells_precision(scenario, precision):
    _, outputs = _shared(scenario, precision, SMALL[scenario])
    assert {k: v.dtype for k, v in outputs.items()} == {k: np.dtype(precision) for k in outputs}


# a worker per cell is three JAX start-ups: the long tier; the fast tier reads the shared cells
@pytest.mark.xdist_group("jax-cells")
@pytest.mark.parametrize("shared", [True, pytest.param(False, marks=pytest.mark.slow)],
                         ids=["shared-workers", "a-worker-each"])
def test_back_to_back_cells_keep_their_own_precision(shared):
    """The x64 flag is process-global in JAX; each cell must get exactly the one it asked for,
    float64 after a float32 cell and float32 after a float64 one: a worker each (float32,
    float64, float32), or the shared cells' worker per precision, one after the other."""
    results = []
    for precision in ("float32", "float64", "float32"):
        _, out = (_shared if shared else _run)("saxpy", precision, SMALL["saxpy"])
        results.append((precision, out["out"]))
    for precision, out in results:
        assert out.dtype == np.dtype(precision)
        if precision == "float64":   # computed in float64, not float32 widened afterwards
            assert np.any(out != out.astype(np.float32).astype(np.float64))


@pytest.mark.xdist_group("jax-cells")
@pytest.mark.parametrize("contact", ["hard", "soft"])
def test_gradient_matches_finite_differences_of_the_oracle(contact):
    params = next(o for o in FD if o["contact"] == contact)
    assert_gradient_matches_finite_differences(_shared("projectile", "float64", params)[1], params)


@pytest.mark.xdist_group("jax-cells")
def test_particle_trajectory_frames_match_the_oracle():
    assert_frames_match_the_oracle(_shared("particles", "float64", FRAMES)[1])


@pytest.mark.xdist_group("jax-cells")
def test_info_reports_donation_and_memory():
    record, _ = _shared("particles", "float32", SMALL["particles"])
    info = record["info"]
    assert info["donated"] is True        # outputs are written into the previous call's buffers
    assert info["alias_bytes"] >= 4 * 33 * 4


REMAT = """
import json, sys
import numpy as np
import backends, scenarios
from backends.jax.projectile import Kernel
b = backends.get("jax"); b.setup("cpu", "float64", "default")
sc = scenarios.get("projectile")
p = sc.params({"contact": "soft", "steps": 4000, "dt": 0.025 * 180 / 4000, "iters": 2})
i = sc.inputs(p, "float64")
res = {}
for seg, unroll in ((0, 1), (63, 1), (64, 8)):
    k = Kernel(p, i, "cpu", "float64", "default", remat_segment=seg, unroll=unroll)
    b.synchronize("cpu", k.run())
    o = k.outputs()
    res[f"{seg}/{unroll}"] = {"temp": k.info()["temp_bytes"], "grad": o["grad"].tolist(),
                "hist": o["loss_history"].tolist(), "ok": sc.check(p, i, o, sc.oracle(p, i, "float64"), "float64").ok}
print("REMAT" + json.dumps(res))
"""


@pytest.mark.slow
def test_remat_and_unroll_options_keep_the_results():
    require_device("jax", "cpu")
    proc = subprocess.run([sys.executable, "-c", REMAT], cwd=ROOT, env=cells.worker_env(),
                          capture_output=True, text=True, timeout=600)
    line = next((r for r in proc.stdout.splitlines() if r.startswith("REMAT")), None)
    assert line, proc.stderr[-2000:]
    res = json.loads(line[5:])
    full = res["0/1"]
    assert full["ok"]
    for key in ("63/1", "64/8"):      # checkpointed segments (one unrolled): same run, less memory
        assert res[key]["ok"]
        assert res[key]["temp"] < full["temp"] / 4
        np.testing.assert_allclose(res[key]["grad"], full["grad"], rtol=1e-12)
        np.testing.assert_allclose(res[key]["hist"], full["hist"], rtol=1e-12)


BATCH = """
import json, sys
import numpy as np
import backends, scenarios
from backends.jax.projectile import Kernel, checkpoint_segment
from compare.running import reuse
b = backends.get("jax"); b.setup("cpu", "float64", "default")
sc = scenarios.get("projectile")
p = sc.params({"contact": "soft", "batch": 37}, quick=True)
i = sc.inputs(p, "float64")
ref = reuse.oracle(sc, p, i, "float64")     # the parity suite's cell asked it already
res = {"segment": checkpoint_segment(p.steps)}
kernels = {}
for variant in ("default", "checkpoint"):
    k = kernels[variant] = Kernel(p, i, "cpu", "float64", variant)
    b.synchronize("cpu", k.run())
    o = k.outputs()
    res[variant] = {"out": {n: a.tolist() for n, a in o.items()}, "ok": sc.check(p, i, o, ref, "float64").ok,
                    "temp": k.info()["temp_bytes"], "remat": k.info()["remat_segment"]}
# set_input on the batch: new v0 rows, same compiled program, the same results as a fresh kernel
k = kernels["default"]
compiled = k.program.compiled
before = k.outputs()
v1 = np.ascontiguousarray(i["v0"][::-1])
k.set_input("v0", v1)
b.synchronize("cpu", k.run())
after = k.outputs()
fresh = Kernel(p, {**i, "v0": v1}, "cpu", "float64", "default")
b.synchronize("cpu", fresh.run())
res["reused"] = k.program.compiled is compiled
res["same_as_fresh"] = all(after[n].tobytes() == a.tobytes() for n, a in fresh.outputs().items())
res["moved"] = bool(np.any(after["grad"] != before["grad"]))
try:
    k.set_input("v0", v1[:5]); res["shape_refused"] = False
except ValueError:
    res["shape_refused"] = True
try:
    Kernel(p, i, "cpu", "float64", "fastmath"); res["variant_refused"] = False
except ValueError:
    res["variant_refused"] = True
print("BATCH" + json.dumps(res))
"""


@pytest.fixture(scope="module")
def batch_results():
    require_device("jax", "cpu")
    proc = subprocess.run([sys.executable, "-c", BATCH], cwd=ROOT, env=cells.worker_env(),
                          capture_output=True, text=True, timeout=600)
    line = next((r for r in proc.stdout.splitlines() if r.startswith("BATCH")), None)
    assert line, proc.stderr[-2000:]
    return json.loads(line[5:])


@pytest.mark.xdist_group("batch_results")
def test_batched_checkpoint_matches_the_plain_path(batch_results):
    """The "checkpoint" variant (segments of round(sqrt(steps)) steps) on a batch: both pass the
    oracle check and agree to float64 rounding (the recomputed forward segments may round
    differently, so not bit for bit), with several times less temporary memory."""
    plain, ckpt = batch_results["default"], batch_results["checkpoint"]
    assert batch_results["segment"] == 13 and ckpt["remat"] == 13 and plain["remat"] == 0
    assert plain["ok"] and ckpt["ok"]
    assert ckpt["temp"] < plain["temp"] / 4
    for name, a in plain["out"].items():
        a, c = np.asarray(a), np.asarray(ckpt["out"][name])
        assert c.shape == a.shape
        # the history descends to ~1e-8 where the loss cancels: its scale is the starting loss
        scale = np.abs(plain["out"]["loss"]) if name == "loss_history" else np.abs(a)
        assert np.all(np.abs(c - a) <= 1e-12 * scale), (name, np.max(np.abs(c - a) / scale))


@pytest.mark.xdist_group("batch_results")
def test_batched_set_input_reuses_the_compiled_program(batch_results):
    assert batch_results["reused"]          # no recompilation: the same executable ran
    assert batch_results["moved"]           # the new v0 was used ...
    assert batch_results["same_as_fresh"]   # ... exactly as a kernel built with it would
    assert batch_results["shape_refused"]   # a different batch size would need a new program


@pytest.mark.xdist_group("batch_results")
def test_projectile_checkpoint_variant_is_offered(batch_results):
    """The variant exists for the projectile only, and a kernel refuses variants it lacks."""
    import backends
    assert batch_results["variant_refused"]
    be = backends.get("jax")
    assert be.variants_for("projectile") == ("default", "graph", "checkpoint")
    assert be.variants_for("saxpy") == ("default", "graph")


def test_graph_variant_is_xla_command_buffers_on_cuda_only():
    """The graph variant sets XLA's command-buffer flags for its worker, is a skip with the
    reason on a CPU, and refuses to run when the environment's own XLA_FLAGS overrode them."""
    import os
    import backends
    from backends.jax import GRAPH_FLAGS
    from compare.running import cells
    be = backends.get("jax")
    assert "WHILE" in GRAPH_FLAGS and "--xla_gpu_graph_min_graph_size=1" in GRAPH_FLAGS
    assert be.variant_environment("graph") == {"XLA_FLAGS": GRAPH_FLAGS}
    assert be.variant_environment("default") == {}
    assert "CUDA only" in be.variant_unavailable("graph", "cpu")
    assert be.variant_unavailable("graph", "cuda") is None and be.variant_unavailable("default", "cpu") is None
    if "XLA_FLAGS" not in os.environ:
        assert cells.worker_env("jax", "graph")["XLA_FLAGS"] == GRAPH_FLAGS
        assert "XLA_FLAGS" not in cells.worker_env("jax", "default")
    saved = os.environ.pop("XLA_FLAGS", None)
    try:
        with pytest.raises(RuntimeError, match="graph variant needs XLA_FLAGS"):
            be.setup("cuda", "float32", "graph")
    finally:
        if saved is not None:
            os.environ["XLA_FLAGS"] = saved


def test_checkpoint_variant_through_the_worker():
    record, outputs = _run("projectile", "float32", {"contact": "soft", "batch": 37},
                           variant="checkpoint")
    assert record["info"]["remat_segment"] == 13
    assert record["error"]["vs_oracle"] <= record["error"]["tolerance"]
    assert outputs["loss_history"].shape == (21, 37) and outputs["grad"].dtype == np.float32


# soft contact's programs: the long tier; the fast tier keeps hard contact's, where checkpointing
# keeps less too
@pytest.mark.parametrize("contact", ["hard", pytest.param("soft", marks=pytest.mark.slow)])
def test_the_design_bytes_are_the_compiled_programs_plan_and_the_checkpoint_keeps_less(contact):
    """info()["design_bytes"] (the gradients page's prediction) is XLA's plan of the compiled program:
    the donated outputs alias the inputs, and the reverse pass keeps what the transposed step needs
    (hard contact: about one predicate byte per step and trajectory, far below a tape of four
    state values); checkpointing keeps less; nothing before the program is compiled."""
    import scenarios
    from backends.jax.projectile import Kernel
    sc = scenarios.get("projectile")
    got = {}
    p = sc.params({"batch": 4096, "iters": 3, "steps": 180, "contact": contact})
    for v in ("default", "checkpoint"):
        k = Kernel(p, sc.inputs(p, "float32"), "cpu", "float32", v)
        assert k.info()["design_bytes"] == {}
        k.run()
        got[v] = k.info()["design_bytes"]
    col = 4096 * 4
    for d in got.values():
        assert set(d) == {"inputs", "outputs", "xla_temporaries"} and 9 * col <= d["outputs"] < 9 * col + 256
    if contact == "hard":
        assert 180 * 4096 <= got["default"]["xla_temporaries"] < 180 * 4 * col / 4     # >= a byte a step
        assert got["checkpoint"]["xla_temporaries"] < got["default"]["xla_temporaries"]
    else:
        assert got["checkpoint"]["xla_temporaries"] < got["default"]["xla_temporaries"] / 2
