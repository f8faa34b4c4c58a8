"""The GPU checks the hand-adjoint backends share (tests/backends/test_cupy.py, tests/backends/test_triton.py):
every scenario's cell times with CUDA events, replays a CUDA graph and reports a device memory
peak; row 0 of a projectile batch equals the single trajectory bitwise for each contact, and a
captured run replayed after ``set_input`` gives what a fresh kernel gives."""
from __future__ import annotations

import numpy as np

from compare.running import cells
from compare.spec import Cell

GPU_CASES = [("saxpy", {}), ("sdf", {}), ("particles", {"record_every": 30}), ("launch", {}), ("copy", {}),
             ("projectile", {"contact": "hard"}), ("projectile", {"contact": "soft"}),
             ("projectile", {"contact": "soft", "batch": 37})]


def assert_gpu_cell_with_events_graph_and_memory(backend: str, scenario: str, overrides: dict,
                                                 precision: str) -> None:
    """One GPU cell through the worker path, with the throughput regime (its graph replay)."""
    spec = {"scenario": scenario, "backend": backend, "device": "cuda", "precision": precision,
            "params": overrides, "quick": True, "repeat": 3, "min_time": 0.0, "throughput": True}
    record, outputs = cells.run(Cell.from_dict(spec), timeout=600)
    assert record["status"] == "ok", f"{record['status']}: {record.get('reason')}\n{record.get('traceback', '')}"
    assert {k: v.dtype for k, v in outputs.items()} == {k: np.dtype(precision) for k in outputs}
    assert record["time"]["events"]["median_s"] > 0, record["time"].get("events_error")
    assert record["time"]["null"]["median_s"] > 0
    graph = record["time"].get("graph", {})
    assert "failed" not in graph and "unavailable" not in graph, graph
    assert record["memory"].get("device_peak_bytes", 0) > 0, record["memory"]

_BODY = """b = backends.get("__BACKEND__"); b.setup("cuda", "float32", "default"); b.ensure_context("cuda")
sc = scenarios.get("projectile")
def build(over, inputs=None):
    p = sc.params(over); i = sc.inputs(p, "float32") if inputs is None else inputs
    k = b.kernel("projectile")(p, i, "cuda", "float32", "default"); k.run(); b.synchronize("cuda", None)
    return p, i, k
res = {}
for c in ("none", "hard", "soft"):
    _, _, one = build({"contact": c}); _, _, many = build({"contact": c, "batch": __BATCH__})
    a, m = one.outputs(), many.outputs()
    res["row0-" + c] = all(np.array_equal(np.asarray(m[n])[:, 0] if n == "loss_history" else np.asarray(m[n])[0], a[n]) for n in a)
p, i, k = build({"contact": "hard", "batch": 8})
replay = b.capture("cuda", k.run)
new = {**i, "v0": i["v0"] * 1.1}
k.set_input("v0", new["v0"]); replay(); b.synchronize("cuda", None)
_, _, fresh = build({"contact": "hard", "batch": 8}, new)
res["set_input+graph"] = all(np.array_equal(k.outputs()[n], v) for n, v in fresh.outputs().items())
print("RESULT" + json.dumps(res))
"""


def row0_and_replay(backend: str, batch: int) -> str:
    """The check's script for ``backend`` (its body only: the caller's runner supplies the
    imports json, numpy as np, backends and scenarios); prints RESULT{name: bool}."""
    return _BODY.replace("__BACKEND__", backend).replace("__BATCH__", str(batch))
