"""The oracles themselves: closed forms, adjoints against finite differences, error bounds."""
from __future__ import annotations

import numpy as np
import pytest

import scenarios
from scenarios import projectile as pj
from scenarios import projectile_adjoint as adj

pytestmark = pytest.mark.cli


def _consts(precision="float64", **over):
    sc = scenarios.get("projectile")
    p = sc.params(over)
    return p, {k: float(v) for k, v in sc.inputs(p, precision).items() if k in pj.CONSTANTS}


def _loss(c, contact, steps, v):
    (x, y, _, _), _ = adj.rollout(c, contact, steps, v[0], v[1])
    return (x - c["target_x"]) ** 2 + (y - c["target_y"]) ** 2


@pytest.mark.parametrize("contact", ["none", "hard", "soft"])
def test_adjoint_matches_central_differences(contact):
    p, c = _consts(contact=contact)
    v = np.array([p.vx0, p.vy0])
    loss, grad, _, _ = adj.evaluate(c, contact, p.steps, v, 2.0**-53)
    assert loss == pytest.approx(_loss(c, contact, p.steps, v), rel=1e-15)
    for h in (1e-6, 3e-7):   # central differences: truncation O(h^2), rounding O(eps/h)
        fd = np.array([(_loss(c, contact, p.steps, v + h * e) - _loss(c, contact, p.steps, v - h * e)) / (2 * h)
                       for e in np.eye(2)])
        assert np.allclose(grad, fd, rtol=1e-6, atol=1e-6 * np.abs(grad).max()), (h, grad, fd)


def test_closed_form_equals_rollout_without_contact():
    p, c = _consts()
    for v in ([2.0, 6.5], [-1.0, 30.0], [0.0, 0.0]):
        loss, grad = adj.closed_form(c, p.steps, v)
        l2, g2, _, _ = adj.evaluate(c, "none", p.steps, v, 2.0**-53)
        assert loss == pytest.approx(l2, rel=1e-12)
        assert np.allclose(grad, g2, rtol=1e-12)


def test_seed_learning_rate_diverges_and_default_converges():
    """lr*lambda_max = 2 (N dt)^2 lr: the seed's 0.08 is past the stability limit 2/40.5."""
    sc = scenarios.get("projectile")
    for lr, converges in ((0.01, True), (0.08, False)):
        p = sc.params({"lr": lr, "iters": 30})
        h = sc.oracle(p, sc.inputs(p, "float64"), "float64")["loss_history"]
        assert (h[-1] < 1e-6 * h[0]) == converges


def test_error_bounds_scale_with_unit_roundoff():
    sc = scenarios.get("projectile")
    for contact in ("none", "hard", "soft"):
        p = sc.params({"contact": contact, "iters": 0})
        b32 = sc.oracle(p, sc.inputs(p, "float32"), "float32")["tol_loss"][0]
        b64 = sc.oracle(p, sc.inputs(p, "float64"), "float64")["tol_loss"][0]
        # bounds are linear in the unit roundoff: (u32 + u64) vs (u64 + u64)
        assert 0 < b64 < b32 and b32 / b64 == pytest.approx((2.0**-24 + 2.0**-53) / 2.0**-52, rel=0.05)


def test_particles_oracle_stays_in_the_box_and_flags_ill_conditioned():
    sc = scenarios.get("particles")
    p = sc.params()
    inputs = sc.inputs(p, "float32")
    ref = sc.oracle(p, inputs, "float32")
    r = float(inputs["radius"])          # the radius the float32 problem uses
    assert np.all(np.abs(ref["x"]) <= 1 - r) and np.all(ref["y"] >= r)
    assert np.all(ref["error_bound"] > 0)
    assert ref["ill_conditioned"].dtype == bool
    # a particle that deviates by more than its bound is reported as a mismatch
    out = {k: ref[k].copy() for k in ("x", "y", "vx", "vy")}
    good = int(np.flatnonzero(~ref["ill_conditioned"])[0])
    out["x"][good] += 10 * ref["error_bound"][good]
    assert not sc.check(p, None, out, ref, "float32").ok


def test_saxpy_and_sdf_checks_fail_on_one_bad_value():
    for name, key in (("saxpy", "out"), ("sdf", "image")):
        sc = scenarios.get(name)
        p = sc.params(quick=True)
        inputs = sc.inputs(p, "float32")
        ref = sc.oracle(p, inputs, "float32")
        out = {key: ref[key].astype(np.float32)}
        assert sc.check(p, inputs, out, ref, "float32").ok
        out[key].flat[7] += 1e-3
        assert not sc.check(p, inputs, out, ref, "float32").ok


def test_particle_trajectory_values_are_checked():
    sc = scenarios.get("particles")
    p = sc.params({"n": 20, "steps": 30, "record_every": 5})
    inputs = sc.inputs(p, "float64")
    ref = sc.oracle(p, inputs, "float64")
    out = {k: ref[k].copy() for k in ("x", "y", "vx", "vy", "traj_x", "traj_y")}
    assert sc.check(p, inputs, out, ref, "float64").ok
    out["traj_y"][3, 4] += 1e-6
    assert not sc.check(p, inputs, out, ref, "float64").ok


def test_projectile_zero_bound_component_is_not_nan():
    """A final hard-contact clamp zeroes a gradient component and its bound: 0/0 counts as exact."""
    sc = scenarios.get("projectile")
    p = sc.params({"steps": 38, "dt": 4.5 / 38, "contact": "hard", "iters": 2})
    inputs = sc.inputs(p, "float64")
    ref = sc.oracle(p, inputs, "float64")
    assert ref["tol_grad"][0][1] == 0
    out = {k: np.copy(ref[k]) for k in sc.outputs}
    assert sc.check(p, inputs, out, ref, "float64").ok
    out["grad"][1] = 1e-300
    assert not sc.check(p, inputs, out, ref, "float64").ok
