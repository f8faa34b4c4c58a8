"""This machine against a reference machine (``compare site MINE --against REFERENCE``).

Cells are matched by their full identity (scenario, framework, device, precision, variant,
parameters, and a sweep's tags), run-suite and sweep-suite records separately, the last record
of each identity. Per matched cell and per regime both measured: the ratio this / reference of
the per-call time, called "within spread" when the two quartile ranges overlap (the difference
lies inside both runs' own spread), else faster or slower. Cells whose status changed (ok on one
side only) follow, one row per framework and cause. Beside them, the two environments side by
side, differences marked.
"""
from __future__ import annotations

import dataclasses
import math
import os
import statistics
from pathlib import Path
from typing import Any, Iterable, Mapping

from compare.render import charts
from compare.results.record import Record
from compare.site import data, floors, fmt, provenance
from compare.site.data import Machine, Timing
from compare.site.questions_pages import Ctx
from compare.site.render import Block, Figure, H, Items, P, Table

DIFF_MARK = "≠"
WITHIN, FASTER, SLOWER = "within spread", "faster", "slower"
FLOORS = "in units of each run's own launch floor"     # the unit that travels (site/data.floors)
SUITES = ("run", "sweep")
COMMAND = "python -m compare site MINE --out REPORT --against REFERENCE"


# ---- the environments -------------------------------------------------------------------------
def _distinct(values: Iterable[Any]) -> str:
    """Every distinct value, in first-seen order ('-' when none): several runs may differ."""
    seen: list[str] = []
    for v in values:
        if v not in (None, "") and str(v) not in seen:
            seen.append(str(v))
    return ", ".join(seen) or "-"


def _spread(values: Iterable[float | None], show: Any) -> str:
    """One figure, or the range over the runs that measured it."""
    vs = sorted(v for v in values if v is not None)
    if not vs:
        return "-"
    return show(vs[0]) if show(vs[0]) == show(vs[-1]) else f"{show(vs[0])} – {show(vs[-1])} ({len(vs)} runs)"


def _gpus(m: Machine, what: str) -> str:
    return _distinct(g.get(what) for e in m.runs for g in e.get("gpus") or [] if isinstance(g, dict))


def _yard(m: Machine, device: str, what: str) -> list[float | None]:
    return [data.num(((e.get("hardware") or {}).get(device) or {}).get(what)) for e in m.runs]


def _env_rows(m: Machine) -> dict[str, str]:
    envs = m.runs
    rows = {"GPU": _gpus(m, "name") if _gpus(m, "name") != "-" else "none",
            "GPU driver": _gpus(m, "driver"),
            "CPU": _distinct(e.get("cpu") for e in envs),
            "cores": _distinct(e.get("cores") for e in envs),
            "memory": _distinct(f"{e['memory_gib']} GiB" for e in envs if e.get("memory_gib")),
            "OS": _distinct(e.get("os") for e in envs),
            "Python": _distinct(e.get("python") for e in envs),
            "CUDA toolkit": _distinct(e.get("cuda_toolkit") for e in envs),
            "commits": _distinct(provenance.short(e.get("git_commit")) + (" (dirty)" if e.get("git_dirty") else "")
                                 for e in envs if e.get("git_commit"))}
    load = host_load(m)
    rows["host load while timing (1-min average, median over cells)"] = f"{load:.1f}" if load is not None else "-"
    return rows


def host_load(m: Machine) -> float | None:
    """The median 1-minute host load over the cells timed (None where no record has it)."""
    # a busy host slows every cell alike: the first thing to rule out when all ratios move together
    load = [v for r in m.records if (v := data.num(r.host_load_1m)) is not None]
    return statistics.median(load) if load else None


def _yard_rows(m: Machine, devices: list[str]) -> dict[str, str]:
    rows = {}
    for dev in devices:
        rows[f"copy bandwidth ({dev})"] = _spread(_yard(m, dev, "copy_bytes_per_s"), lambda v: fmt.rate(v, "B/s"))
        rows[f"launch latency ({dev})"] = _spread(_yard(m, dev, "launch_latency_s"), fmt.seconds)
        rows[f"launch pipelined ({dev})"] = _spread(_yard(m, dev, "launch_pipelined_s"), fmt.seconds)
    return rows


