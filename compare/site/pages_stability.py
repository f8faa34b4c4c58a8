"""The stability pages: the answer first, each framework's outcome in each stress experiment
(compare/site/stability_outcomes.py), then the summary line per experiment; the detail of each
experiment on its own page (stability-EXPERIMENT), its figure with the sentence that says what to
see in it, its rows collapsed across the frameworks that gave the same finding (at most
``MAX_ROWS``; every row in the CSV it links)."""
from __future__ import annotations

import re
from typing import Any

from compare.render import charts, figure_check
from compare.results.analysis import Finding, RunInfo
from compare.site import questions_pages as qp
from compare.site import stability_outcomes as so
from compare.site.provenance import run_words
from compare.site.questions_pages import doc_link
from compare.site.render import Figure, H, P, Table
from compare.stress import page
from compare.stress.numerics import Experiment

MAX_ROWS = 200          # a detail page's table; a page stays under 300 lines (tests/site/test_pages_stability.py)
ROW_HEADERS = ("frameworks", "device", "precision", "setting", "figure", "value", "verdict", "detail")


def href(name: str) -> str:
    return f"stability-{name}.html"


def stability(c: qp.Ctx) -> list[Any]:
    if c.m.stress is None:
        return [P("No stability records (stress.json) in this store: `python -m compare stress`.")]
    from compare.stress.registry import experiments
    rows: list[Finding] = list(c.m.stress.analysis.get("rows", []))
    reg = {k: e for k, e in experiments().items() if any(r["experiment"] == k for r in rows)}
    got = so.outcomes(rows)
    fws = so.frameworks(rows)
    blocks: list[Any] = [P(f"**{answer(got, fws, list(reg))}**"),
                         H("Each framework in each experiment", "outcomes"),
                         Table(("framework", *(f"[{e}]({href(e)})" for e in reg)),
                               tuple((fw, *(cell(got.get((fw, e)), e) for e in reg)) for fw in fws), sortable=False),
                         P("In each cell, with the rows that count against the framework of those it ran: "
                           + "; ".join(f"**{k}**: {v}" for k, v in so.MEANING.items())
                           + ". A racy control that is caught (`RACE DETECTED`) is the detector working and "
                           "counts as a pass; one that is `MISSED` counts against its framework."),
                         H("Summary"),
                         Table(page.SUMMARY_HEADERS, tuple((f"[{s[0]}]({href(s[0])})", *s[1:])
                                                           for s in page.summary(rows, reg))),
                         P("The stability stress suite: long rollouts, dt sweeps, overflow, learning-rate "
                           "divergence, gradient quality through contact, float32 error distributions and "
                           "run-to-run races. How each verdict is decided: " + doc_link(c.out, "stress.md")
                           + ". Verdicts in capitals flag a problem or a limit found (`flagged`); the worst "
                           "row is the flagged one (else any) with the largest error, share of a bound or "
                           "count of differing elements, or the first flagged where its figure is none of "
                           "these. Each experiment's figure and rows are on its own page, linked above.")]
    prov = page.provenance(page.stored(c.m.stress))
    for name, exp in reg.items():
        mine = [r for r in rows if r["experiment"] == name]
        c.subpages[f"stability-{name}"] = (f"Stability: {name} — {c.m.name()}",
                                           detail(c, exp, mine, {k: got[k] for k in got if k[1] == name},
                                                  page.runs_of(prov.get(name, []))))
    return blocks


def cell(o: so.Outcome | None, experiment: str) -> str:
    return "-" if o is None else f"[{so.cell_text(o)}]({href(experiment)})"


def answer(got: dict[tuple[str, str], so.Outcome], fws: list[str], exps: list[str]) -> str:
    """The page's first sentence: what fails for one framework alone (or with some, or would
    not run), what fails for every framework that ran it, and who passes every experiment."""
    ran = [fw for fw in fws if any(got.get((fw, e)) and got[(fw, e)].kind != so.SKIPPED for e in exps)]
    def where(kind: str) -> list[str]:
        return [f"{fw} in {e} ({got[(fw, e)].of_kind} row{'s' if got[(fw, e)].of_kind != 1 else ''})"
                for e in exps for fw in ran if got.get((fw, e)) and got[(fw, e)].kind == kind]
    alone = where(so.ALONE)
    words = [f"Fails alone: {', '.join(alone)}" if alone else "No framework fails a case alone"]
    words += [f"{kind}: {', '.join(w)}" for kind in (so.WITH_SOME, so.ERROR) if (w := where(kind))]
    shared = [e for e in exps if any(got.get((fw, e)) and got[(fw, e)].kind == so.WITH_ALL for fw in ran)]
    if shared:
        words.append("flagged for every framework that ran the case (the problem or its precision, not a "
                     "port): " + ", ".join(shared))
    clean = [fw for fw in ran if all(got.get((fw, e)) is None or got[(fw, e)].kind in (so.PASS, so.SKIPPED)
                                     for e in exps)]
    words.append(f"{len(clean)} of {len(ran)} frameworks pass every experiment they ran"
                 + (f" ({', '.join(clean)})" if clean else ""))
    return "; ".join(words) + "."


