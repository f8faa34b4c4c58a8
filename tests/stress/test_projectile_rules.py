"""compare/stress/projectile_rules.py: the projectile experiments' verdict rules on synthetic
histories and losses (moved here from tests/suites/test_stress.py)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from compare.stress import projectile_rules


@pytest.mark.parametrize("history,expected", [
    ([100.0 * 0.5 ** k for k in range(40)], "converged"),         # 1e-12 of the start
    ([100.0, 50.0, 40.0, 35.0], "stalled"),                        # better, not 1e-6 of the start
    ([100.0] * 10, "stalled"),                                     # no progress, no growth
    ([100.0, 100.05], "stalled"),                                  # within 0.1 %: rounding, not growth
    ([100.0, 200.0, 400.0], "diverged"),                           # grew
    ([100.0, 1e3, 1e6, math.inf], "diverged"),                     # overflowed
    ([100.0, 1.0, math.nan, 0.0], "diverged"),                     # NaN anywhere
    ([100.0, 1e8, 1e-5], "converged"),                             # a spike does not matter at the end
    ([], "diverged"),
])
def test_classify(history, expected):
    assert projectile_rules.classify(history) == expected


def test_classify_gradient_descent_on_a_quadratic_matches_the_stability_bound():
    """GD on L = lam/2 v^2 contracts by |1 - lr lam| per step: stable iff lr < 2/lam."""
    lam = 40.5
    def hist(lr):
        v = 1.0
        out = []
        for _ in range(61):
            out.append(0.5 * lam * v * v)
            v -= lr * lam * v
        return out
    assert projectile_rules.classify(hist(0.01)) == "converged"
    assert projectile_rules.classify(hist(0.049)) == "stalled"          # |1 - lr lam| = 0.98: slow
    assert projectile_rules.classify(hist(0.08)) == "diverged"
    lrs = [0.01, 0.045, 0.055, 0.08]
    below, first = projectile_rules.observed_boundary(lrs, [projectile_rules.classify(hist(lr)) for lr in lrs])
    assert below == 0.045 and first == 0.055 and below < 2 / lam <= first


def test_observed_boundary_without_divergence():
    assert projectile_rules.observed_boundary([0.1, 0.2], ["stalled", "converged"]) == (0.2, None)


def test_loss_mispredictions_separates_jumps_from_curvature_and_rounding():
    vy = np.linspace(0.0, 1.0, 11)
    smooth = [[0.0, 2 * v] for v in vy]                      # L = v^2, exact gradient
    assert projectile_rules.loss_mispredictions(vy, vy ** 2, smooth) == (0, 0)
    jump = vy ** 2 + (vy > 0.55)                             # a step the gradient cannot see
    assert projectile_rules.loss_mispredictions(vy, jump, smooth) == (1, 0)
    flat = np.full(11, 25.0) + 1e-7 * (-1.0) ** np.arange(11)  # rounding noise on a flat loss
    assert projectile_rules.loss_mispredictions(vy, flat, [[0.0, 0.0]] * 11, noise_rel=2 ** -23) == (0, 10)
