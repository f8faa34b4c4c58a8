"""compare/site/topics/particles.py: the particle loop's matrix rows and its page, built from the site's test
store (fast tier). Named test_topic_particles (not test_particles): pytest collects test files by their
basename, and compare/sweep/points/ and compare/render/figures/ have a particles module too."""
from __future__ import annotations

from compare.site.render import Figure, H
from compare.site.topics import particles
from site_topics import ctx, unrendered  # noqa: F401  (the shared fixtures)


def test_its_rows_are_the_small_and_large_particle_loops():
    assert particles.SCENARIO == "particles" and particles.SMALL
    assert [r.key for r in particles.RULES] == ["particles-small", "particles-large"]
    assert [(r.unit, r.better) for r in particles.RULES] == [("s", "lower"), ("1/s", "higher")]
    assert set(particles.PAGES) == {"particles"}


def test_the_large_row_ranks_a_rate_higher_first(ctx):
    row = next(r for r in ctx.rows if r.rule.key == "particles-large")
    ranked = [c for c in row.cells.values() if c.ratio is not None and not c.reference]
    assert ranked and row.cells[row.top].value == max(c.value for c in ranked)


def test_its_page_has_both_verdicts_and_both_figures(ctx):
    blocks = particles.PAGES["particles"][1](ctx)
    heads = [b.text for b in blocks if isinstance(b, H)]
    assert {"Particle loop, small n", "Particle loop, large n"} <= set(heads)
    figs = {b.png for b in blocks if isinstance(b, Figure)}
    assert {"figures/particles-small.png", "figures/particles-large.png"} <= figs
    for f in figs:
        assert (ctx.into / f).is_file()
    large = next(b for b in blocks if isinstance(b, Figure) and b.png == "figures/particles-large.png")
    assert "--set n=" in large.command and "--check-sample 4096" in large.command
