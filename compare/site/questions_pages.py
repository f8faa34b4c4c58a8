"""What the question pages share: the context of a build, the verdicts of a page's matrix rows,
bars per framework and variant with spread, the scaling curves, the numbers as a table, and
under each figure the command that reproduces its data. The pages of one scenario's questions
are in compare/site/topics/, the pages over every scenario in compare/site/pages.py."""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any, Callable, Sequence, cast

from compare.planning import publish_plan
from compare.render import charts
from compare.results.record import Record
from compare.site import data, fmt, pages_why, provenance, ranking
from compare.site.data import Machine
from compare.site.matrix import Row
from compare.site.render import Block, Figure, H, Items, P, Table

Page = list[Block]

REPO_DOCS = Path(__file__).resolve().parents[2] / "docs"


def doc_link(out: Path, name: str) -> str:
    """A relative link to docs/NAME when the site lies inside this repository, else its name."""
    target = REPO_DOCS / name
    try:
        Path(out).resolve().relative_to(REPO_DOCS.parent)
    except ValueError:
        return f"`docs/{name}` in the repository"
    return f"[docs/{name}]({os.path.relpath(target, Path(out).resolve())})"


class Ctx:
    """What every page builder needs: the machine, its rows, where the site will stand (``out``:
    links are relative to it) and the folder it is written into (``into``, its sibling while it
    is built: compare/site/whole.py)."""

    def __init__(self, m: Machine, rows: list[Row], out: Path, store_arg: str, into: Path | None = None,
                 later: Sequence[tuple[str, Machine]] = ()) -> None:
        self.m, self.rows, self.out, self.store_arg = m, rows, out, store_arg
        self.later = list(later)      # the later sittings' stores, by label (compare/site/sittings.py)
        self.into = into or out
        self.subpages: dict[str, tuple[str, Page]] = {}    # stem -> (title, blocks): pages a builder adds
        self.device = m.primary_device
        (self.into / "figures").mkdir(parents=True, exist_ok=True)

    def rows_of(self, page: str) -> list[Row]:
        return [r for r in self.rows if r.rule.page == page]

    def fig(self, name: str) -> tuple[Path, str, str]:
        """The PNG's path, and the PNG's and CSV's paths relative to the pages."""
        return self.into / "figures" / f"{name}.png", f"figures/{name}.png", f"figures/{name}.csv"

    def cmd(self, *words: str, timed: bool = True) -> str:
        """The commands that measure a figure's cells again, as the published ones were (timed
        suites: in several interleaved processes, set-ups side by side, within one sitting), into
        a new folder, and build its site; ``compare agree`` then holds it against this store
        ordering by ordering.
        (Into the store with --resume they would remeasure nothing: it holds every cell.)"""
        store = self.store_arg if " " not in self.store_arg else "STORE"
        protocol = " " + " ".join(publish_plan.PROTOCOL) if timed else ""
        return (f"python -m compare {' '.join(words)}{protocol} --out NEW\n"
                "python -m compare site NEW --out NEW/report" + (f"\npython -m compare agree {store} NEW" if timed else ""))


def verdicts(rows: list[Row]) -> list[Block]:
    out: list[Block] = []
    for r in rows:
        runs = f" {provenance.words(r.runs)}" if provenance.one_run(r.runs) else ""
        out += [H(r.rule.question, r.rule.key), P(f"**{r.verdict}**"),
                P(f"Rule: {r.rule.text} Read here: {r.scope or 'no records'}, device {r.device}.{runs}")]
        out += not_default(r)
        far = pages_why.lines(r)
        if far:
            out += [P(f"Ratios above {pages_why.WHY_ABOVE:g}×, and what the slow port does differently, "
                      "from its record (`info`, `time`):"), Items(tuple(far))]
    return out


def not_default(r: Row) -> list[Block]:
    """The cells whose figure is a variant other than the framework's default, with the
    default's figure beside it: what the plain call costs."""
    won = [c for c in r.cells.values() if c.winner_not_default]
    if not won:
        return []
    unit = r.rule.unit
    return [P("Where a framework's cell is a variant other than its default, the default variant's "
              "figure on the same row:"),
            Table(("framework", "cell's variant", "its figure", "ratio", "default variant's figure"),
                  tuple((c.framework, c.variant, fmt.value(c.value, unit),
                         fmt.ratio(c.ratio) if c.ratio is not None else "-", fmt.default_text(c, unit))
                        for c in sorted(won, key=lambda c: c.framework)), sortable=False)]


def _bar(r: Record, fig: Callable[[Record], Any], note: str = "") -> charts.Bar:
    v = fig(r) if r.status == "ok" else None
    if isinstance(v, data.Timing):
        return charts.Bar(r.backend, r.variant, v.median, v.lo, v.hi,
                          "~ noisy" if v.noisy else note)
    return charts.Bar(r.backend, r.variant, v,
                      mark=note if v is not None else (r.status if r.status != "ok" else "not measured"))


