"""The recommendation matrix: one row per user question, one column per framework.

Each row is a ``Rule``: the records it reads (scenario, device, precision, sizes), the figure it
compares (a per-call time, a rate, device memory, an error, a time to first result) and which
way is better. A framework's cell is its best figure over its variants (named), as a ratio to
the row's leader (2.0: twice as slow, half the rate, twice the memory). A row names a best only
where the leader is separated from the runner-up (compare/site/ranking.py), else a tie. A rule
may set cells apart as a reference (hand-written adjoints beside automatic differentiation):
shown, never ranked. The rule's text is printed beside the row; each verdict is derived here.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Callable, cast

import backends
from backends.base import DEFAULT_VARIANT
import scenarios
from compare.render import colors
from compare.results.record import Record
from compare.site import data, provenance, ranking
from compare.site.data import Machine, Timing
from scenarios.base import Precision

NOT_SAME_WORK = backends.base.UNRANKED_VARIANTS     # change the arithmetic: never ranked, shown
FAST_REASON = "ran with fast math (its former default): shown on the page, never ranked"
VARIANT_RULE = ("each framework's fastest variant: IEEE arithmetic only (fast-math variants shown, never ranked); "
                "every launch path the user writes counts (Warp record_cmd, torch.compile modes, XLA command buffers, "
                "a CUDA graph the port captures), the harness's replay of a captured call only on the graph-replay row")


@dataclasses.dataclass(frozen=True)
class Cell:
    framework: str
    value: float | None           # the figure, in the row's unit; None when not ok or not measured
    lo: float | None = None       # spread (quartiles) where timed
    hi: float | None = None
    variant: str = ""
    status: str = "absent"        # ok | mismatch | error | skipped | absent (no such record)
    reason: str = ""
    noisy: str = ""
    ratio: float | None = None    # to the row's leader: >= 1 for ranked cells, 1 is the leader
    ci: tuple[float, float] | None = None    # the median's 95 % interval across processes
    processes: int = 1
    tied: bool = False            # shares the top of the row (the best, or tied with it)
    reference: bool = False       # set apart by the rule (a hand adjoint): shown, never ranked
    default_value: float | None = None   # the default variant's figure, where another variant won
    default_ratio: float | None = None   # ... and its ratio to the row's leader
    why: str = ""                 # a far ratio's reason, read from its records (site/pages_why.py)
    untimed: tuple[str, ...] = ()   # its variants never timed at the row's point (site/untimed.py)

    @property
    def winner_not_default(self) -> bool:   # the plain call gets the default's figure instead
        return self.value is not None and self.variant not in ("", "default")

    @property
    def band(self) -> str:
        if self.ratio is None:
            return "none"
        if self.reference:
            return "ref"
        if self.tied:
            return "best"
        # ranked bands by their upper bound (compare.render.colors.BANDS); beyond the last: "poor"
        return next((b.name for b in colors.BANDS if b.bound and self.ratio <= b.bound), "poor")


@dataclasses.dataclass(frozen=True)
class Reference:
    """Cells a rule shows beside its ranking but never ranks: which records, and in words."""
    test: Callable[[Record], bool]    # the record is a reference
    ranked: str                       # what the row ranks, e.g. 'AD'
    what: str                         # the reference cells in words, e.g. 'Hand-written adjoints'

    def words(self, ahead: bool) -> str:
        """The verdict's name for them: a ceiling only where all of them lead the ranking."""
        return f"{self.what} ({'reference ceiling' if ahead else 'reference'}, not {self.ranked})"