def _packages(m: Machine) -> dict[str, str]:
    seen: dict[str, list[Any]] = {}
    for env in m.runs:
        for k, v in (env.get("packages") or {}).items():
            seen.setdefault(k, []).append(v)
    return {k: _distinct(vs) for k, vs in seen.items()}


def _side_by_side(mine: dict[str, str], ref: dict[str, str], what: str) -> Table:
    """Both machines' values, a differing one in bold with a mark (missing on one side: '-')."""
    rows = []
    for k in list(mine) + [k for k in ref if k not in mine]:
        a, b = mine.get(k, "-"), ref.get(k, "-")
        if a == b == "-":                  # neither side has it (a GPU driver on two CPUs)
            continue
        differ = a != b
        rows.append((k, f"**{a}**" if differ else a, f"**{b}**" if differ else b, DIFF_MARK if differ else ""))
    return Table((what, "this run", "reference", DIFF_MARK), tuple(rows))


def environments(m: Machine, ref: Machine) -> list[Block]:
    devices = sorted({d for x in (m, ref) for e in x.runs for d in (e.get("hardware") or {})},
                     key=lambda d: (d != "cuda", d != "cpu", d))
    yard_m, yard_r = _yard_rows(m, devices), _yard_rows(ref, devices)
    pk_m, pk_r = _packages(m), _packages(ref)
    differ = sorted(k for k in set(pk_m) | set(pk_r) if pk_m.get(k, "-") != pk_r.get(k, "-"))
    return [H("The two environments", "environments"),
            P(f"Rows marked {DIFF_MARK} differ (a value listed with commas: the runs of that side "
              "differ among themselves). The yardsticks are measured by each run with no framework "
              "involved: a machine's copy bandwidth and launch cost bound what any framework can reach."),
            _side_by_side({**_env_rows(m), **yard_m}, {**_env_rows(ref), **yard_r}, "machine"),
            P(f"Package versions: {len(differ)} of {len(set(pk_m) | set(pk_r))} differ"
              + (f" ({', '.join(differ)})." if differ else ".")),
            _side_by_side(dict(sorted(pk_m.items())), dict(sorted(pk_r.items())), "package")]


# ---- matching cells ---------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Compared:
    """One regime of one matched cell, both sides ok and timed."""
    suite: str
    rec: Record
    mine: Timing
    ref: Timing
    regime: str
    there: Record | None = None         # the reference's record of the cell (its run's yardstick)

    @property
    def ratio(self) -> float:
        return self.mine.median / self.ref.median

    @property
    def floor_ratio(self) -> float | None:
        """The ratio in each side's launch floors (``data.floors``: its cell's own or its run's); None without both."""
        a = data.floors(self.rec, self.regime, self.mine)
        b = data.floors(self.there, self.regime, self.ref) if self.there is not None else None
        return a / b if a is not None and b else None

    @property
    def verdict(self) -> str:
        if self.mine.lo <= self.ref.hi and self.ref.lo <= self.mine.hi:
            return WITHIN
        return FASTER if self.mine.median < self.ref.median else SLOWER


def _cells(m: Machine) -> dict[tuple[str, str], Record]:
    """(suite, identity) -> the last record of that identity."""
    out: dict[tuple[str, str], Record] = {}
    for suite, recs in (("run", m.run), ("sweep", m.sweep)):
        for r in recs:
            out[(suite, r.key)] = r
    return out


@dataclasses.dataclass
class Matching:
    compared: list[Compared]
    changed: list[tuple[str, Record, Record]]        # (suite, mine, reference): ok on one side only
    matched: int
    both_failed: int
    untimed: int                                      # both ok, no regime in common
    only_mine: list[Record]
    only_ref: list[Record]


