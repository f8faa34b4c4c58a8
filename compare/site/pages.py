"""The site: the overview (recommendation matrix), the question pages, stability, machine and
method; every page written as HTML and as its Markdown twin."""
from __future__ import annotations

import html
import math
import os
import re
from pathlib import Path
from typing import Any

import backends
from compare import charts, noise
from compare.site import data, fmt, matrix, questions, ranking
from compare.site import questions_pages as qp
from compare.site.data import Machine
from compare.site.matrix import Row
from compare.site.render import Figure, H, Items, P, Raw, Table

REPO_DOCS = Path(__file__).resolve().parents[2] / "docs"


def doc_link(out: Path, name: str) -> str:
    """A relative link to docs/NAME when the site lies inside this repository, else its name."""
    target = REPO_DOCS / name
    try:
        Path(out).resolve().relative_to(REPO_DOCS.parent)
    except ValueError:
        return f"`docs/{name}` in the repository"
    return f"[docs/{name}]({os.path.relpath(target, Path(out).resolve())})"


# ---- the matrix -------------------------------------------------------------------------------
def matrix_html(rows: list[Row], frameworks: list[str]) -> str:
    head = "".join(f'<th data-framework="{html.escape(f)}">{html.escape(f)}</th>' for f in frameworks)
    body = []
    for r in rows:
        tds = []
        for f in frameworks:
            c = r.cells.get(f, matrix.Cell(f, None))
            txt = html.escape(fmt.cell_text(c))
            if f in r.tied:
                txt = f"<strong>{txt}</strong>"
            tds.append(f'<td class="cell {c.band}" title="{html.escape(_title(r, c))}">{txt}</td>')
        q = f'<a href="{r.rule.page}.html">{html.escape(r.rule.question)}</a>'
        body.append(f"<tr><th>{q}</th>{''.join(tds)}<td>{html.escape(r.best_text())}</td></tr>")
    return (f'<table id="matrix"><thead><tr><th>question ({html.escape(rows[0].device if rows else "")})</th>'
            f"{head}<th>best</th></tr></thead><tbody>{''.join(body)}</tbody></table>")


def matrix_md(rows: list[Row], frameworks: list[str], link_prefix: str = "") -> str:
    lines = ["| question | " + " | ".join(frameworks) + " | best |", "|---|" + "---|" * (len(frameworks) + 1)]
    for r in rows:
        cells = []
        for f in frameworks:
            c = r.cells.get(f, matrix.Cell(f, None))
            t = f"{fmt.BAND_EMOJI[c.band]} {fmt.cell_text(c)}"
            cells.append(f"**{t}**" if f in r.tied else t)
        lines.append(f"| [{r.rule.question}]({link_prefix}{r.rule.page}.md) | " + " | ".join(cells)
                     + f" | {r.best_text()} |")
    return "\n".join(lines)


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
          "(`tie: …`). Colours: 🟩 **bold**: the best, or tied with it; 🟨 within 2× of the "
          "leader; 🟧 within 5×; 🟥 beyond; 🟦 `✎` a hand-written adjoint on a gradient row: "
          "its ratio to the best automatic differentiation, shown as a reference and "
          f"never ranked. `~` marks a noisy figure (quartile spread above {100 * noise.SPREAD:.0f} % of the "
          f"median, under {noise.MIN_REPEATS} repeats, other processes busy on the host while it was "
          "timed, or pipelined calls slower than one synchronised call); `✗` a cell that failed its check or crashed; `skipped` a framework or "
          "device not available (the reason is in the tooltip and on the question's page); `—` "
          "not measured. A framework's cell is its fastest variant; the variant and the raw "
          "figure are in the tooltip and on the pages.")


def legend() -> Raw:
    """The legend, with real colour swatches in HTML (no emoji font needed) and emoji in Markdown."""
    from compare.site.render import inline_html
    text = inline_html(LEGEND)
    for band, emoji in fmt.BAND_EMOJI.items():
        text = text.replace(emoji, f'<span class="cell {band}" style="display:inline-block;width:1.2em">&nbsp;</span>')
    return Raw(f'<p class="legend">{text}</p>', LEGEND)


def evaluate(m: Machine) -> tuple[list[Row], list[Row]]:
    """(rows with at least one figure, rows with none on this machine)."""
    rows = [matrix.evaluate(r, m, fmt.value) for r in questions.RULES]
    return [r for r in rows if r.top], [r for r in rows if not r.top]