def timing_table(recs: list[Record], regimes: tuple[str, ...] = data.REGIMES,
                 extra: Callable[[Record], list[str]] | None = None,
                 extra_headers: tuple[str, ...] = (), floors: bool = False) -> Table:
    """Each record's per-call figures by regime; ``floors``: each beside its launch floors where the
    regime has that unit (``data.floors``: the cell's own, 'cell floors', else its run's yardstick)."""
    rows = []
    for r in sorted(recs, key=lambda r: (r.scenario, data.size(r), r.backend, r.variant)):
        cells = [r.backend, r.variant, r.scenario,
                 fmt.params_text(r.params or {}, data.defaults(r.scenario)), r.precision]
        for g in regimes:
            t = data.per_call(r, g) if r.status == "ok" else None
            text = (fmt.with_floors(t.median, data.floors(r, g, t), data.own_floor(r, g)) if t and floors
                    else fmt.seconds(t.median) if t else "")
            cells.append("-" if t is None else text + (fmt.NOISY_MARK if t.noisy else ""))
            if g != "graph":
                cells.append("-" if t is None else fmt.seconds(t.hi - t.lo))
        cells += extra(r) if extra else []
        cells.append(r.status if r.status == "ok" else f"{r.status}: {r.reason[:160]}")
        rows.append(tuple(cells))
    heads = ["framework", "variant", "scenario", "parameters", "precision"]
    for g in regimes:
        heads += [g] if g == "graph" else [g, f"{g} IQR"]
    return Table(tuple(heads + list(extra_headers) + ["status"]), tuple(rows))


def _label(backend: str, variant: str | None) -> str:
    """A framework and its variant as the figures and verdicts name them."""
    return backend if variant in (None, "default") else f"{backend} {variant}"


# ---- helpers of the topic pages (compare/site/topics/) --------------------------------
def _group(recs: list[Record]) -> dict[tuple[str, str], list[Record]]:
    out: dict[tuple[str, str], list[Record]] = {}
    for r in recs:
        out.setdefault((r.backend, r.variant), []).append(r)
    return out


def _host_share(r: Record) -> list[str]:
    thr = r.time.throughput if r.time else None
    h, t = (data.num(thr.host_s), data.num(thr.median_s)) if thr else (None, None)
    return [fmt.pct(h / t) if h is not None and t else "-"]


def _launch_yardstick(recs: list[Record]) -> str:
    """The driver's empty-kernel launch of the runs that timed ``recs`` (each record keeps its own
    run's yardstick in ``hardware``), never another run's."""
    seen = []
    for r in recs:
        hw = r.hardware
        lat, pipe = (data.num(hw.launch_latency_s), data.num(hw.launch_pipelined_s)) if hw else (None, None)
        if lat and pipe and (lat, pipe) not in seen:
            seen.append((lat, pipe))
    words = [f"{fmt.seconds(lat)} with a synchronise, {fmt.seconds(pipe)} pipelined" for lat, pipe in seen]
    if len(words) > 1:
        return f"{len(words)} runs timed these cells, their yardsticks: " + "; ".join(words)
    return words[0] if words else ""


def _cell(r: Record) -> tuple[Any, ...]:
    """A cell's identity without the suite's tags; a parameter an older record lacks is at its
    default (as matrix.latest reads it)."""
    import json
    params = {**data.defaults(r.scenario), **(r.params or {})}
    return (r.scenario, r.backend, r.device, r.precision, r.variant, json.dumps(params, sort_keys=True, default=str))


def _dedicated(recs: list[Record], run: tuple[Record, ...]) -> list[Record]:
    """Each record, or the run suite's (its newest) where that measured the same cell too: one
    figure per cell on every page, the one the matrix rows keep (the run suite's record is the
    later in ``Machine.records``, so ``matrix.latest`` keeps it)."""
    mine = {_cell(r): r for r in run}
    return [mine.get(_cell(r), r) for r in recs]


