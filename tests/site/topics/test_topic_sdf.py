"""compare/site/topics/sdf.py: SDF has no rows of its own; its default cells are small kernels, built from the site's test
store (fast tier). Named test_topic_sdf (not test_sdf): pytest collects test files by their
basename, and compare/sweep/points/ and compare/render/figures/ have a sdf module too."""
from __future__ import annotations

from compare.site.render import Figure, H
from compare.site.topics import sdf
from site_topics import ctx, unrendered  # noqa: F401  (the shared fixtures)


def test_sdf_is_a_small_kernel_without_rows_or_pages():
    from compare.site import topics
    assert sdf.SMALL and not hasattr(sdf, "RULES") and not hasattr(sdf, "PAGES")
    assert "sdf" in topics.SMALL and topics.TOPICS["sdf"] is sdf


def test_the_per_call_page_shows_sdfs_default_cells(ctx):
    from compare.site.topics import saxpy
    blocks = saxpy.PAGES["per-call"][1](ctx)
    assert any("sdf" in str(getattr(b, "caption", "")) + str(getattr(b, "command", "")) + str(getattr(b, "rows", ""))
               for b in blocks)
