"""The stability page: the stress suite's findings, one summary line per experiment (cases,
skipped, flagged, the worst row) ahead of every experiment's figure and rows; in HTML the rows
fold under a <details>, in Markdown they follow under the experiment's heading."""
from __future__ import annotations

import math
import re
from typing import Any

from compare.render import charts, figure_check
from compare.results.analysis import RunInfo
from compare.site import questions_pages as qp
from compare.site.provenance import run_words
from compare.site.questions_pages import doc_link
from compare.site.render import Figure, H, P, Raw, Table, block_html, block_md
from compare.stress import page


def stability(c: qp.Ctx) -> list[Any]:
    if c.m.stress is None:
        return [P("No stability records (stress.json) in this store: `python -m compare stress`.")]
    from compare.stress import plots
    from compare.stress.registry import experiments
    a = c.m.stress.analysis
    prov = page.provenance(page.stored(c.m.stress))
    reg = experiments()
    blocks: list[Any] = [P("The stability stress suite: long rollouts, dt sweeps, overflow, learning-rate "
                           "divergence, gradient quality through contact, float32 error distributions and "
                           "run-to-run races. How each verdict is decided: " + doc_link(c.out, "stress.md")
                           + ". Verdicts in capitals flag a problem or a limit found (`flagged`); the worst "
                           "row is the flagged one (else any) with the largest error, share of a bound or "
                           "count of differing elements, or the first flagged where its figure is none of "
                           "these. Each experiment's rows follow its summary line below."),
                         H("Summary"), Table(page.SUMMARY_HEADERS, tuple(page.summary(a.get("rows", []), reg)))]
    for name, exp in reg.items():
        rows = [r for r in a.get("rows", []) if r.get("experiment") == name]
        if not rows:
            continue
        counts: dict[str, int] = {}
        for r in rows:
            v = re.sub(r"(?<![\w.])\d[\d.e+-]*%?", "#", str(r.get("verdict", "")).split(" (")[0])
            counts[v] = counts.get(v, 0) + 1
        blocks += [H(f"{name}: {exp.title}", name),
                   P("Verdicts: " + "; ".join(f"{v} ×{k}" for v, k in counts.items())),
                   P(made_by(page.runs_of(prov.get(name, []))))]
        series = (a.get("series") or {}).get(name)
        png, rel, _ = c.fig(f"stability-{name}")
        if series and exp.plot is not None:
            figure_check.checked(lambda: plots.draw(exp, series, png), png)
            if png.exists():
                charts.write_csv(png.with_suffix(".csv"), ("backend", "device", "precision", "setting", "figure", "value"),
                                 [(r["backend"], r["device"], r["precision"], r["setting"], r["figure"], r["value"])
                                  for r in rows])
                blocks.append(Figure(rel, exp.title, c.cmd(f"stress --only {name}", timed=False), rel[:-4] + ".csv"))
        shown = exp.table_rows(rows) if exp.table_rows is not None else rows
        blocks.append(folded(Table(("framework", "device", "precision", "setting", "figure", "value", "verdict",
                                    "detail"),
                                   tuple((r["backend"], r["device"], r["precision"], str(r["setting"]),
                                          str(r["figure"]), _value(r.get("value")), str(r["verdict"]),
                                          str(r.get("detail", ""))[:200]) for r in shown))))
    return blocks


def made_by(runs: list[RunInfo]) -> str:
    """Which runs gave an experiment's rows (``provenance.run_words``; of several, the frameworks
    each gave)."""
    if not runs:
        return "Its run is not recorded."
    def one(r: RunInfo) -> str:
        gave = f": {', '.join(r['backends'])}" if len(runs) > 1 and r.get("backends") else ""
        return run_words(r.get("created"), r.get("git_commit"), r.get("git_dirty")) + gave
    return ("From " if len(runs) == 1 else f"From {len(runs)} runs: ") + "; ".join(map(one, runs)) + "."


def folded(t: Table) -> Raw:
    """A table of rows folded under a <details> in HTML (a scannable page); in Markdown, as is."""
    n = len(t.rows)
    return Raw(f"<details><summary>{n} row{'s' if n != 1 else ''}</summary>{block_html(t)}</details>", block_md(t))


def _value(v: Any) -> str:
    if isinstance(v, float) and math.isfinite(v) and v != 0:
        return f"{v:.4g}"
    return "-" if v is None else str(v)
