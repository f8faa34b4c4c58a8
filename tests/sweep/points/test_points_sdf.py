"""compare/sweep/points/sdf.py: the resolution sweep and its error against the analytic field
(fast tier). Named test_points_sdf: pytest collects test files by basename, and other packages
have an sdf module too."""
from __future__ import annotations

import scenarios
from compare.results.record import Record
from compare.sweep.points import Knob
from compare.sweep.points.sdf import SDF_RES, SWEEPS
from scenarios.base import Precision


def test_error_points_are_square_resolutions_and_nothing_else():
    for (device, quick), res in SDF_RES.items():
        pts = SWEEPS.points("error", device, quick)
        assert [(pt.params, pt.knob) for pt in pts] == [({"width": r, "height": r}, Knob("resolution", r)) for r in res]
        assert SWEEPS.points("bandwidth", device, quick) == []


def test_a_finer_image_is_closer_to_the_analytic_field():
    sc = scenarios.get("sdf")
    rec = Record(scenario="sdf", backend="numpy", device="cpu", precision="float64", status="ok")
    cache: dict = {}
    errors = []
    for r in (16, 64):
        params = {"width": r, "height": r}
        image = sc.oracle(sc.params(params), {}, Precision.FLOAT64)["image"]
        got = SWEEPS.converged_error(params, {"image": image}, rec, cache)
        assert got.metric == SWEEPS.error_metric and got.reference.note == "analytic field, float64"
        errors.append(got.error)
    assert 0 < errors[1] < errors[0]
    assert SWEEPS.converged_error({"width": 8, "height": 8}, None, rec, cache) is None