@dataclasses.dataclass(frozen=True)
class Rule:
    key: str                      # stable id; also the anchor on its page
    question: str                 # the row's label in the matrix
    page: str                     # the page (stem) that answers it in full
    unit: str                     # 's', 'B', '1/s', 'x' (a plain ratio)
    better: str                   # 'lower' | 'higher'
    text: str                     # the rule in words, printed on the pages
    pick: Callable[[Machine, str], list[Record]]     # the records the row reads
    figure: Callable[[Record], Timing | float | None]  # one record's figure
    device: str = ""              # '' the report's device; else this one
    exact: bool = False           # deterministic figures (bytes, error shares): no interval needed
    reference: Reference | None = None    # cells shown beside the ranking, never in it
    cells: Callable[[Machine, str], dict[str, "Cell"]] | None = None   # a row's own cell builder
    repeated: str = ""            # ranks only figures with a 95 % interval: the command that repeats them


@dataclasses.dataclass(frozen=True)
class Row:
    rule: Rule
    device: str
    cells: dict[str, Cell]
    top: str | None               # the leading figure's framework: the ratios' reference
    tied: tuple[str, ...]         # who shares the top, the leader first: (top,) when separated
    verdict: str
    scope: str                    # the sizes the row ended up reading, in words
    runs: tuple[str, ...] = ()    # the runs its figures come from (compare.site.provenance)

    @property
    def best(self) -> str | None:
        """The one best framework, only where it is separated from every other ranked one."""
        return self.top if len(self.tied) == 1 else None

    def best_text(self) -> str:
        """The matrix's last column: the best, ``tie: a, b, c`` (``tie: a, b +4``) or ``—``."""
        if self.top is None:
            return "—"
        if not self.tied:       # figures from several runs, unstamped ones, an uncommitted tree: never ranked
            if provenance.one_run(self.runs):       # ... nor one run's figures that a rule needs repeated
                return f"— ({ranking.bare([c for c in self.cells.values() if not c.reference])})"
            return f"— ({provenance.mark(self.runs)})"
        return self.tied[0] if len(self.tied) == 1 else f"tie: {ranking.shorten(self.tied)}"


# ---- record selection -------------------------------------------------------------------------
def latest(recs: list[Record]) -> list[Record]:
    """One record per framework, variant and size: an exact one timed in the most processes, else
    the last stored; a parameter an older record lacks is read at its default (projectile's batch)."""
    seen: dict[tuple[Any, ...], Record] = {}
    for r in recs:
        d = data.defaults(r.scenario)
        full = r if all(k in (r.params or {}) for k in d) else r.replace(params={**d, **(r.params or {})})
        k = (r.backend, r.scenario, r.device, r.precision, r.variant, data.size(full), data.at_defaults(r))
        rank = (exact(r), data.process_count(r))
        seen[k] = r if k not in seen or rank >= (exact(seen[k]), data.process_count(seen[k])) else seen[k]
    return list(seen.values())


def one_run(recs: list[Record]) -> list[Record]:
    """One record per cell, from one run where one measured every framework (provenance.one_run_of)."""
    return latest(provenance.one_run_of(recs, exact, data.process_count))


def exact(r: Record) -> bool:
    """IEEE arithmetic: not a fast-math variant nor a record its backend says ran fast math
    (Dr.Jit's float32 cells before its exact default): shown on the pages, never ranked."""
    if r.variant in NOT_SAME_WORK:
        return False
    be = backends.BACKENDS.get(r.backend, backends.Backend())
    return not be.ran_fast_math(r.precision, r.info)


def _pool(m: Machine, device: str, scenario: str, precision: Precision = Precision.FLOAT32,
          sweep: tuple[str | None, ...] = (None, "bandwidth", "scaling"),
          keep: Callable[[Record], bool] = lambda r: True) -> list[Record]:
    return [r for r in m.records if r.device == device and r.scenario == scenario
            and r.precision == precision and data.tag(r, "sweep") in sweep
            and (exact(r) or r.variant == DEFAULT_VARIANT) and keep(r)]


def _largest(recs: list[Record]) -> list[Record]:
    """The records at the largest size that at least two frameworks ran ok (else any)."""
    sizes: dict[float, set[str]] = {}
    for r in recs:
        if r.status == "ok":
            sizes.setdefault(data.size(r), set()).add(r.backend)
    good = [s for s, bs in sizes.items() if len(bs) >= 2] or list(sizes)
    if not good:
        return []
    top = max(good)
    return [r for r in recs if data.size(r) == top]


