"""compare/site/pages.py: the overview's matrix in three formats and the accuracy, first-call and
CPU pages, built from the site's test store (fast tier; the figures are drawn, not rasterised:
tests/render/test_charts.py checks them). The matrix rows themselves: tests/site/test_matrix.py."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from compare.render import charts
from compare.site import data, pages, pages_why, questions
from compare.site import questions_pages as qp
from compare.site.render import Figure, H, Items, Raw, Table

STORE = Path(__file__).resolve().parents[2] / "tests" / "data" / "site"


@pytest.fixture(scope="module")
def machine():
    return data.load([STORE])


@pytest.fixture(scope="module")
def evaluated(machine):
    return pages.evaluate(machine)


@pytest.fixture
def ctx(machine, evaluated, tmp_path, monkeypatch):
    saved = []

    def save(fig, path):
        saved.append(fig)
        Path(path).write_bytes(b"png")
        charts.pyplot().close(fig)
    monkeypatch.setattr(charts, "save", save)
    from compare.sweep import plots as sweep_plots       # drawn in tests/sweep/test_sweep_plots.py

    def time_vs_error(records, device, path):
        Path(path).write_bytes(b"png")
        return True
    monkeypatch.setattr(sweep_plots, "plot_time_vs_error", time_vs_error)
    c = qp.Ctx(machine, evaluated[0], tmp_path, "STORE")
    c.saved = saved
    return c


def test_evaluate_splits_rows_with_and_without_figures(evaluated):
    rows, empty = evaluated
    assert all(r.top for r in rows) and not any(r.top for r in empty)
    assert [r.rule.key for r in rows + empty] == sorted((r.rule.key for r in rows + empty),
                                                        key=[q.key for q in questions.RULES].index)
    assert {"cpu", "busy"} <= {r.rule.key for r in empty}          # an H100 store: no CPU cells


def test_the_matrix_has_one_column_per_framework_and_a_best(machine, evaluated):
    rows, fws = evaluated[0], machine.frameworks
    table, _, notes = pages.matrix_md(rows, fws, "pages/").partition("\n\n")
    md = table.splitlines()
    far = pages_why.notes(rows, fws)          # the far ratios' footnotes, under the table
    assert far and len(notes.splitlines()) == 2 + len({id(n.row) for n in far}) and "](pages/" in notes
    assert md[0] == "| question | " + " | ".join(fws) + " | best |"
    assert len(md) == 2 + len(rows) and all(line.count(" | ") == len(fws) + 1 for line in md[2:])
    assert md[2].startswith(f"| [{rows[0].rule.question}](pages/{rows[0].rule.page}.md) |")
    html = pages.matrix_html(rows, fws)
    assert re.findall(r'data-framework="([^"]+)"', html) == fws
    assert html.count("<tr>") == 1 + len(rows) and html.count('<td class="cell ') == len(rows) * len(fws)


def test_the_legend_states_the_separation_rule():
    legend = pages.legend()
    assert "at least 5 % apart" in legend.markdown and "at least 1.6× apart" in legend.markdown
    assert '<span class="cell best"' in legend.html and "🟩" not in legend.html


def test_the_matrix_picture_is_drawn_once(ctx, evaluated, machine):
    pages.matrix_png(ctx.into / "overview.png", evaluated[0], machine.frameworks, "overview")
    assert len(ctx.saved) == 1 and (ctx.into / "overview.png").is_file()


def test_the_index_links_every_row_and_page(ctx, evaluated):
    blocks = pages.index(ctx, "t", evaluated[1])
    items = [b for b in blocks if isinstance(b, Items)]
    assert all(f"]({r.rule.page}.html)" in items[0].texts[i] for i, r in enumerate(ctx.rows))
    assert {f"[{t}]({k}.html)" for k, t in questions.PAGES.items()} == set(items[-1].texts)
    assert any(isinstance(b, Raw) and 'id="matrix"' in b.html for b in blocks)
    assert any("Rows without records on this machine" in getattr(b, "text", "") for b in blocks)


def test_the_accuracy_page_tables_every_default_cell(ctx):
    blocks = pages.accuracy(ctx)
    table = next(b for b in blocks if isinstance(b, Table))
    assert table.headers[:3] == ("scenario", "framework", "status") and table.rows
    heads = [b.text for b in blocks if isinstance(b, H)]
    assert "float32 accuracy against the float64 oracle" in heads and "Run time against error" in heads
    assert (ctx.into / "figures" / "accuracy-time-vs-error.csv").is_file()


def test_the_first_call_page_draws_its_figure_and_tables_setup_and_first_call(ctx):
    blocks = pages.compile_cost(ctx)
    assert [b.png for b in blocks if isinstance(b, Figure)] == ["figures/compile-first-call.png"]
    assert (ctx.into / "figures" / "compile-first-call.csv").is_file()
    table = next(b for b in blocks if isinstance(b, Table))
    assert "time to first result" in table.headers and table.rows


def test_the_cpu_page_of_a_gpu_store_points_at_the_cpu_report(ctx):
    blocks = pages.cpu(ctx)
    assert any("no CPU cells" in getattr(b, "text", "") for b in blocks) and not ctx.saved