def _scaling(c: Ctx, scenario: str, ylabel: str, xlabel: str, memory: bool = False, compact: bool = False) -> Page:
    """The scaling sweep's figures and table; ``compact``: the table only at the largest size
    (the published one), every size in the CSV it links."""
    recs = _dedicated([r for r in c.m.sweep if data.tag(r, "sweep") == "scaling" and r.scenario == scenario
                       and r.device == c.device and r.precision == "float32"], c.m.run)
    ok = [r for r in recs if r.status == "ok"]
    if not ok:
        return []
    blocks: Page = [H(f"{scenario.capitalize()}: scaling")]
    for what, fig, unit, lab in (("rate", data.item_rate, "1/s", ylabel),
                                 ("memory", data.device_bytes, "B", "device memory above the context (bytes)")):
        if what == "memory" and not memory:
            continue
        series = []
        for (fw, var), rs in sorted(_group(ok).items()):
            pts = sorted((data.size(r), v) for r in rs if (v := fig(r)) is not None)
            if pts:
                series.append(charts.Series(_label(fw, var), fw,
                                            [p[0] for p in pts], [p[1] for p in pts]))
        if not series:
            continue
        png, rel, csv = c.fig(f"{scenario}-{what}-vs-size")
        charts.curves(png, f"{scenario}: {lab} against size ({c.device}, float32, throughput regime)",
                      xlabel, lab, series)
        blocks.append(Figure(rel, f"{lab.capitalize()} against size, one line per framework (a size the "
                             "run suite measured too shows its record, as the verdicts do).",
                             c.cmd(f"sweep scaling --scenarios {scenario} --devices {c.device}"), csv))
    rows = []
    for r in sorted(recs, key=lambda r: (r.backend, data.size(r))):
        rows.append((r.backend, r.variant, f"{data.size(r):.0f}",
                     fmt.rate(data.item_rate(r)) if r.status == "ok" else "-",
                     fmt.nbytes(data.device_bytes(r)) if r.status == "ok" else "-",
                     "scaling sweep" if data.tag(r, "sweep") == "scaling" else "run",
                     r.status if r.status == "ok" else f"{r.status}: {r.reason[:120]}"))
    heads = ("framework", "variant", "size", ylabel, "device memory", "record", "status")
    if compact:
        _, _, csv = c.fig(f"{scenario}-scaling")
        charts.write_csv(c.into / csv, ("framework", "variant", "size", "items per second", "device bytes",
                                        "record", "status"),
                         [(r.backend, r.variant, data.size(r), data.item_rate(r) if r.status == "ok" else None,
                           data.device_bytes(r) if r.status == "ok" else None,
                           "scaling sweep" if data.tag(r, "sweep") == "scaling" else "run",
                           r.status if r.status == "ok" else f"{r.status}: {r.reason}")
                          for r in sorted(recs, key=lambda r: (r.backend, data.size(r)))])
        top = max(data.size(r) for r in recs)
        blocks.append(P(f"At the largest size ({top:.0f}), the one the verdicts read; every size: [CSV]({csv})."))
        rows = [row for row in rows if row[2] == f"{top:.0f}"]
    blocks.append(Table(heads, tuple(rows)))
    return blocks


@dataclasses.dataclass(frozen=True)
class _Fig:                 # a figure as compare.site.ranking reads it
    framework: str
    value: float | None
    ci: tuple[float, float] | None


def _longest_loop(hz: list[Record]) -> Page:
    """Which framework differentiates a long loop fastest, and at what memory: the horizon
    sweep's hard-contact float32 cells at the most steps that two or more frameworks ran."""
    ok = [r for r in hz if r.status == "ok" and r.precision == "float32"
          and (r.params or {}).get("contact") == "hard"]
    steps_of = lambda r: int((r.params or {}).get("steps") or 0)  # noqa: E731
    ran: dict[int, set[str]] = {}
    for r in ok:
        ran.setdefault(steps_of(r), set()).add(r.backend)
    shared = [n for n, fws in ran.items() if len(fws) >= 2]
    if not shared:
        return []
    n = max(shared)
    rows = []
    ci: dict[int, tuple[float, float] | None] = {}
    for r in (r for r in ok if steps_of(r) == n):
        t = data.per_call(r, "throughput") or data.timing(r, "latency")
        rows.append((t.median if t else None, data.device_bytes(r), r))
        ci[id(r)] = t.ci if t else None
    # (cast: each sorts only the rows whose figure it filtered to be not None)
    timed = sorted((x for x in rows if x[0] is not None), key=lambda x: cast(float, x[0]))
    small = sorted((x for x in rows if x[1] is not None), key=lambda x: cast(float, x[1]))
    name = lambda r: _label(r.backend, r.variant)  # noqa: E731
    batch = (rows[0][2].params or {}).get("batch")
    text = f"A long loop: {n} steps, hard contact, float32, batch {batch}."
    figs = [_Fig(name(r), cast(float, t), ci[id(r)]) for t, _, r in timed]
    top = ranking.tie(figs)            # one-process figures: a best only where separated (the matrix's rule)
    fastest = (f"fastest: {name(timed[0][2])} ({fmt.seconds(timed[0][0])} per loss + gradient)" if len(top) <= 1
               else f"fastest: a tie of {', '.join(top)} ({ranking.why_tied(figs[0], [f for f in figs[1:] if f.framework in top])})")
    parts = ([fastest] if timed else []) \
        + ([f"least device memory: {name(small[0][2])} ({fmt.nbytes(small[0][1])})"] if small else [])
    if parts:
        joined = "; ".join(parts)
        text += f" {joined[0].upper()}{joined[1:]}."
    return [H(f"A long loop ({n} steps): time and memory"), P(f"**{text}**"),
            Table(("framework", "variant", "time per call", "device memory", "gradients agreeing with FD"),
                  tuple((r.backend, r.variant, fmt.seconds(t), fmt.nbytes(m),
                         fmt.pct(r.fd_agreement))
                        for t, m, r in sorted(rows, key=lambda x: (x[0] is None, x[0] or 0.0))))]