# ---- pages ------------------------------------------------------------------------------------
def index(c: qp.Ctx, title: str, empty: list[Row]) -> list[Any]:
    m, fws = c.m, c.m.frameworks
    blocks: list[Any] = [P(f"Generated by `python -m compare site` from the stored records of one machine: "
                           f"**{m.name()}** ({len(m.run)} run cells, {len(m.sweep)} sweep cells"
                           + (f", {len(m.stress.analysis.get('rows', []))} stability findings" if m.stress else "")
                           + "). Nothing on these pages is written by hand."),
                         H("Which framework for my job?"),
                         Raw(matrix_html(c.rows, fws), matrix_md(c.rows, fws)), legend(),
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
    rows = []
    for r in sorted(matrix.all_defaults(c.m, c.device), key=lambda r: (r.scenario, r.backend)):
        if r.scenario not in matrix.IN_ALL:
            continue
        e = r.error or {}
        share = matrix.error_share(r)
        err, tol = data.num(e.get("vs_oracle")), data.num(e.get("tolerance"))
        rows.append((r.scenario, r.backend, r.status, "-" if err is None else f"{err:.3g}",
                     "-" if tol is None else f"{tol:.3g}", "-" if share is None else f"{share:.3g}",
                     str(e.get("metric", "")) or r.reason))
    blocks += [H("float32 error per scenario (default sizes)"),
               Table(("scenario", "framework", "status", "error", "tolerance", "share", "metric"), tuple(rows))]
    err = [r for r in c.m.sweep if data.tag(r, "sweep") == "error" and r.device == c.device]
    if err:
        from compare.sweep import plots as sweep_plots
        png, rel, csv = c.fig("accuracy-time-vs-error")
        if sweep_plots.plot_time_vs_error(list(err), c.device, png):
            charts.write_csv(png.with_suffix(".csv"), ("scenario", "framework", "variant", "precision", "params",
                                                       "wall median s", "error"),
                             [(r.scenario, r.backend, r.variant, r.precision,
                               fmt.params_text(r.params or {}, data.defaults(r.scenario)),
                               (r.time or {}).get("median_s"), (r.error or {}).get("converged"))
                              for r in err if r.status == "ok"])
            fws = ", ".join(f for f in c.m.frameworks if any(r.backend == f for r in err))
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
        setup = data.num((r.time or {}).get("setup_s")) if ok else None
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
    return blocks


def stability(c: qp.Ctx) -> list[Any]:
    if c.m.stress is None:
        return [P("No stability records (stress.json) in this store: `python -m compare stress`.")]
    from compare.stress import plots
    from compare.stress.registry import experiments
    a = c.m.stress.analysis
    blocks: list[Any] = [P("The stability stress suite: long rollouts, dt sweeps, overflow, learning-rate "
                           "divergence, gradient quality through contact, float32 error distributions and "
                           "run-to-run races. How each verdict is decided: " + doc_link(c.out, "stress.md")
                           + ". Verdicts in capitals flag a problem or a limit found.")]
    reg = experiments()
    for name, exp in reg.items():
        rows = [r for r in a.get("rows", []) if r.get("experiment") == name]
        if not rows:
            continue
        counts: dict[str, int] = {}
        for r in rows:
            v = re.sub(r"(?<![\w.])\d[\d.e+-]*%?", "#", str(r.get("verdict", "")).split(" (")[0])
            counts[v] = counts.get(v, 0) + 1
        blocks += [H(f"{name}: {exp.title}"), P("Verdicts: " + "; ".join(f"{v} ×{k}" for v, k in counts.items()))]
        series = (a.get("series") or {}).get(name)
        png, rel, _ = c.fig(f"stability-{name}")
        if series and exp.plot is not None:
            plots.draw(exp, series, png)
            if png.exists():
                charts.write_csv(png.with_suffix(".csv"), ("backend", "device", "precision", "setting", "figure", "value"),
                                 [(r["backend"], r["device"], r["precision"], r["setting"], r["figure"], r["value"])
                                  for r in rows])
                blocks.append(Figure(rel, exp.title, c.cmd(f"stress --only {name}", resume=False), rel[:-4] + ".csv"))
        shown = exp.table_rows(rows) if exp.table_rows is not None else rows
        blocks.append(Table(("framework", "device", "precision", "setting", "figure", "value", "verdict", "detail"),
                            tuple((r["backend"], r["device"], r["precision"], str(r["setting"]), str(r["figure"]),
                                   _value(r.get("value")), str(r["verdict"]), str(r.get("detail", ""))[:200])
                                  for r in shown)))
    return blocks


def _value(v: Any) -> str:
    if isinstance(v, float) and math.isfinite(v) and v != 0:
        return f"{v:.4g}"
    return "-" if v is None else str(v)
