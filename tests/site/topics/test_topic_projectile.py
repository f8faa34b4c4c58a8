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

    def horizon(records, device, path, scenario, part="all"):
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
    assert {"figures/gradients-horizon.png", "figures/gradients-horizon-time.png",
            "figures/gradients-horizon-quality.png"} <= {f.png for f in figs}
    assert all(f.caption and f.csv == f.png[:-4] + ".csv" for f in figs if "horizon" in f.png)
    for f in figs:
        assert (ctx.into / f.png).is_file() and (ctx.into / f.csv).is_file()


def test_its_scaling_table_is_the_published_size_with_every_size_in_a_csv(ctx):
    from compare.site.render import P, Table
    blocks = projectile.PAGES["gradients"][1](ctx)
    head = next(i for i, b in enumerate(blocks) if isinstance(b, H) and b.text == "Projectile: scaling")
    table = next(b for b in blocks[head:] if isinstance(b, Table))
    sizes = {row[2] for row in table.rows}
    assert len(sizes) == 1, sizes
    note = next(b for b in blocks[head:] if isinstance(b, P) and "every size" in b.text)
    assert "figures/projectile-scaling.csv" in note.text and f"({sizes.pop()})" in note.text
    assert (ctx.into / "figures" / "projectile-scaling.csv").is_file()


def horizon_rec(backend: str, status: str, ratio: float, variant: str = "default", steps: int = 600) -> Record:
    return Record(scenario="projectile", backend=backend, device="cpu", precision="float32", status=status,
                  variant=variant, params={"steps": steps, "contact": "soft", "batch": 256},
                  tags={"sweep": "horizon", "knob": {"name": "steps", "value": steps}},
                  error={"vs_oracle": ratio, "tolerance": 1.0, "worst_trajectory": 14},
                  gradient={"fd_agreement": 0.4})


def test_a_horizon_point_past_its_bound_is_said_with_who_and_whether_it_is_one_arithmetic():
    same = [horizon_rec("warp", "mismatch", 1.9259014), horizon_rec("torch", "mismatch", 1.9259021),
            horizon_rec("jax", "ok", 0.35), horizon_rec("jax", "ok", 0.33, "checkpoint"),
            horizon_rec("warp", "ok", 0.2, steps=180)]
    [text] = projectile.outside_bound(same)
    assert "soft contact, float32, 600 steps" in text and "2 frameworks (torch, warp)" in text
    assert "1.9259 in every one, the same to 5 digits (checked trajectory 14): not a port's defect" in text
    assert "Within it: jax (0.35), jax/checkpoint (0.33)." in text
    apart = [horizon_rec("warp", "mismatch", 1.9), horizon_rec("torch", "mismatch", 3.0)]
    [text] = projectile.outside_bound(apart)
    assert "1.9 to 3" in text and "not a port's defect" not in text
    assert projectile.outside_bound([horizon_rec("warp", "ok", 0.5)]) == []
