"""Checks of a cell's outputs against the float64 oracle that several backends' tests share
(tests/backends/test_taichi.py, tests/backends/test_jax.py, tests/backends/test_mlx.py): the projectile's gradient against
finite differences of the oracle's loss, and the particles' trajectory frames."""
from __future__ import annotations

import numpy as np
import pytest

import scenarios
from scenarios.projectile import CONSTANTS
from scenarios.projectile_adjoint import finite_difference_gradient, loss_of, rollout

FD = [{"contact": c, "iters": 0} for c in ("hard", "soft")]      # the gradient cells' parameters
FRAMES = {"n": 33, "steps": 57, "record_every": 7}                 # the trajectory cell's


def assert_gradient_matches_finite_differences(outputs: dict, params: dict) -> None:
    """A single trajectory's float64 gradient and loss against central differences of the oracle."""
    contact = params["contact"]
    sc = scenarios.get("projectile")
    p = sc.params(params, quick=True)
    inputs = sc.inputs(p, "float64")
    c = {k: float(inputs[k]) for k in CONSTANTS}
    _, tape = rollout(c, contact, p.steps, *map(float, inputs["v0"]))
    if contact == "hard":
        assert any(t[-1] for t in tape), "the contact must fire for the test to mean anything"
    else:
        assert any(t[1][1] < 0 for t in tape), "the projectile must penetrate the soft ground"

    v0 = inputs["v0"].astype(np.float64)
    fd = finite_difference_gradient(c, contact, p.steps, v0)
    grad = outputs["grad"]
    assert np.all(np.abs(grad - fd) <= 1e-6 * np.abs(fd) + 1e-9 * np.max(np.abs(fd))), (grad, fd)
    assert float(outputs["loss"]) == pytest.approx(loss_of(c, contact, p.steps, v0), rel=1e-13)


def assert_frames_match_the_oracle(outputs: dict) -> None:
    """The FRAMES cell's trajectory frames: the scenario's check only verifies their shape."""
    sc = scenarios.get("particles")
    p = sc.params(FRAMES, quick=True)
    ref = sc.oracle(p, sc.inputs(p, "float64"), "float64")
    for k in ("traj_x", "traj_y"):
        assert outputs[k].shape == ref[k].shape == (57 // 7 + 1, 33)
        np.testing.assert_allclose(outputs[k], ref[k], rtol=0, atol=1e-13)