def defaults_of(scenario: str, precision: Precision = Precision.FLOAT32) -> Callable[[Machine, str], list[Record]]:
    def pick(m: Machine, device: str) -> list[Record]:
        return one_run([r for r in _pool(m, device, scenario, precision, (None,)) if data.at_defaults(r)])
    return pick


def largest_of(scenario: str, sweep: tuple[str | None, ...] = (None, "bandwidth", "scaling"),
               keep: Callable[[Record], bool] = lambda r: True) -> Callable[[Machine, str], list[Record]]:
    def pick(m: Machine, device: str) -> list[Record]:
        return one_run(_largest(_pool(m, device, scenario, Precision.FLOAT32, sweep, keep)))
    return pick


def all_defaults(m: Machine, device: str) -> list[Record]:
    return one_run([r for r in m.run if r.device == device and r.precision == "float32"
                    and r.variant == backends.base.DEFAULT_VARIANT and data.at_defaults(r) and exact(r)
                    and data.tag(r, "sweep") is None])


# ---- row figures ------------------------------------------------------------------------------
def regime(name: str) -> Callable[[Record], Timing | None]:
    return lambda r: data.per_call(r, name)


def rate(r: Record) -> Timing | None:
    """Work items per second, carrying its timing's quartiles and interval through work / time
    (so the rate is separated as the timing it comes from)."""
    v = data.item_rate(r)
    t = data.per_call(r, "throughput") or data.timing(r, "latency")
    if v is None or t is None:
        return None
    work = v * t.median
    ci = (work / t.ci[1], work / t.ci[0]) if t.ci else None
    return Timing(v, work / t.hi, work / t.lo if t.lo > 0 else v, t.repeats, "", t.processes, ci)


class NotComparable(ValueError):
    """A framework's records give no figure this row can compare (the message says why)."""


ERROR_FLOOR = 1e-3                # a share of the bound below this counts as this (exact results)


def error_share(r: Record) -> float | None:
    """A record's error against the float64 oracle as a share of its derived tolerance."""
    e = r.error
    err, tol = (data.num(e.vs_oracle), data.num(e.tolerance)) if e else (None, None)
    return err / tol if err is not None and tol else None


def _error_geomean(recs: list[Record]) -> float | None:
    shares = [error_share(r) for r in recs]
    known = [s for s in shares if s is not None]
    if not shares or len(known) < len(shares):       # some record has no error share
        return None
    return math.exp(sum(math.log(max(s, ERROR_FLOOR)) for s in known) / len(known))


def _sum_first(recs: list[Record]) -> Timing | None:
    """The sum over the scenarios of the time to first result (set-up + first call); its
    interval, where every part has one, is the sum of the ends (wider than the sum's own)."""
    ts = []
    for r in recs:
        t = data.first_result(r)
        if t is None:
            raise NotComparable(f"{r.scenario}: no set-up time (time.setup_s) in its record, so no "
                                "time to first result")
        ts.append(t)
    if not ts:
        return None
    v = sum(t.median for t in ts)
    cis = [t.ci for t in ts if t.ci]
    ci = (sum(c[0] for c in cis), sum(c[1] for c in cis)) if len(cis) == len(ts) else None
    return Timing(v, v, v, None, "", min(t.processes for t in ts), ci)


# Per-framework aggregates over several scenarios: (records of one framework) -> figure, or
# NotComparable with the reason.
AGGREGATES: dict[str, Callable[[list[Record]], Timing | float | None]] = {
    "accuracy": _error_geomean, "compile": _sum_first}
IN_ALL = tuple(n for n, sc in scenarios.SCENARIOS.items() if sc.in_all)   # the scenarios of `all`


