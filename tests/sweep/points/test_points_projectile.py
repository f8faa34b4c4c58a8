"""compare/sweep/points/projectile.py: the projectile's batch, horizon and dt sweeps (fast tier;
the batch and horizon test moved here from tests/sweep/test_points.py). Named
test_points_projectile: pytest collects test files by basename, and other packages have a
projectile module too."""
from __future__ import annotations

from compare.sweep.points import SWEEPS
from compare.sweep.points import projectile


def test_projectile_sweeps_batch_and_horizon_per_contact():
    for (device, quick), batches in projectile.BATCH_SWEEP.items():
        pts = SWEEPS["projectile"].points("scaling", device, quick)
        assert [pt.params["batch"] for pt in pts] == list(batches)
        assert all(pt.params["contact"] == "hard" and pt.params["iters"] == 20 for pt in pts)
    hz = SWEEPS["projectile"].points("horizon", "cpu", False)
    for contact, steps in projectile.HORIZON_STEPS[False].items():
        assert [pt.params["steps"] for pt in hz if pt.params["contact"] == contact] == list(steps)
    assert {pt.params["batch"] for pt in hz} == {projectile.HORIZON_BATCH["cpu", False]}
    assert {pt.params["contact"] for pt in SWEEPS["projectile"].points("error", "cpu", False)} == {"soft"}
