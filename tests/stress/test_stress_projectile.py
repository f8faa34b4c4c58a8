"""compare/stress/projectile.py: the projectile stress experiments (learning rate, gradient
quality, horizon). Named test_stress_projectile: pytest collects test files by basename, and
other packages have a projectile module too. With no framework chosen an experiment still runs
its float64 oracle on the host: the slow tier checks that the oracle's gradient descent diverges
where the predicted 2/lambda_max says it should."""
from __future__ import annotations

import pytest

from compare.stress import projectile
from compare.stress.numerics import ORACLE
from compare.stress.projectile_rules import CONTACTS
from compare.suites import stress_context as context


def oracle_only() -> context.Ctx:
    return context.Ctx([], ["cpu"], True, 1, 1.0, {})


def test_the_lr_grid_brackets_the_predicted_boundary_and_holds_the_seeds():
    for quick in (True, False):
        grid = projectile.lr_grid(quick)
        assert list(grid) == sorted(grid) and set(projectile.SEED_LRS) <= set(grid)
        assert any(lr < 0.049 for lr in grid) and any(lr > 0.052 for lr in grid)    # lr* ~ 0.049-0.052
    assert len(projectile.lr_grid(True)) < len(projectile.lr_grid(False))


def test_its_experiments_and_their_page_hooks():
    e = projectile.EXPERIMENTS
    assert list(e) == ["projectile-lr", "projectile-gradient", "projectile-horizon"]
    assert e["projectile-lr"].extra_markdown is not None and e["projectile-lr"].table_rows is not None
    assert all(x.plot is not None for x in e.values())


def test_the_horizon_sweep_needs_a_framework():
    assert projectile.exp_projectile_horizon(oracle_only()) == ([], {})


@pytest.mark.slow
def test_the_oracles_descent_agrees_with_the_predicted_boundary():
    rows, series = projectile.exp_projectile_lr(oracle_only())
    predicted = [r for r in rows if r.backend == "physics"]
    assert [r.setting for r in predicted] == [f"contact={c}" for c in CONTACTS]
    gd = [r for r in rows if r.backend == ORACLE and r.figure.startswith("observed boundary") and r.setting.startswith("gd")]
    assert gd and all(r.verdict.startswith("agrees with predicted lr*") for r in gd), [r.verdict for r in gd]
    assert series["lrs"] == list(projectile.lr_grid(True))
    assert {k.split("/")[-1] for k in series["histories"]} == {f"{lr:g}" for lr in projectile.SEED_LRS}


@pytest.mark.slow
def test_the_gradient_experiment_scans_the_oracle():
    rows, series = projectile.exp_projectile_gradient(oracle_only())
    assert rows and {"h", "lines", "scans"} <= set(series)