def _geomean_vs_best(m: Machine, device: str, regime: str = "throughput") -> dict[str, Cell]:
    """CPU-only use (the busy row too, on its records, in ``regime``): per framework, the geometric
    mean over the scenarios of its ``regime`` time divided by the fastest framework's on that scenario."""
    recs = all_defaults(m, device)
    best: dict[str, float] = {}
    times: dict[tuple[str, str], float] = {}
    for r in recs:
        t = data.per_call(r, regime) if r.status == "ok" else None
        if t is not None:
            times[(r.backend, r.scenario)] = t.median
            best[r.scenario] = min(best.get(r.scenario, math.inf), t.median)
    cells = {}
    for fw in sorted({r.backend for r in recs}):
        mine = {r.scenario: r for r in recs if r.backend == fw}
        bad = next((r for r in mine.values() if r.status != "ok"), None)
        if bad is not None or any(s not in mine for s in best):
            cells[fw] = Cell(fw, None, status=bad.status if bad else "absent",
                             reason=(bad.reason if bad else "") or "not every scenario measured")
            continue
        logs = [math.log(times[(fw, s)] / best[s]) for s in best if (fw, s) in times]
        if len(logs) != len(best):
            cells[fw] = Cell(fw, None, status="absent", reason="a scenario has no timing")
            continue
        cells[fw] = Cell(fw, math.exp(sum(logs) / len(logs)), status="ok", variant="default")
    return cells


def _cell(fw: str, fig: Timing | float, variant: str, reference: bool = False) -> Cell:
    if isinstance(fig, Timing):
        return Cell(fw, fig.median, fig.lo, fig.hi, variant, "ok", "", fig.noisy,
                    ci=fig.ci, processes=fig.processes, reference=reference)
    return Cell(fw, fig, variant=variant, status="ok", reference=reference)


def _aggregate(rule: Rule, recs: list[Record]) -> dict[str, Cell]:
    cells: dict[str, Cell] = {}
    for fw in sorted({r.backend for r in recs}):
        mine = [r for r in recs if r.backend == fw]
        bad = next((r for r in mine if r.status != "ok"), None)
        missing = {r.scenario for r in recs} - {r.scenario for r in mine}
        why = (bad.reason if bad else "") or "not every scenario measured"
        fig = None
        if not bad and not missing:
            try:
                fig = AGGREGATES[rule.key](mine)
            except NotComparable as exc:
                why = str(exc)
        cells[fw] = _cell(fw, fig, "default") if fig is not None else \
            Cell(fw, None, status=bad.status if bad else "absent", reason=why, variant="default")
    return cells


def _cells(rule: Rule, m: Machine, device: str) -> dict[str, Cell]:
    if rule.cells is not None:
        return rule.cells(m, device)
    if rule.key == "cpu":
        return _geomean_vs_best(m, device)
    recs = rule.pick(m, device)
    if rule.key in AGGREGATES:
        return _aggregate(rule, recs)
    cells: dict[str, Cell] = {}
    plain: dict[str, float] = {}     # each framework's default-variant figure
    for r in recs:
        fw = r.backend
        fig = rule.figure(r) if r.status == "ok" and exact(r) else None
        val = fig.median if isinstance(fig, Timing) else fig
        if val is not None and r.variant == DEFAULT_VARIANT:
            plain[fw] = val
        if fig is None or val is None:
            if fw not in cells:      # keep why a framework has no figure, unless it has one
                cells[fw] = Cell(fw, None, status=r.status if r.status != "ok" else "absent",
                                 reason=r.reason or ("no figure of this kind in its record" if exact(r)
                                                     else FAST_REASON))
            continue
        cur = cells.get(fw)
        better = cur is None or cur.value is None or (
            val < cur.value if rule.better == "lower" else val > cur.value)
        if better:
            cells[fw] = _cell(fw, fig, r.variant, rule.reference is not None and rule.reference.test(r))
    return {fw: dataclasses.replace(c, default_value=plain.get(fw)) if c.winner_not_default else c
            for fw, c in cells.items()}


