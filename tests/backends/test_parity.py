"""One parity suite run against every backend (array-api-tests style).

Each case runs the real worker path (one process per cell). A port passes when it agrees with the
float64 oracle within the scenario's derived tolerance: in float64 that tolerance is ~1e-14..1e-12
(exactness: the port is the same algorithm); in float32 it is the derived rounding bound. Float64
ports must also agree with Warp's float64 output to the same tight level.
Select one backend with ``pytest -m <backend>``.
"""
from __future__ import annotations

import math

import pytest

import backends
from conftest import ran, require_device, run_cases

CASES = [
    ("saxpy", {}),                                       # quick: n = 100_003
    ("saxpy", {"n": 1}),
    ("saxpy", {"n": 257, "inputs": "random", "seed": 3}),
    ("sdf", {}),                                         # quick: 203 x 97, non-square
    ("sdf", {"width": 2, "height": 3}),
    ("particles", {}),                                   # quick: n = 1000
    ("particles", {"n": 33, "steps": 57, "record_every": 7}),
    ("projectile", {"contact": "none"}),
    ("projectile", {"contact": "hard"}),
    ("projectile", {"contact": "soft"}),
    ("projectile", {"steps": 7, "iters": 0}),
    # batched: B trajectories, each descending on its own loss; an awkward B, all three contacts
    ("projectile", {"contact": "none", "batch": 37}),
    ("projectile", {"contact": "hard", "batch": 37}),
    ("projectile", {"contact": "soft", "batch": 37}),
]
# (batched case, single case): row 0 of a batch is the seed case, computed by the same arithmetic
BATCH_ROW0 = {c: (("projectile", {"contact": c, "batch": 37}), ("projectile", {"contact": c}))
              for c in ("none", "hard", "soft")}
# float64 agreement with Warp (relative to each scenario's metric): both ports are the same
# algorithm, so they may differ only by float64 rounding, e.g. FMA contraction.
TIGHT_VS_WARP = {"saxpy": 1e-15, "sdf": 1e-13, "particles": 1e-12, "projectile": 1e-12}


def _params(case):
    # one xdist group per backend, its own tests' shared cells' (conftest.run_cases): the cells
    # they have in common run once
    return [pytest.param(b, d, p, s, o, marks=[getattr(pytest.mark, b), pytest.mark.xdist_group(f"{b}-cells")],
                         id=f"{b}-{d}-{p}-{s}-" + ",".join(f"{k}={v}" for k, v in o.items()))
            for b in backends.BACKENDS for d in backends.DEVICES for p in ("float64", "float32")
            for s, o in case]


def run_case(backend, device, precision, scenario, overrides):
    """Every case of one backend, device and precision runs in one worker process (the first
    test of the group runs them all): the framework starts once, not once per case. Correctness
    only: warm kernel caches, no throughput regime (conftest.CORRECTNESS; timing runs start cold)."""
    run_cases([(backend, s, precision, o, device, "default") for s, o in CASES])
    return ran((backend, scenario, precision, overrides, device, "default"))


@pytest.mark.parametrize("backend,device,precision,scenario,overrides", _params(CASES))
def test_parity(backend, device, precision, scenario, overrides):
    require_device(backend, device, precision)
    record, outputs = run_case(backend, device, precision, scenario, overrides)
    assert record.status == "ok", f"{record.status}: {record.reason}\n{record.traceback or ''}"
    err = record.error
    assert math.isfinite(err["vs_oracle"]) and err["vs_oracle"] <= err["tolerance"]
    assert record.time["first_call_s"] > 0 and record.time["median_s"] > 0
    if precision == "float64" and backend != backends.reference():
        require_device(backends.reference(), device)
        ref_rec, ref_out = run_case(backends.reference(), device, "float64", scenario, overrides)
        assert ref_rec.status == "ok", ref_rec.reason
        import scenarios
        sc = scenarios.get(scenario)
        p = sc.params(overrides, quick=True)
        d = sc.distance(p, sc.inputs(p, "float64"), outputs, ref_out)
        assert d <= TIGHT_VS_WARP[scenario], f"float64 {backend} vs {backends.reference()} differ by {d:.3g}"


@pytest.mark.parametrize("backend,device,precision,scenario,overrides",
                         [p for p in _params([b for b, _ in BATCH_ROW0.values()]) if p.values[1] == "cpu"])
def test_batch_row0_is_the_single_trajectory(backend, device, precision, scenario, overrides):
    """On the CPU, row 0 of a batched run equals the unbatched run bit for bit: the batch only
    adds trajectories, it does not change any trajectory's arithmetic."""
    require_device(backend, device)
    single = BATCH_ROW0[overrides["contact"]][1]
    (rec_b, out_b), (rec_1, out_1) = (run_case(backend, device, precision, s, o)
                                      for s, o in ((scenario, overrides), single))
    assert rec_b.status == "ok" and rec_1.status == "ok", (rec_b.reason, rec_1.reason)
    for name, a in out_1.items():
        row0 = out_b[name][:, 0] if name == "loss_history" else out_b[name][0]
        assert row0.tobytes() == a.tobytes(), f"{name}: batch row 0 {row0} != single {a}"