def match(m: Machine, ref: Machine) -> Matching:
    mine, theirs = _cells(m), _cells(ref)
    res = Matching([], [], 0, 0, 0, [r for k, r in mine.items() if k not in theirs],
                   [r for k, r in theirs.items() if k not in mine])
    for k, a in mine.items():
        b = theirs.get(k)
        if b is None:
            continue
        res.matched += 1
        ok_a, ok_b = a.status == "ok", b.status == "ok"
        if ok_a != ok_b:
            res.changed.append((k[0], a, b))
            continue
        if not ok_a:
            res.both_failed += 1
            continue
        per_regime = [(g, data.per_call(a, g), data.per_call(b, g)) for g in data.REGIMES]
        pairs = [(g, ta, tb) for g, ta, tb in per_regime if ta is not None and tb is not None]
        res.compared += [Compared(k[0], a, ta, tb, g, b) for g, ta, tb in pairs]
        res.untimed += not pairs
    res.compared.sort(key=lambda x: (_order(x.rec), data.REGIMES.index(x.regime)))
    res.changed.sort(key=lambda x: _order(x[1]))
    return res


def _order(r: Record) -> tuple[Any, ...]:
    return (r.device != "cuda", r.device, r.scenario, SUITES.index("sweep" if r.tags else "run"),
            _tags_text(r), data.size(r), r.backend, r.variant, r.precision)


def _tags_text(r: Record) -> str:
    t = r.tags or {}
    knob = t.get("knob") if isinstance(t.get("knob"), Mapping) else None
    if "sweep" in t:
        return f"{t['sweep']} sweep" + (f", {knob.get('name')}={knob.get('value')}" if knob else "")
    return ", ".join(f"{k}={v}" for k, v in sorted(t.items())) if t else ""


def _where(r: Record) -> str:
    """The cell's parameters (those off the defaults) and, for a sweep record, its sweep."""
    p = fmt.params_text(r.params or {}, data.defaults(r.scenario))
    return p + (f"; {_tags_text(r)}" if r.tags else "")


def _scenarios(recs: list[Record]) -> str:
    return ", ".join(sorted({r.scenario for r in recs})) or "-"


# ---- the page ---------------------------------------------------------------------------------
def _geo(values: list[float]) -> float:
    return math.exp(sum(math.log(v) for v in values) / len(values))


def yardstick_line(m: Machine, ref: Machine, devices: Iterable[str]) -> str:
    """How far apart the machines are before any framework: the same-run copy yardstick."""
    parts = []
    for dev in devices:
        a = [v for v in _yard(m, dev, "copy_bytes_per_s") if v]
        b = [v for v in _yard(ref, dev, "copy_bytes_per_s") if v]
        if a and b:
            ma, mb = statistics.median(a), statistics.median(b)
            same = 0.95 < mb / ma < 1.05
            parts.append(f"on {dev} this run copies at {fmt.rate(ma, 'B/s')}, the reference at "
                         f"{fmt.rate(mb, 'B/s')} (same-run copy yardstick, medians over runs)"
                         + ("" if same else f": a byte takes {fmt.ratio(mb / ma)} the reference's time "
                            "here, and a bandwidth-bound cell may differ by as much for that alone"))
    la, lb = host_load(m), host_load(ref)
    if la is not None and lb is not None:
        parts.append(f"the host's load while timing (1-min average, median over cells) was {la:.1f} here "
                     f"and {lb:.1f} on the reference"
                     + (" (a busy host slows every cell)" if abs(la - lb) >= 1 else ""))
    return ("Before any framework: " + "; ".join(parts) + ".") if parts else ""


