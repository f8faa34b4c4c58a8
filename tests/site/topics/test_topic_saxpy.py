"""compare/site/topics/saxpy.py: SAXPY's matrix rows and its two pages, built from the site's test
store (fast tier). Named test_topic_saxpy (not test_saxpy): pytest collects test files by their
basename, and compare/sweep/points/ and compare/render/figures/ have a saxpy module too."""
from __future__ import annotations

import pytest

from compare.site.render import Figure, H
from compare.site.topics import saxpy
from site_topics import ctx, unrendered  # noqa: F401  (the shared fixtures)


def test_its_rows_read_saxpy_and_are_the_bandwidth_and_per_call_questions():
    assert saxpy.SCENARIO == "saxpy" and saxpy.SMALL
    assert [r.key for r in saxpy.RULES] == ["bandwidth", "latency", "pipelined", "graph"]
    assert {r.page for r in saxpy.RULES} == set(saxpy.PAGES) == {"bandwidth", "per-call"}


def test_the_rows_rank_the_stores_saxpy_cells(ctx):
    rows = {r.rule.key: r for r in ctx.rows}
    for key in ("bandwidth", "latency", "pipelined"):
        assert rows[key].top in ctx.m.frameworks and rows[key].cells[rows[key].top].ratio == 1.0
    # the largest n a framework ran: the bandwidth row reads no default-size cell
    assert rows["bandwidth"].scope != rows["latency"].scope


@pytest.mark.parametrize("page", ["bandwidth", "per-call"])
def test_each_page_has_its_verdicts_and_figures_that_exist(ctx, page):
    label, build = saxpy.PAGES[page]
    blocks = build(ctx)
    heads = [b.text for b in blocks if isinstance(b, H)]
    assert all(r.rule.question in heads for r in ctx.rows_of(page))
    figs = [b for b in blocks if isinstance(b, Figure)]
    assert figs, label
    for f in figs:
        assert (ctx.into / f.png).is_file() and (ctx.into / f.csv).is_file(), f.png
        assert "python -m compare" in f.command


def test_the_per_call_table_gives_each_figure_in_its_runs_launch_floors(ctx):
    """Latency and pipelined cells read '<time> = <n> floors' where the record keeps its run's
    yardstick, the unit is defined once on the page; graph replay and the bandwidth page's table
    stay in seconds."""
    from compare.site import data, fmt
    from compare.site.render import P, Table
    blocks = saxpy.PAGES["per-call"][1](ctx)
    assert sum(isinstance(b, P) and b.text == saxpy.FLOORS for b in blocks) == 1
    table = next(b for b in blocks if isinstance(b, Table) and "latency" in b.headers and "host share" in b.headers)
    from compare.site import matrix
    recs = [r for r in matrix.defaults_of("saxpy")(ctx.m, ctx.device)
            if r.status == "ok" and (t := data.per_call(r, "latency")) and data.floors(r, "latency")]
    assert recs, "the store holds a timed small cell with a yardstick"
    lat = table.headers.index("latency")
    for r in recs:
        t = data.per_call(r, "latency")
        want = fmt.with_floors(t.median, data.floors(r, "latency")) + (fmt.NOISY_MARK if t.noisy else "")
        assert " floors" in want
        assert any(row[:3] == (r.backend, r.variant, "saxpy") and row[lat] == want for row in table.rows), want
    graph = table.headers.index("graph")
    assert not any("floors" in row[graph] for row in table.rows)
    bw = saxpy.PAGES["bandwidth"][1](ctx)
    assert not any("floors" in c for b in bw if isinstance(b, Table) for row in b.rows for c in row)


def test_a_cells_own_floor_is_named_where_it_divides(tmp_path):
    """A record with its cell's own floor (``cell_floor.before``) reads '<time> = <n> cell floors',
    divided by that floor, and the page defines the unit once; the store's other records keep their
    run's yardstick ('floors'); a store without one (every committed store) reads as before."""
    import json
    import shutil
    from site_topics import STORE
    from compare.site import data, fmt, matrix, pages
    from compare.site import questions_pages as qp
    from compare.site.render import P, Table
    shutil.copytree(STORE, tmp_path / "store")
    doc = json.loads((tmp_path / "store" / "results.json").read_text())
    mine = next(r for r in doc["records"] if r["backend"] == "warp" and r["status"] == "ok" and r["device"] == "cuda"
                and r["scenario"] == "saxpy" and r["precision"] == "float32" and r["variant"] == "default"
                and r["params"]["n"] == 1000000 and r.get("hardware"))
    lat = mine["time"]["latency"]["median_s"]
    mine["cell_floor"] = {"before": {"latency_s": lat / 4, "pipelined_s": 1e-6, "context": "test"}}
    (tmp_path / "store" / "results.json").write_text(json.dumps(doc))
    m = data.load([tmp_path / "store"])
    c = qp.Ctx(m, pages.evaluate(m)[0], tmp_path / "site", "STORE")
    blocks = saxpy.PAGES["per-call"][1](c)
    assert sum(isinstance(b, P) and b.text == saxpy.OWN_FLOORS for b in blocks) == 1
    table = next(b for b in blocks if isinstance(b, Table) and "host share" in b.headers)
    col = table.headers.index("latency")
    row = next(row for row in table.rows if row[:3] == ("warp", "default", "saxpy") and row[3] == "defaults")
    assert row[col].startswith(fmt.with_floors(lat, 4.0, own=True)) and "= 4 cell floors" in row[col]
    others = [row[col] for row in table.rows if row[:2] != ("warp", "default") and " floors" in row[col]]
    assert others and not any("cell floors" in t for t in others)
    assert all(not data.own_floor(r, "latency") for r in matrix.defaults_of("saxpy")(c.m, c.device)
               if r.backend != "warp")


def test_without_a_cells_own_floor_the_page_does_not_mention_one(ctx):
    from compare.site.render import P, Table
    blocks = saxpy.PAGES["per-call"][1](ctx)
    assert not any(isinstance(b, P) and b.text == saxpy.OWN_FLOORS for b in blocks)
    assert not any("cell floors" in c for b in blocks if isinstance(b, Table) for row in b.rows for c in row)
