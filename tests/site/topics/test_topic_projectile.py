"""compare/site/topics/projectile.py: the gradient rows (AD ranked, hand adjoints beside it) and their page, built from the site's test
store (fast tier). Named test_topic_projectile (not test_projectile): pytest collects test files by their
basename, and compare/sweep/points/ and compare/render/figures/ have a projectile module too."""
from __future__ import annotations

from pathlib import Path

import pytest

from compare.results.record import Record
from compare.site.render import Figure, H
from compare.site.topics import projectile
from site_topics import ctx, unrendered  # noqa: F401  (the shared fixtures)


@pytest.fixture(autouse=True)
def unrendered_horizon(monkeypatch):
    """The horizon plot is not drawn either (tests/sweep/test_sweep_plots.py checks it)."""
    from compare.sweep import plots as sweep_plots

    def horizon(records, device, path, scenario):
        Path(path).write_bytes(b"png")
        return True
    monkeypatch.setattr(sweep_plots, "plot_horizon", horizon)


def test_its_rows_are_the_gradients_rate_and_memory():
    assert [r.key for r in projectile.RULES] == ["gradients", "gradients-memory"]
    assert all(r.reference is projectile.HAND_ADJOINTS for r in projectile.RULES)
    assert projectile.RULES[1].exact and set(projectile.PAGES) == {"gradients"}


def rec(backend: str, method=None) -> Record:
    return Record(scenario="projectile", backend=backend, device="cuda", precision="float32", status="ok",
                  gradient={"method": method} if method else None)


def test_the_gradient_method_is_the_records_else_the_backends():
    import backends
    assert projectile.gradient_method(rec("warp", "adjoint")) == projectile.ADJOINT
    assert projectile.hand_adjoint(rec("jax", "adjoint")) and not projectile.hand_adjoint(rec("jax", "ad"))
    assert projectile.gradient_method(rec("jax")) == backends.BACKENDS["jax"].gradient_method
    assert projectile.gradient_method(rec("no-such-framework")) == "-"


def test_hand_adjoints_are_never_the_best(ctx):
    for row in ctx.rows:
        if row.rule.key.startswith("gradients"):
            assert row.top is None or not projectile.hand_adjoint(
                next(r for r in ctx.m.records if r.backend == row.top and r.scenario == "projectile"))
            for c in row.cells.values():
                assert not (c.reference and c.tied)


def test_its_page_answers_both_rows(ctx):
    blocks = projectile.PAGES["gradients"][1](ctx)
    heads = [b.text for b in blocks if isinstance(b, H)]
    assert all(r.rule.question in heads for r in ctx.rows_of("gradients"))
    figs = [b for b in blocks if isinstance(b, Figure)]
    assert "figures/gradients-horizon.png" in {f.png for f in figs}
    for f in figs:
        assert (ctx.into / f.png).is_file() and (ctx.into / f.csv).is_file()