def summary(mm: Matching) -> list[Block]:
    cs = mm.compared
    n = len(cs)
    count = {v: sum(c.verdict == v for c in cs) for v in (WITHIN, FASTER, SLOWER)}
    lines = [f"**{mm.matched} cells matched** ({len({id(c.rec) for c in cs})} compared in {n} "
             f"cell-regime pairs): **{count[WITHIN]} within spread**, {count[FASTER]} faster here, "
             f"{count[SLOWER]} slower here."]
    for dev in sorted({c.rec.device for c in cs}, key=lambda d: (d != "cuda", d)):
        on = [c for c in cs if c.rec.device == dev]
        per = [f"{g} {fmt.ratio(statistics.median(c.ratio for c in on if c.regime == g))}"
               for g in data.REGIMES if any(c.regime == g for c in on)]
        fl = [f for c in on if (f := c.floor_ratio) is not None]
        lines.append(f"Median ratio on {dev}: **{fmt.ratio(statistics.median(c.ratio for c in on))}** "
                     f"over {len(on)} pairs ({'; '.join(per)})." + (
                         f" {FLOORS.capitalize()}: **{fmt.ratio(statistics.median(fl))}** over the {len(fl)} "
                         f"latency and pipelined pairs with both yardsticks{floors.count(on)}." if fl else ""))
    if mm.changed:
        lines.append(f"**{_n(len(mm.changed), 'cell')} changed status** (listed after the matched cells).")
    skipped = [f"{_n(k, 'cell')} {why}" for k, why in ((mm.both_failed, "failed or skipped on both sides"),
                                                       (mm.untimed, "without a timed regime in common")) if k]
    if skipped:
        lines.append("Not compared: " + ", ".join(skipped) + ".")
    lines.append(_only(mm))
    return [Items(tuple(lines))]


def _only(mm: Matching) -> str:
    return (f"Cells on one side only (not listed): {len(mm.only_mine)} only in this run "
            f"({_scenarios(mm.only_mine)}), {len(mm.only_ref)} only in the reference "
            f"({_scenarios(mm.only_ref)}).")


def _n(k: int, word: str) -> str:
    return f"{k} {word}{'' if k == 1 else 's'}"


def figure(c: Ctx, mm: Matching) -> list[Block]:
    """Per framework and variant, the geometric mean of its ratios over the default-size cells
    (float32 and float64, every scenario), one panel per device and regime."""
    default = [x for x in mm.compared if data.at_defaults(x.rec) and x.suite == "run"]
    f32 = [x for x in default if x.rec.precision == "float32"]
    # float32 alone where it ran: one bar mixing precisions would hide which one moved
    cs, scope = f32, "the default-size float32 cells"
    if not cs:
        cs, scope = (default, "the default-size cells") if default else (mm.compared, "every matched cell")
    groups: dict[tuple[str, str], dict[tuple[str, str], list[Compared]]] = {}
    for x in cs:
        groups.setdefault((x.rec.device, x.regime), {}).setdefault(
            (x.rec.backend, x.rec.variant), []).append(x)
    panels = []
    for (dev, g), by_fw in sorted(groups.items(), key=lambda kv: (kv[0][0] != "cuda", kv[0][0],
                                                                  data.REGIMES.index(kv[0][1]))):
        bars = []
        for (fw, var), xs in by_fw.items():
            lo = _geo([x.mine.lo / x.ref.hi for x in xs]) if all(x.mine.lo > 0 for x in xs) else None
            hi = _geo([x.mine.hi / x.ref.lo for x in xs]) if all(x.ref.lo > 0 for x in xs) else None
            inside = sum(x.verdict == WITHIN for x in xs)
            bars.append(charts.Bar(fw, var, _geo([x.ratio for x in xs]), lo, hi, f"{inside}/{len(xs)} within spread"))
        panels.append(charts.Panel(f"{dev}, {g}", bars))
    png, rel, csv = c.fig("against-ratio")
    charts.bar_panels(png, "Per-call time, this run / the reference",
                      "ratio of per-call times, log scale (below 1: faster here; whiskers: quartiles "
                      "against quartiles)", panels, log=True, fmt=fmt.ratio,
                      reference=(1.0, "as fast as the reference"))
    return [Figure(rel, f"Ratio per framework and variant over {scope}: the geometric mean of this "
                   "run's per-call time over the reference's, one panel per device and regime; "
                   "a bar left of the line is faster here.", COMMAND, csv)]


def _status_text(r: Record) -> str:
    return r.status if r.status == "ok" else f"{r.status}: {r.reason[:120]}"


def _cell_words(r: Record) -> tuple[str, ...]:
    return (r.device, r.scenario, r.backend, r.variant, r.precision, _where(r))


