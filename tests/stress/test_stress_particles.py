"""compare/stress/particles.py: contacts, first flips and the NumPy emulation of an overflow
(moved here from tests/suites/test_stress.py). Named test_stress_particles: pytest collects test
files by basename, and other packages have a particles module too."""
from __future__ import annotations

import numpy as np

from compare.stress import particles as particles_stress


def test_contacts_and_first_flips():
    radius = 0.03
    lo = float(np.float32(-1) + np.float32(radius))
    ty = np.array([[0.5, radius], [radius, 0.4], [0.2, 0.1]])
    tx = np.array([[0.0, 0.0], [0.0, 0.0], [lo, 0.0]])
    c = particles_stress.contacts(tx, ty, radius, np.float32)
    assert c.tolist() == [[False, True], [True, False], [True, False]]
    other = c.copy(); other[1, 0] = False
    assert particles_stress.first_flips(c, other).tolist() == [1, -1]


def test_emulation_finds_the_overflow_step():
    """bounce > 1 at the walls: the horizontal speed overflows sooner in float32 than in float64."""
    s32 = particles_stress.first_nonfinite_step({"n": 16, "bounce": 3.0}, "float32", 5000)
    s64 = particles_stress.first_nonfinite_step({"n": 16, "bounce": 3.0}, "float64", 5000)
    assert s32 is not None and s64 is not None and s32 < s64
    assert particles_stress.first_nonfinite_step({"n": 16, "bounce": 0.5}, "float32", 500) is None


def test_state_error_is_the_largest_per_particle_difference_and_finite_state_checks_all_four():
    ref = {k: np.zeros(3) for k in particles_stress.STATE}
    out = {k: np.zeros(3, np.float32) for k in particles_stress.STATE}
    out["vx"][1], out["y"][2] = 0.5, -2.0
    assert particles_stress.state_error(out, ref).tolist() == [0.0, 0.5, 2.0]
    assert particles_stress.finite_state(out)
    out["vy"][0] = np.inf
    assert not particles_stress.finite_state(out) and particles_stress.state_error(out, ref)[0] == np.inf


def test_particle_inputs_resolve_the_overrides():
    p, inp = particles_stress.particle_inputs({"n": 8, "steps": 3}, "float32")
    assert (p.n, p.steps) == (8, 3) and inp["x0"].dtype == np.float32 and inp["x0"].shape == (8,)


def test_particle_experiments_are_registered():
    assert {"particles-dt", "particles-long", "particles-inf"} <= set(particles_stress.EXPERIMENTS)
