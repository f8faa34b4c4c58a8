"""The site: the overview (recommendation matrix), the question pages, stability, machine and
method; every page written as HTML and as its Markdown twin."""
from __future__ import annotations

import html
from pathlib import Path
from typing import Any

import backends
from compare.render import charts, colors, figure_check
from compare.measuring import noise
from compare.site import data, fmt, glossary, matrix, pages_why, questions, ranking, shared_host
from compare.site import accuracy_why, untimed
from compare.site import questions_pages as qp
from compare.site.questions_pages import REPO_DOCS, doc_link  # noqa: F401 (assemble reads them here)
from compare.site.data import Machine
from compare.site.matrix import Row
from compare.site.pages_stability import stability  # noqa: F401 (a page of the site)
from compare.site.render import Figure, H, Items, P, Raw, Table
from compare.sweep.rows import converged, wall_s

# ---- the matrix -------------------------------------------------------------------------------
def matrix_html(rows: list[Row], frameworks: list[str], key: str = "") -> str:
    """The matrix, each ratio above pages_why.WHY_ABOVE marked, its reason listed under it; ``key``
    names the machine in the footnotes' ids."""
    notes = pages_why.notes(rows, frameworks)
    marks = {(n.row.rule.key, n.row.device, n.cell.framework): n for n in notes}
    head = "".join(f'<th data-framework="{html.escape(f)}">{html.escape(f)}</th>' for f in frameworks)
    body = []
    for r in rows:
        tds = []
        for f in frameworks:
            c = r.cells.get(f, matrix.Cell(f, None))
            txt = html.escape(fmt.cell_text(c))
            if f in r.tied:
                txt = f"<strong>{txt}</strong>"
            if (r.rule.key, r.device, f) in marks:
                txt += pages_why.mark_html(marks[(r.rule.key, r.device, f)], key)
            if fmt.variant_label(c):
                txt += f'<span class="variant">{html.escape(fmt.variant_label(c))}</span>'
            tds.append(f'<td class="cell {c.band}" title="{html.escape(_title(r, c))}">{txt}</td>')
        q = f'<a href="{r.rule.page}.html">{html.escape(r.rule.question)}</a>'
        body.append(f"<tr><th>{q}</th>{''.join(tds)}<td>{html.escape(r.best_text())}</td></tr>")
    return (f'<table id="matrix"><thead><tr><th>question ({html.escape(rows[0].device if rows else "")})</th>'
            f"{head}<th>best</th></tr></thead><tbody>{''.join(body)}</tbody></table>"
            + pages_why.notes_html(notes, key))


def matrix_md(rows: list[Row], frameworks: list[str], link_prefix: str = "", key: str = "") -> str:
    """The matrix in Markdown (matrix.md, which README embeds), its far ratios' footnotes under it."""
    notes = pages_why.notes(rows, frameworks)
    marks = {(n.row.rule.key, n.row.device, n.cell.framework): n for n in notes}
    lines = ["| question | " + " | ".join(frameworks) + " | best |", "|---|" + "---|" * (len(frameworks) + 1)]
    for r in rows:
        cells = []
        for f in frameworks:
            c = r.cells.get(f, matrix.Cell(f, None))
            t = f"{fmt.BAND_EMOJI[c.band]} {fmt.cell_text(c)}"
            t = f"**{t}**" if f in r.tied else t
            t += pages_why.mark_md(marks[(r.rule.key, r.device, f)], key) if (r.rule.key, r.device, f) in marks else ""
            cells.append(t + (f" <sub>{fmt.variant_label(c)}</sub>" if fmt.variant_label(c) else ""))
        lines.append(f"| [{r.rule.question}]({link_prefix}{r.rule.page}.md) | " + " | ".join(cells)
                     + f" | {r.best_text()} |")
    foot = pages_why.notes_md(notes, key, link_prefix)
    return "\n".join(lines) + (f"\n\n{foot}" if foot else "")


def _band_colors(band: str) -> tuple[str, str]:
    """(background, text) of a band: the pages' own (compare.render.colors.BANDS)."""
    b = colors.BAND[band]
    return b.background, b.text