def _changed_rows(mm: Matching) -> tuple[tuple[str, ...], ...]:
    """The status changes folded: one row per device, framework, variant and the two statuses
    (a framework not installed on one side is one row, not one per cell)."""
    groups: dict[tuple[str, ...], list[Record]] = {}
    for _, a, b in mm.changed:
        groups.setdefault((a.device, a.backend, a.variant, _status_text(a), _status_text(b)), []).append(a)
    return tuple((dev, fw, var, f"{len(recs)}: " + ", ".join(dict.fromkeys(
                      f"{r.scenario} {r.precision}" + (f" ({_where(r)})" if _where(r) != "defaults" else "")
                      for r in recs)), mine, ref)
                 for (dev, fw, var, mine, ref), recs in groups.items())


def tables(mm: Matching) -> list[Block]:
    """Every matched cell first (what a reader came for), then the status changes, folded."""
    blocks: list[Block] = []
    rows = []
    for x in mm.compared:
        noisy = (fmt.NOISY_MARK if x.mine.noisy else "", fmt.NOISY_MARK if x.ref.noisy else "")
        rows.append((*_cell_words(x.rec), x.regime,
                     fmt.seconds(x.mine.median) + noisy[0], fmt.seconds(x.ref.median) + noisy[1],
                     fmt.ratio(x.ratio), fmt.ratio(f) + floors.mark(x) if (f := x.floor_ratio) is not None else "-",
                     x.verdict))
    if rows:
        blocks += [H("Every matched cell", "cells"),
                   P("Per-call time in each regime both runs measured; ratio = this run / reference "
                     f"(below 1: faster here); in floors: the same {FLOORS}{floors.note(mm.compared)}. "
                     f"{WITHIN.capitalize()}: the two quartile ranges overlap. "
                     f"{fmt.NOISY_MARK} marks a noisy figure (wide spread, few repeats or a busy host). Click a "
                     "header to sort."),
                   Table(("device", "scenario", "framework", "variant", "precision", "parameters", "regime",
                          "this run", "reference", "ratio", "in floors", "verdict"), tuple(rows))]
    if mm.changed:
        blocks += [H("Status changes", "status"),
                   P("Cells ok on one side and failed, mismatched or skipped on the other, one row per "
                     "framework, variant and pair of statuses (its cells: scenario and precision)."),
                   Table(("device", "framework", "variant", "cells", "this run", "reference"), _changed_rows(mm))]
    return blocks


def _sources(m: Machine) -> str:
    def rel(p: Path) -> str:
        try:
            r = os.path.relpath(p)
        except ValueError:
            return str(p)
        return r if not r.startswith("..") else str(Path(p).resolve())
    return ", ".join(f"`{rel(p)}`" for p in m.sources)


def page(c: Ctx, ref: Machine) -> list[Block]:
    mm = match(c.m, ref)
    blocks: list[Block] = [
        P(f"This run: {c.m.name()} ({_sources(c.m)}). Reference: {ref.name()} ({_sources(ref)}). "
          "Each cell both ran (same scenario, framework, device, precision, variant and parameters) "
          "is compared by its per-call time; a ratio below 1 means this machine is faster. "
          "A difference inside both runs' quartile ranges is called within spread: "
          "it is not a difference the runs can tell apart.")]
    if not mm.matched:
        blocks += [H("Nothing in common", "summary"),
                   P(f"**No cell of this run matches one of the reference's**, so there is nothing to "
                     f"compare cell by cell. This run holds {len(mm.only_mine)} cells "
                     f"({_scenarios(mm.only_mine)}), the reference {len(mm.only_ref)} "
                     f"({_scenarios(mm.only_ref)}); a cell matches only at the same device, precision, "
                     "variant and parameters. Rerun the reference's cells here (its commands are on its "
                     "machine page) to compare them. The environments are still compared below.")]
    else:
        yard = yardstick_line(c.m, ref, sorted({x.rec.device for x in mm.compared}))
        blocks += [H("Summary", "summary"), *summary(mm), *([P(yard)] if yard else [])]
        if mm.compared:
            blocks += figure(c, mm)
        blocks += tables(mm)
    return blocks + environments(c.m, ref)