def detail(c: qp.Ctx, exp: Experiment, rows: list[Finding], got: dict[tuple[str, str], so.Outcome],
           runs: list[RunInfo]) -> list[Any]:
    """One experiment's page: its answer, figure, rows (collapsed, capped) and their CSV."""
    name = exp.name
    summary = page.summary(rows, {name: exp})[0]
    kinds: dict[str, list[str]] = {}
    for (fw, _), o in got.items():
        kinds.setdefault(o.kind, []).append(fw)
    outcome = "; ".join(f"{k}: {', '.join(sorted(v))}" for k, v in sorted(kinds.items(), key=lambda kv: so.ORDER.index(kv[0])))
    blocks: list[Any] = [
        P(f"**{exp.title}: {summary[2]} cases, {summary[3]} skipped, {summary[4]} flagged. {outcome}.**"),
        P(f"Worst row: {summary[5]}." if summary[5] != "-" else "No row has a worst figure (none flagged, "
          "none an error or a share of a bound)."),
        P(f"Verdicts: {verdict_counts(rows)}. {made_by(runs)} How each verdict is decided: "
          f"{doc_link(c.out, 'stress.md')}. [Every experiment](stability.html).")]
    csv_png, csv_rel, _ = c.fig(f"stability-{name}")
    csv = csv_png.with_suffix(".csv")
    charts.write_csv(csv, ("backend", "device", "precision", "setting", "figure", "value", "verdict", "detail"),
                     [(r["backend"], r["device"], r["precision"], r["setting"], r["figure"], r.get("value"),
                       page.verdict(r), r.get("detail", "")) for r in rows])
    series = (c.m.stress.analysis.get("series") or {}).get(name) if c.m.stress else None
    if series and exp.plot is not None:
        from compare.stress import plots
        figure_check.checked(lambda: plots.draw(exp, series, csv_png), csv_png, key=(plots.draw, exp, series))
        if csv_png.exists():
            blocks.append(Figure(csv_rel, exp.look or exp.title, c.cmd(f"stress --only {name}", timed=False),
                                 csv_rel[:-4] + ".csv"))
    shown = so.collapsed(exp.table_rows(rows) if exp.table_rows is not None else rows)
    if len(shown) > MAX_ROWS:           # the failing rows first, then the others as they come
        bad = {i for i, s in enumerate(shown) if so.failing(Finding(experiment=name, backend=s[0], device=s[1], precision=s[2], setting=s[3],
                                                              figure=s[4], value=s[5], verdict=s[6], detail=s[7]))}
        shown = [shown[i] for i in sorted(range(len(shown)), key=lambda i: i not in bad)][:MAX_ROWS]
    blocks += [H("Rows", "rows"),
               P(f"{len(shown)} lines for {len(rows)} rows: frameworks that gave the same finding share a line"
                 + (f"; the first {MAX_ROWS} (failing ones first)" if len(shown) == MAX_ROWS else "")
                 + f". Every row, one per framework: [CSV]({csv_rel[:-4]}.csv)."),
               Table(ROW_HEADERS, tuple(tuple(s) for s in shown))]
    return blocks


def verdict_counts(rows: list[Finding]) -> str:
    """Each kind of verdict (numbers apart) and how many rows gave it."""
    counts: dict[str, int] = {}
    for r in rows:
        v = re.sub(r"(?<![\w.])\d[\d.e+-]*%?", "#", page.verdict(r).split(" (")[0])
        counts[v] = counts.get(v, 0) + 1
    return "; ".join(f"{v} ×{k}" for v, k in counts.items())


def made_by(runs: list[RunInfo]) -> str:
    """Which runs gave an experiment's rows (``provenance.run_words``; of several, the frameworks
    each gave)."""
    if not runs:
        return "Its run is not recorded."
    def one(r: RunInfo) -> str:
        gave = f": {', '.join(r['backends'])}" if len(runs) > 1 and r.get("backends") else ""
        return run_words(r.get("created"), r.get("git_commit"), r.get("git_dirty"), r.get("noisy_sitting")) + gave
    return ("From " if len(runs) == 1 else f"From {len(runs)} runs: ") + "; ".join(map(one, runs)) + "."

