"""compare/sweep/points/particles.py: the particles' dt and n sweeps and their error against a
converged float64 rollout (fast tier). Named test_points_particles: pytest collects test files by
basename, and other packages have a particles module too."""
from __future__ import annotations

import numpy as np

import scenarios
from compare.results.record import Record
from compare.sweep.converged import Reference
from compare.sweep.points.particles import PARTICLES_DT, PARTICLES_N, PARTICLES_T, SCALING_CHECKED, SWEEPS
from scenarios.base import Precision


def test_scaling_points_grow_in_n_and_check_a_sample():
    for (device, quick), ns in PARTICLES_N.items():
        pts = SWEEPS.points("scaling", device, quick)
        assert [pt.params["n"] for pt in pts] == list(ns) == sorted(ns)
        assert all(pt.params["record_every"] == 0 and pt.check_sample == SCALING_CHECKED and not pt.save_outputs
                   for pt in pts)
    assert SWEEPS.points("horizon", "cpu", False) == [] and SWEEPS.points("bandwidth", "cpu", False) == []


def test_a_smaller_dt_is_closer_to_the_converged_reference():
    sc = scenarios.get("particles")
    rec = Record(scenario="particles", backend="numpy", device="cpu", precision="float64", status="ok")
    cache: dict = {}
    errors = []
    for dt in (0.04, 0.01):
        params = {"n": 8, "dt": dt, "steps": round(PARTICLES_T / dt)}
        p = sc.params(params)
        out = sc.oracle(p, sc.inputs(p, "float64"), Precision.FLOAT64)
        got = SWEEPS.converged_error(params, {k: np.asarray(out[k]) for k in ("x", "y")}, rec, cache,
                                     Reference(dt=0.0025))
        assert got.metric == SWEEPS.error_metric
        errors.append(got.error)
    assert 0 < errors[1] < errors[0]
    assert SWEEPS.converged_error({"n": 8}, None, rec, cache) is None