def matrix_png(path: Path, rows: list[Row], frameworks: list[str], title: str) -> None:
    """The matrix as a picture (README's overview): drawn by matplotlib from the rows, at a fixed
    size per row and column in the font matplotlib ships, saved without metadata, so the same
    records give the same bytes (no browser, no screenshot)."""
    import textwrap

    import matplotlib
    from matplotlib.patches import Rectangle
    plt = charts.pyplot()
    from matplotlib.textpath import TextPath
    q_in, col_in, line_in, pad_in, margin = 2.7, 0.78, 0.17, 0.08, 0.12
    # the last column as wide as its longest text (a tie names several), in the 8-point font
    best_in = max([0.85] + [TextPath((0, 0), r.best_text() or "—", size=8).get_extents().width / 72 + 0.16
                            for r in rows])
    labels = [textwrap.wrap(r.rule.question, 40) or [""] for r in rows]
    heights = [pad_in * 2 + line_in * len(lab) for lab in labels]
    width = 2 * margin + q_in + col_in * len(frameworks) + best_in
    foot = textwrap.wrap(
        "Each cell: the framework's figure over the row's best (1.00× is the best; 2.00× twice as slow, "
        "half the rate or twice the memory); small text under a ratio: the winning variant, not the default; "
        f"~ noisy, {fmt.UNTIMED_MARK} a variant not timed there, ✗ failed, — not measured. Generated by python -m "
        "compare site from the stored records; each row's rule is on the report's pages.", int(width * 15),
        break_on_hyphens=False)
    head_in, title_in, foot_in = 0.34, 0.5, 0.15 + line_in * len(foot)
    height = title_in + head_in + sum(heights) + foot_in
    with matplotlib.rc_context({**charts.RC, "font.family": "DejaVu Sans", "font.size": 8}):
        fig = plt.figure(figsize=(width, height))
        ax = fig.add_axes((0, 0, 1, 1))
        ax.set_xlim(0, width)
        ax.set_ylim(height, 0)               # inches from the top
        ax.axis("off")
        ax.text(margin, title_in / 2, title, fontsize=11, fontweight="bold", va="center")
        xs = [margin, margin + q_in] + [margin + q_in + col_in * (i + 1) for i in range(len(frameworks))] \
            + [width - margin]

        def box(i: int, y: float, h: float, text: str, bg: str, fg: str = "#1b1f24", bold: bool = False,
                left: bool = False, dy: float = 0.0) -> None:
            ax.add_patch(Rectangle((xs[i], y), xs[i + 1] - xs[i], h, facecolor=bg, edgecolor="#d0d7de",
                                   linewidth=0.8))
            ax.text(xs[i] + 0.06 if left else (xs[i] + xs[i + 1]) / 2, y + h / 2 + dy, text, color=fg,
                    ha="left" if left else "center", va="center", fontweight="bold" if bold else "normal")

        y = title_in
        device = rows[0].device if rows else ""
        for i, head in enumerate([f"question ({device})", *frameworks, "best"]):
            box(i, y, head_in, head, "#f3f5f7", bold=True, left=i == 0)
        y += head_in
        for r, lab, h in zip(rows, labels, heights):
            box(0, y, h, "\n".join(lab), "#ffffff", left=True)
            for i, f in enumerate(frameworks, start=1):
                c = r.cells.get(f, matrix.Cell(f, None))
                bg, fg = _band_colors(c.band)
                label = fmt.variant_label(c)
                box(i, y, h, fmt.cell_text(c), bg, fg, bold=f in r.tied, dy=-0.05 if label else 0.0)
                if label:      # the winning variant, small, under the ratio
                    ax.text((xs[i] + xs[i + 1]) / 2, y + h / 2 + 0.03, label, color=fg, fontsize=6,
                            ha="center", va="top")
            box(len(frameworks) + 1, y, h, r.best_text() or "—", "#ffffff")
            y += h
        ax.text(margin, y + foot_in / 2, "\n".join(foot), fontsize=7, color="#57606a", va="center")
        charts.save(fig, path)


def _title(r: Row, c: matrix.Cell) -> str:
    return fmt.cell_title(c, r.rule.unit, f"one of the {r.rule.reference.what.lower()}" if r.rule.reference else "a reference")


LEGEND = ("Each cell is the framework's figure divided by the leading framework's on that row "
          "(1.00× leads; 2.00× is twice as slow, half the rate or twice the memory). A row names "
          "a best (last column) only where the leader is separated from every other framework: "
          f"95 % intervals across worker processes that do not overlap and at least "
          f"{100 * (ranking.SEPARATED_GAP - 1):.0f} % apart, or, for a figure from one process "
          f"(no interval), at least {ranking.ONE_PROCESS_GAP:g}× apart; deterministic figures "
          f"(memory, error shares) at least {100 * (ranking.SEPARATED_GAP - 1):.0f} % apart. "
          "Otherwise the row is a tie, and everyone not separated from the leader shares it "
          "(`tie: …`); `— (why)` where it names none (figures from several runs, not from a commit, or "
          "from one process on a row that ranks only repeated figures). Colours: " + "; ".join(f"{b.emoji} {colors.band_words(b)}" for b in colors.BANDS) +
          f". `~` marks a noisy figure (quartile spread above {100 * noise.SPREAD:.0f} % of the "
          f"median, under {noise.MIN_REPEATS} repeats, other processes busy on the host while it was "
          "timed, or pipelined calls slower than one synchronised call); `✗` a cell that failed its check or crashed; `skipped` a framework or "
          "device not available (the reason is on the row's page); `—` not measured. A framework's "
          "cell is its fastest variant; a variant other than the default is named under the ratio; "
          f"`{fmt.UNTIMED_MARK}` marks a framework with a variant never timed at the row's point (named on the "
          "row's page): its cell is the fastest of those timed. "
          f"A ratio above {pages_why.WHY_ABOVE:g}× carries a numbered mark: its reason, read from its "
          "records, is listed under the matrix. The figures behind the ratios (times, rates, bytes, "
          "their spread and interval, and the default variant's figure) are on each row's page: "
          "follow the row's link (in the HTML report, hovering over a cell also shows them).")


