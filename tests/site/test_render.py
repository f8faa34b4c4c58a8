"""compare/site/render.py: a page's blocks in HTML and in Markdown (fast tier)."""
from __future__ import annotations

import pytest

from compare.site import render as R


def test_inline_markup_is_links_bold_and_code_and_the_rest_is_escaped():
    assert R.inline_html("a [b](c.html) **d** `e<f>` <g>") == \
        'a <a href="c.html">b</a> <strong>d</strong> <code>e&lt;f&gt;</code> &lt;g&gt;'


def test_markdown_links_between_pages_point_at_the_twins():
    assert R.md_links("see [x](matrix.html#row-1) and [y](https://e.org/a.html)") == \
        "see [x](matrix.md#row-1) and [y](https://e.org/a.html)"
    assert R.md_cell("a|b\nc") == "a\\|b c"


def test_tables_mark_numeric_cells_and_sort():
    t = R.Table(("name", "time"), (("warp", "1.5 ms"), ("x|y", "n/a")))
    html = R.block_html(t)
    assert html.startswith('<table class="sortable"><thead><tr><th>name</th><th>time</th></tr>')
    assert '<td class="num">1.5 ms</td>' in html and "<td>n/a</td>" in html
    assert R.block_md(t) == "| name | time |\n|---|---|\n| warp | 1.5 ms |\n| x\\|y | n/a |"
    assert "sortable" not in R.block_html(R.Table(("a",), (), sortable=False))


def test_every_block_in_both_formats():
    blocks = [R.H("Title", "t"), R.P("text"), R.Code("x < 1"), R.Items(("one", "[two](two.html)")),
              R.Figure("a.png", "cap", "compare run", "a.csv"), R.Raw("<b>raw</b>", "**raw**")]
    html = [R.block_html(b) for b in blocks]
    md = [R.block_md(b) for b in blocks]
    assert html[0] == '<h2 id="t">Title</h2>' and md[0] == "## Title"
    assert html[2] == "<pre><code>x &lt; 1</code></pre>" and md[2] == "```\nx < 1\n```"
    assert md[3] == "- one\n- [two](two.md)"
    assert '<img src="a.png" alt="cap">' in html[4] and '<a href="a.csv">data (CSV)</a>' in html[4]
    assert md[4] == "![cap](a.png)\n\n*cap* ([data](a.csv))\n\n```\ncompare run\n```"
    assert (html[5], md[5]) == ("<b>raw</b>", "**raw**")
    with pytest.raises(TypeError):
        R.block_html("not a block")
    with pytest.raises(TypeError):
        R.block_md(3)


def test_a_page_is_self_contained_and_its_twin_links_the_markdown():
    page = R.page_html("T<1>", [("Overview", "index.html")], [R.P("body")])
    assert page.startswith("<!DOCTYPE html>") and "<title>T&lt;1&gt;</title>" in page
    assert f"<style>{R.CSS}</style>" in page and "<script>" in page and "<p>body</p>" in page
    assert "http" not in page.replace("http-equiv", "")
    assert R.page_md("T", [("Overview", "index.html"), ("Rows", "rows.html")], [R.P("body")]) == \
        "# T\n\n[Overview](index.md) · [Rows](rows.md)\n\nbody\n"
