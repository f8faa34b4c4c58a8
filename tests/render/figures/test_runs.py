"""compare/render/figures/runs.py: which runs a scenario's picture draws, and their labels (fast tier)."""
from __future__ import annotations

from compare.render.figures.runs import pick_runs, run_label
from compare.results.record import Record


def rec(backend, device="cpu", precision="float32", variant="default") -> Record:
    return Record(scenario="saxpy", backend=backend, device=device, precision=precision, status="ok", variant=variant)


def test_run_label_names_a_variant_only_where_not_the_default():
    assert run_label(rec("warp")) == "warp/cpu/float32"
    assert run_label(rec("warp", "cuda", "float64", "tile")) == "warp/cuda/float64/tile"


def test_one_float32_default_run_per_backend_and_device():
    runs = [(rec("warp", variant="tile"), {}), (rec("warp"), {"a": 1}), (rec("warp"), {"a": 2}),
            (rec("warp", "cuda"), {}), (rec("jax", precision="float64"), {}), (rec("numpy"), {})]
    picked = pick_runs(runs, 10)
    assert [(r.backend, r.device) for r, _ in picked] == [("warp", "cpu"), ("warp", "cuda"), ("numpy", "cpu")]
    assert picked[0][1] == {"a": 1}                       # the first of a (backend, device)
    assert len(pick_runs(runs, 2)) == 2


def test_without_float32_defaults_the_first_runs():
    runs = [(rec("jax", precision="float64"), {}), (rec("warp", variant="tile"), {}), (rec("cupy", precision="float64"), {})]
    assert pick_runs(runs, 2) == runs[:2]