def legend(glossary: str = "") -> Raw:
    """The legend, with real colour swatches in HTML (no emoji font needed) and emoji in Markdown;
    ``glossary``: the glossary's link from the page, where it has one."""
    from compare.site.render import inline_html
    words = LEGEND + (f" Every term, variant and framework in a sentence: [the glossary]({glossary})." if glossary else "")
    text = inline_html(words)
    for band, emoji in fmt.BAND_EMOJI.items():
        text = text.replace(emoji, f'<span class="cell {band}" style="display:inline-block;width:1.2em">&nbsp;</span>')
    return Raw(f'<p class="legend">{text}</p>', words)


def evaluate(m: Machine) -> tuple[list[Row], list[Row]]:
    """(rows with at least one figure, rows with none on this machine)."""
    rows = [untimed.mark(pages_why.explain(matrix.evaluate(r, m, fmt.value), m), m) for r in questions.RULES]
    return [r for r in rows if r.top], [r for r in rows if not r.top]


# ---- pages ------------------------------------------------------------------------------------
def index(c: qp.Ctx, title: str, empty: list[Row]) -> list[Any]:
    m, fws, key = c.m, c.m.frameworks, pages_why.key_of(c.m)
    blocks: list[Any] = [P(f"Generated by `python -m compare site` from the stored records of one machine: "
                           f"**{m.name()}** ({len(m.run)} run cells, {len(m.sweep)} sweep cells"
                           + (f", {len(m.stress.analysis.get('rows', []))} stability findings" if m.stress else "")
                           + "). Nothing on these pages is written by hand."),
                         H("Which framework for my job?"),
                         Raw(matrix_html(c.rows, fws, key), matrix_md(c.rows, fws, key=key)),
                         legend(glossary.href(c.out)),
                         H("Verdicts and the rule behind each row")]
    blocks.append(Items(tuple(f"[{r.rule.question}]({r.rule.page}.html): **{r.verdict}** Rule: {r.rule.text}"
                              for r in c.rows)))
    if empty:
        blocks.append(P("Rows without records on this machine: " + "; ".join(r.rule.question for r in empty)
                        + ". Another machine's report answers them."))
    blocks += [H("Pages"), Items(tuple(f"[{t}]({k}.html)" for k, t in questions.PAGES.items()))]
    return blocks


def accuracy(c: qp.Ctx) -> list[Any]:
    blocks: list[Any] = [P("Every cell is checked against a float64 oracle of the same algorithm; the "
                           "tolerance is derived per scenario (" + doc_link(c.out, "measurement.md")
                           + "). The share is the error divided by that tolerance.")]
    blocks += qp.verdicts(c.rows_of("accuracy"))
    recs = [r for r in matrix.all_defaults(c.m, c.device) if r.scenario in matrix.IN_ALL]
    why = accuracy_why.paragraph(recs)      # what sets the shares apart, from the records
    blocks += [P(why)] if why else []
    rows = []
    for r in sorted(recs, key=lambda r: (r.scenario, r.backend)):
        e = r.error
        share = matrix.error_share(r)
        err, tol = (data.num(e.vs_oracle), data.num(e.tolerance)) if e else (None, None)
        rows.append((r.scenario, r.backend, r.status, "-" if err is None else f"{err:.3g}",
                     "-" if tol is None else f"{tol:.3g}", "-" if share is None else f"{share:.3g}",
                     str((e.get("metric", "") if e else "")) or r.reason))
    blocks += [H("float32 error per scenario (default sizes)"),
               Table(("scenario", "framework", "status", "error", "tolerance", "share", "metric"), tuple(rows))]
    swept = [r for r in c.m.sweep if data.tag(r, "sweep") == "error" and r.device == c.device]
    if swept:
        from compare.sweep import plots as sweep_plots
        from compare.sweep.metrics import error_points
        png, rel, csv = c.fig("accuracy-time-vs-error")
        if figure_check.checked(lambda: sweep_plots.plot_time_vs_error(list(swept), c.device, png), png,
                                key=(sweep_plots.plot_time_vs_error, list(swept), c.device)):
            # the plotted points and their coordinates: the wall clock (time.wall; time.median_s
            # is the CUDA events' where a framework has them) and the error against the
            # converged reference (converged.error, unfloored)
            pts = [p["rec"] for sc in dict.fromkeys(r.scenario for r in swept)
                   for p in error_points(list(swept), c.device, sc)]
            charts.write_csv(png.with_suffix(".csv"), ("scenario", "framework", "variant", "precision", "params",
                                                       "wall median s", "error"),
                             [(r.scenario, r.backend, r.variant, r.precision,
                               fmt.params_text(r.params or {}, data.defaults(r.scenario)),
                               wall_s(r), converged(r).error) for r in pts])
            fws = ", ".join(f for f in c.m.frameworks if any(r.backend == f for r in swept))
            blocks += [H("Run time against error"),
                       Figure(rel, "Time against error against a converged float64 reference, both "
                              "precisions and fast-math variants; the Pareto front is the fastest "
                              f"framework at each accuracy. Frameworks in this sweep: {fws}.",
                              c.cmd(f"sweep error --devices {c.device}"), csv)]
    return blocks


