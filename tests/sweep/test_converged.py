"""Converged references of the time-against-error sweep (compare/sweep/converged.py): they
converge, are memoised per sweep point, and the typed ``Converged`` is the stored block exactly."""
from __future__ import annotations

import dataclasses
import json
import types

import numpy as np
import pytest

import scenarios
from compare.results.record import Record
from compare.sweep import converged
from compare.sweep.converged import Converged, Reference, ReferenceInfo
from compare.sweep.points import sweeps
from conftest import ROOT

STORED = ["docs/results/cpu/sweep.json", "docs/results/h100/sweep.json", "tests/data/format1-sweep.json"]


def test_references_converge():
    sdf = scenarios.get("sdf")
    errs = [converged.reconstruction_error(sdf.oracle(sdf.params({"width": r, "height": r}), {}, "float64")["image"])["error"]
            for r in (32, 128, 512)]
    assert errs[0] > errs[1] > errs[2] > 0
    params = {"n": 16, "seed": 0}
    part = scenarios.get("particles")
    ref = converged.converged_positions(part, params, 0.001, 3000)
    e = [converged.position_error(*converged.converged_positions(part, params, dt, round(3.0 / dt)), *ref)["error"]
         for dt in (0.02, 0.004)]
    assert e[0] > e[1] > 0
    p = {"contact": "none", "iters": 0}
    proj = scenarios.get("projectile")
    exact = proj.params(p)       # continuous limit of the no-contact case
    T = 4.5
    x, y = exact.vx0 * T, exact.vy0 * T + 0.5 * exact.gravity * T * T
    dx, dy = x - exact.target_x, y - exact.target_y
    loss, grad = converged.converged_loss_grad(proj, p, 0.0005, 9000)
    assert abs(loss - (dx * dx + dy * dy)) / (dx * dx + dy * dy) < 1e-3
    assert np.allclose(grad, [2 * dx * T, 2 * dy * T], rtol=1e-3)


def test_dt_reference_is_memoised_per_point_and_measures_its_own_error():
    calls = []

    def solve(sc, base, dt, steps):
        calls.append((dict(base), dt, steps))
        return (dt * steps, dt)             # 'a reference' whose distance is its dt

    sc = types.SimpleNamespace(name="fake")
    cache: converged.Cache = {}
    args = (solve, lambda a, b: abs(a[1] - b[1]), 3.0)
    ref, info = converged.dt_reference(cache, sc, {"dt": 0.1, "steps": 30, "n": 4}, Reference(dt=0.01), 0.5, *args)
    assert ref == (3.0, 0.01)
    assert calls == [({"n": 4}, 0.01, 300), ({"n": 4}, 0.02, 150)]      # the reference, then at 2 dt
    assert (info.dt, info.steps, info.simulated_time_s) == (0.01, 300, 3.0)
    assert info.self_difference == pytest.approx(0.01) and info.eval_grid is None
    # another swept dt of the same point: the same reference, not solved again
    again = converged.dt_reference(cache, sc, {"dt": 0.05, "steps": 60, "n": 4}, Reference(dt=0.01), 0.5, *args)
    assert again == (ref, info) and len(calls) == 2
    # no reference: the scenario's default dt; other parameters: another reference
    assert converged.dt_reference(cache, sc, {"n": 4}, None, 0.5, *args)[1].dt == 0.5
    assert converged.dt_reference(cache, sc, {"n": 8}, Reference(dt=0.01), 0.5, *args)[0] == ref
    assert len(calls) == 6 and len(cache) == 3


def test_reference_info_keeps_the_stored_key_order():
    info = ReferenceInfo("a note", dt=0.01, steps=300, simulated_time_s=3.0, self_difference=1e-9)
    assert list(info.to_json()) == ["dt", "steps", "simulated_time_s", "self_difference", "note"]
    assert ReferenceInfo("field", eval_grid=2001).to_json() == {"eval_grid": 2001, "note": "field"}
    c = Converged.measured({"error": 0.5, "rms": 0.25}, "max |d|", ReferenceInfo("field", eval_grid=2001))
    assert json.dumps(c.to_json()) == json.dumps(
        {"error": 0.5, "rms": 0.25, "metric": "max |d|", "reference": {"eval_grid": 2001, "note": "field"}})
    assert Converged.from_json(json.loads(json.dumps(c.to_json()))) == c


@pytest.mark.parametrize("path", STORED)
def test_every_stored_block_round_trips_through_the_type(path):
    """A block written today has the shape of every block stored so far, byte for byte."""
    blocks = [r["converged"] for r in json.loads((ROOT / path).read_text())["records"] if r.get("converged")]
    assert len(blocks) > 50
    for b in blocks:
        c = Converged.from_json(b)
        assert isinstance(c.reference, ReferenceInfo) and c.metric
        assert json.dumps(c.to_json()) == json.dumps(b)


def test_scenarios_measure_their_converged_error():
    sat = Record(scenario="saxpy", backend="numpy", device="cpu", precision="float32", status="ok",
                 error={"vs_oracle": 3e-8, "tolerance": 1e-6})
    c = sweeps("saxpy").converged_error({"n": 4}, None, sat, {})
    assert c is not None and c.error == 3e-8 and c.reference.note.startswith("float64 oracle")
    assert sweeps("saxpy").converged_error({"n": 4}, None, dataclasses.replace(sat, error=None), {}) is None
    for name in ("sdf", "particles", "projectile"):          # the outputs were not kept: no error
        assert sweeps(name).converged_error({}, None, sat, {}) is None
    sdf = scenarios.get("sdf")
    image = sdf.oracle(sdf.params({"width": 64, "height": 64}), {}, "float64")["image"]
    c = sweeps("sdf").converged_error({"width": 64, "height": 64}, {"image": image}, sat, {})
    assert c is not None and 0 < c.figures["rms"] <= float(c.error) and c.reference.eval_grid == converged.SDF_EVAL


def test_particles_error_against_a_finer_rollout():
    part = scenarios.get("particles")
    params = dataclasses.asdict(part.params({"n": 16, "dt": 0.01, "steps": 300}))    # as a record holds them
    x, y = converged.converged_positions(part, params, 0.01, 300)
    cache: converged.Cache = {}
    c = sweeps("particles").converged_error(params, {"x": x, "y": y}, Record(
        scenario="particles", backend="numpy", device="cpu", precision="float64", status="ok"),
        cache, reference=Reference(dt=0.0025))
    assert c is not None and set(c.figures) == {"max"} and c.figures["max"] >= float(c.error) > 0
    assert (c.reference.dt, c.reference.steps) == (0.0025, 1200) and len(cache) == 1
    assert c.reference.self_difference is not None and c.reference.self_difference < float(c.error)