def _verdict(rule: Rule, cells: dict[str, Cell], top: str | None, tied: tuple[str, ...],
             fmt: Callable[[float, str], str]) -> str:
    if top is None:
        return "No framework has a figure for this row in these records."
    lead = cells[top]
    lead_value = cast(float, lead.value)    # evaluate picks top among the cells with a value
    ranked = sorted((c for c in cells.values() if c.ratio is not None and not c.reference),
                    key=lambda c: c.ratio or 0.0)
    best = f"Best {rule.reference.ranked}" if rule.reference else "Best"
    if len(tied) > 1:
        among = f" among {rule.reference.ranked}" if rule.reference else ""
        why = ranking.why_tied(lead, [cells[f] for f in tied[1:]], rule.exact)
        text = (f"Tie{among}: {', '.join(tied)} (not separated from {top}'s "
                f"{fmt(lead_value, rule.unit)}: {why}).")
    elif len(ranked) > 1:
        runner = ranked[1]
        sep = ranking.separated(lead, runner, rule.exact)
        text = f"{best}: {top} ({fmt(lead_value, rule.unit)}), separated from {runner.framework} ({sep.words()})."
    else:
        text = f"{best}: {top} ({fmt(lead_value, rule.unit)}), the only one measured."
    refs = sorted((c for c in cells.values() if c.reference and c.ratio is not None), key=lambda c: c.ratio or 0.0)
    if rule.reference and refs:
        text += (f" {rule.reference.words(all((c.ratio or 1.0) < 1 for c in refs))}: " + "; ".join(
            f"{c.framework} {ranking.than(c.ratio or 1.0, rule.unit)}" + (f" than {top}" if i == 0 else "")
            for i, c in enumerate(refs)) + ".")
    failed = [c.framework for c in cells.values() if c.status in ("error", "mismatch")]
    if failed:
        text += f" Failed: {', '.join(failed)}."
    noisy = [c.framework for c in cells.values() if c.noisy]
    if noisy:
        text += f" Noisy: {', '.join(noisy)}."
    return text


def evaluate(rule: Rule, m: Machine, fmt: Callable[[float, str], str]) -> Row:
    device = rule.device or m.primary_device
    cells = _cells(rule, m, device)
    values = {f: c.value for f, c in cells.items() if c.value is not None and c.value > 0 and not c.reference}
    top = (min if rule.better == "lower" else max)(values, key=lambda f: values[f]) if values else None
    tied: tuple[str, ...] = ()
    if top is not None:
        b = values[top]

        def to_top(v: float | None) -> float | None:
            return (v / b if rule.better == "lower" else b / v) if v is not None and v > 0 else None
        cells = {f: dataclasses.replace(c, ratio=to_top(c.value), default_ratio=to_top(c.default_value))
                 for f, c in cells.items()}
        ranked = sorted((cells[f] for f in values), key=lambda c: (c.ratio, c.framework != top))
        tied = ranking.tie(ranked, rule.exact)
        cells = {f: dataclasses.replace(c, tied=f in tied) for f, c in cells.items()}
    recs = rule.pick(m, device) if rule.key != "cpu" else all_defaults(m, device)
    runs = provenance.runs_of(r for r in recs if r.status == "ok")
    verdict = _verdict(rule, cells, top, tied, fmt)
    unranked = provenance.words(runs) if not provenance.one_run(runs) else \
        ranking.unrepeated([c for c in cells.values() if not c.reference], rule.repeated)
    if unranked and top is not None:     # never ranked across runs, nor unrepeated where the rule needs repeats
        tied, cells = (), {f: dataclasses.replace(c, tied=False) for f, c in cells.items()}
        verdict = f"{unranked} Leading figure: {top} ({fmt(values[top], rule.unit)})."
    return Row(rule, device, cells, top, tied, verdict, data.scope(recs), runs)