def compile_cost(c: qp.Ctx) -> list[Any]:
    blocks: list[Any] = [P("Time to first result, with kernel caches emptied: set-up (the kernel's "
                           "constructor: allocation, upload, and whatever framework work a port does "
                           "there, e.g. recording a tape, which compiles its kernels) plus the first "
                           "call (compilation or tracing plus the call). A port may compile in either, "
                           "so only their sum compares (" + doc_link(c.out, "measurement.md")
                           + "). Later calls in the same process reuse the compiled kernel.")]
    blocks += qp.verdicts(c.rows_of("compile"))
    recs = [r for r in matrix.all_defaults(c.m, c.device) if r.scenario in matrix.IN_ALL]
    panels = [charts.Panel(sc, [qp._bar(r, data.first_result) for r in recs if r.scenario == sc])
              for sc in matrix.IN_ALL]
    png, rel, csv = c.fig("compile-first-call")
    charts.bar_panels(png, f"Time to first result, cold caches ({c.device}, float32, default variant)",
                      "seconds: set-up + first call (log scale)", panels, log=True, fmt=fmt.seconds)
    blocks.append(Figure(rel, "Set-up plus first call per scenario and framework.",
                         c.cmd(f"all --devices {c.device} --precision float32"), csv))
    rows = []
    for r in sorted(recs, key=lambda r: (r.scenario, r.backend)):
        ok = r.status == "ok"
        setup = data.num(r.time.setup_s) if ok and r.time else None
        first, total = (data.timing(r, "first"), data.first_result(r)) if ok else (None, None)
        rows.append((r.scenario, r.backend, fmt.seconds(setup), fmt.seconds(first.median if first else None),
                     fmt.seconds(total.median if total else None),
                     str(total.processes) if total else "-", r.status if ok else f"{r.status}: {r.reason[:120]}"))
    blocks += [H("Set-up and first call per cell"),
               Table(("scenario", "framework", "set-up", "first call", "time to first result",
                      "processes", "status"), tuple(rows))]
    return blocks


def cpu(c: qp.Ctx) -> list[Any]:
    blocks: list[Any] = qp.verdicts(c.rows_of("cpu"))
    recs = [r for r in matrix.all_defaults(c.m, "cpu") if r.scenario in matrix.IN_ALL]
    if not recs:
        return blocks + [P("This machine's records hold no CPU cells: see the CPU report.")]
    baseline = backends.cpu_baseline()
    who = backends.display_name(baseline or "")
    panels = []
    for sc in matrix.IN_ALL if baseline else ():
        mine = [r for r in recs if r.scenario == sc]
        base = next((data.per_call(r, "throughput") for r in mine if r.backend == baseline and r.status == "ok"), None)
        if base is None:
            continue
        bars = []
        for r in mine:
            t = data.per_call(r, "throughput") if r.status == "ok" else None
            bars.append(charts.Bar(r.backend, "default", base.median / t.median if t else None,
                                   mark="" if t else r.status))
        panels.append(charts.Panel(sc, bars))
    if panels:
        png, rel, csv = c.fig(f"cpu-speedup-vs-{baseline}")
        charts.bar_panels(png, f"CPU: speed-up against {who} in the same run (float32, throughput regime)",
                          f"times faster than {who} (log scale)", panels, log=True, better="higher",
                          reference=(1.0, who), fmt=lambda v: f"{v:.3g}×")
        blocks.append(Figure(rel, f"Speed-up of each framework against {who}, per scenario.",
                             c.cmd("all --devices cpu --precision float32"), csv))
    blocks += [H("Every CPU cell at the defaults"), qp.timing_table(recs, ("latency", "throughput"))]
    return blocks + shared_host.section(c.m)
