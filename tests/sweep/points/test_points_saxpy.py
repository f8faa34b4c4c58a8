"""compare/sweep/points/saxpy.py: SAXPY's bandwidth sizes and its error point (fast tier; the
error-point test moved here from tests/sweep/test_points.py). Named test_points_saxpy: pytest
collects test files by basename, and other packages have a saxpy module too."""
from __future__ import annotations

import scenarios
from compare.results.record import Record
from compare.sweep.points import SWEEPS, Knob
from compare.sweep.points.saxpy import SAXPY_EXP
from compare.sweep.points.saxpy import SWEEPS as SAXPY


def test_bandwidth_sizes_grow_in_powers_of_two_to_about_a_gib_on_the_gpu():
    for (device, quick), exps in SAXPY_EXP.items():
        ns = [pt.params["n"] for pt in SAXPY.points("bandwidth", device, quick)]
        assert ns == [1 << e for e in exps] and ns == sorted(ns)
    assert max(SAXPY_EXP["cuda", False]) == 28 and max(SAXPY_EXP["cpu", False]) < 28


def test_its_converged_error_is_the_oracles_own():
    rec = Record(scenario="saxpy", backend="warp", device="cpu", precision="float32", status="ok",
                 error={"vs_oracle": 3e-8, "tolerance": 1e-6})
    got = SAXPY.converged_error({"n": 4}, None, rec, {})
    assert got.error == 3e-8 and got.metric == SAXPY.error_metric and "float64 oracle" in got.reference.note
    assert SAXPY.converged_error({"n": 4}, None, rec.replace(error=None), {}) is None


def test_saxpy_error_point_varies_precision_only():
    (pt,) = SWEEPS["saxpy"].points("error", "cpu", True)
    assert pt.knob == Knob("precision") and pt.reference is None
    assert pt.params == {"n": scenarios.get("saxpy").params(quick=True).n}
