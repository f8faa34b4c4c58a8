"""The CPU on a shared host: each framework's cells timed again while other processes keep cores
busy (``compare run --busy N``: a laptop or a CI runner is rarely idle), against the same cell
idle in the same run.

The row ranks what a user on a shared host feels, the time under load: per framework, the
geometric mean over the four scenarios (defaults, float32, default variant) of its busy latency
divided by the fastest framework's busy latency on that scenario (matrix._geomean_vs_best on the
busy records: the same scenarios for everyone, a framework missing one is not comparable). Its
slowdown, busy over idle latency (geometric mean), stands beside it on the page, never ranked: a
framework slow when idle may lose little to a busy core and still be slow under load.

The row ranks only figures repeated across processes (the rule's ``repeated``, ranking.unrepeated):
a busy host is the noisiest place to time, and a one-process figure says little of the next process.
Where every busy figure of a framework was timed in several processes (``--busy N --processes K``),
its interval is the geometric mean of the scenarios' interval ends over the same fastest times:
every framework is divided by the same constants, so intervals compare as the busy times do
(wider than the mean's own interval, as the compile row's sum of ends). From one process a cell
(no interval) the row shows its ratios and names no best.

A slowdown below 1 (faster under load) is noise unless the records explain it: each such cell is
shown with its idle and busy medians and spreads, and called WITHIN where the busy median lies
inside the idle figure's quartiles (or interval), explained where the idle cell itself was timed
on a busy host, else UNEXPLAINED. A large slowdown is explained from the cores the cell used
while idle (``time.noise.own_cores``): a loop split over every core waits for its slowest thread,
and with a core taken one thread waits for the other process.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Literal

from compare.results.record import Record
from compare.site import data, fmt, matrix, ranking
from compare.site.matrix import IN_ALL, Cell
from compare.site.render import H, P, Table
from compare.spec import BUSY_TAG

REGIME = "latency"   # one synchronised call: what a user waits for on a shared host
LARGE = 2.0          # a slowdown the page explains
PARALLEL = 1.5       # cores used while idle above this: the cell runs a parallel loop
WITHIN = "within the spread of the idle figure"
UNEXPLAINED = "faster under load: unexplained by the records"
REPEAT = "python -m compare all --devices cpu --precision float32 --busy 1 --processes 6"
INTERVALS = f"`{REPEAT}` times each cell in 6 processes and gives every figure a 95 % interval"

Key = tuple[Any, ...]


def _busy(r: Record) -> int:
    return int((r.tags or {}).get(BUSY_TAG) or 0)


def _ident(r: Record) -> Key:
    return (r.backend, r.scenario, (r.run or {}).get("created"))


def pairs(m: data.Machine, device: str = "cpu") -> list[tuple[Record, Record]]:
    """(idle, busy) records of one cell of the experiment, both of one run: at the defaults,
    float32, default variant, the four scenarios."""
    mine = [r for r in m.busy if (r.device, r.precision, r.variant) == (device, "float32", "default")
            and data.at_defaults(r) and r.scenario in IN_ALL]
    idle = {_ident(r): r for r in mine if _busy(r) == 0}
    return [(idle[_ident(b)], b) for b in mine if _busy(b) > 0 and _ident(b) in idle]


def slowdown(idle: Record, busy: Record) -> float | None:
    a, b = data.timing(idle, REGIME), data.timing(busy, REGIME)
    if idle.status != "ok" or busy.status != "ok" or a is None or b is None:
        return None
    return b.median / a.median


def pick(m: data.Machine, device: str) -> list[Record]:
    return [r for pair in pairs(m, device) for r in pair]


def _under_load(m: data.Machine, device: str) -> tuple[data.Machine, list[tuple[Record, Record]]]:
    """The busy records as a machine of their own (its run suite: what matrix's readers read),
    and the (idle, busy) pairs of the busy records that the row reads (one per framework and scenario)."""
    got = pairs(m, device)
    idle = {_ident(b): i for i, b in got}
    view = dataclasses.replace(m, run=tuple(b for _, b in got), sweep=())
    return view, [(idle[_ident(b)], b) for b in matrix.all_defaults(view, device)]


def _geomean(xs: list[float]) -> float:
    return math.exp(sum(math.log(x) for x in xs) / len(xs))


def _with_interval(c: Cell, busy: list[Record]) -> Cell:
    """The cell with its processes and, where every busy figure has one, its 95 % interval."""
    ts = [data.per_call(r, REGIME) for r in busy]
    if c.value is None or not ts or any(t is None for t in ts):
        return c
    timed = [t for t in ts if t is not None]
    n = min(t.processes for t in timed)
    cis = [t.ci for t in timed if t.ci is not None]
    if len(cis) < len(timed):
        return dataclasses.replace(c, processes=n)
    ci = (c.value * _geomean([lo / t.median for (lo, _), t in zip(cis, timed)]),
          c.value * _geomean([hi / t.median for (_, hi), t in zip(cis, timed)]))
    return dataclasses.replace(c, ci=ci, processes=n)


def cells(m: data.Machine, device: str) -> dict[str, Cell]:
    """The row's cells: each framework's time under load against the fastest busy time per scenario."""
    view, got = _under_load(m, device)
    out = matrix._geomean_vs_best(view, device, REGIME)
    return {fw: _with_interval(c, [b for _, b in got if b.backend == fw]) for fw, c in out.items()}


def slowdowns(m: data.Machine, device: str = "cpu") -> dict[str, float | None]:
    """Each framework's slowdown beside its time under load: the geometric mean over the row's
    scenarios of busy over idle latency (None where a scenario has no pair of figures)."""
    per: dict[str, list[float | None]] = {}
    for idle, busy in _under_load(m, device)[1]:
        per.setdefault(busy.backend, []).append(slowdown(idle, busy))
    return {fw: _geomean([v for v in vs if v is not None]) if vs and None not in vs else None
            for fw, vs in per.items()}


def _cores(r: Record, key: Literal["own_cores", "others_cores"]) -> float | None:
    n = r.time.noise if r.time else None
    return data.num(None if n is None else n.own_cores if key == "own_cores" else n.others_cores)


def faster(idle: Record, busy: Record) -> str:
    """A busy figure below its idle one in words: noise (WITHIN the idle spread), explained by the
    idle cell's own record (timed on a busy host), or UNEXPLAINED; '' where busy is not faster."""
    s = slowdown(idle, busy)
    a, b = data.timing(idle, REGIME), data.timing(busy, REGIME)
    if s is None or s >= 1 or a is None or b is None:
        return ""
    if a.lo <= b.median <= a.hi:
        return WITHIN
    host = next((w for w in a.noisy.split("; ") if w.startswith("host busy")), "")
    return f"faster under load: the idle figure was not idle ({host})" if host else UNEXPLAINED


def why(idle: Record, busy: Record) -> str:
    """A large slowdown in words, from the records: how many cores the cell used idle."""
    s = slowdown(idle, busy)
    own = _cores(idle, "own_cores")
    if s is None or s < LARGE:
        return ""
    if own is not None and own > PARALLEL:
        return (f"uses {own:.1f} cores when idle: a loop split over every core waits for its slowest "
                "thread, and one thread now shares its core with the busy process")
    return f"uses {own:.1f} core when idle: the host's scheduler gave it less than a core" if own is not None else ""


def _spread(t: data.Timing | None) -> str:
    """A median with its spread: the quartiles, or the 95 % interval where processes gave one."""
    if t is None:
        return "-"
    what = f"interval over {t.processes} processes" if t.processes > 1 else "quartiles"
    return f"{fmt.seconds(t.median)} ({what} {fmt.seconds(t.lo)}–{fmt.seconds(t.hi)})"


def _framework_rows(m: data.Machine, got: list[tuple[Record, Record]]) -> tuple[tuple[str, ...], ...]:
    row, slow = cells(m, "cpu"), slowdowns(m)
    lead = min((c.value for c in row.values() if c.value is not None), default=1.0)
    rows = []
    for fw, c in sorted(row.items(), key=lambda kv: (kv[1].value is None, kv[1].value or 0.0, kv[0])):
        if c.value is None:
            rows.append((fw, f"- ({(c.reason or c.status).split(';')[0]})", "-", "-", "-", "-"))
            continue
        labels = [faster(i, b) for i, b in got if b.backend == fw]
        quick = [x for x in labels if x]
        s = slow.get(fw)
        kinds = {WITHIN: "within the idle spread", UNEXPLAINED: "unexplained by the records"}
        counts = {k: sum(kinds.get(x, "idle figure not idle") == k for x in quick)
                  for k in (*kinds.values(), "idle figure not idle")}
        note = "-" if not quick else (
            f"{len(quick)} of its {len(labels)} cells (below): " + ", ".join(f"{v} {k}" for k, v in counts.items() if v))
        sep = (f"{fmt.ratio(c.ci[0])}–{fmt.ratio(c.ci[1])} ({c.processes} processes)" if c.ci
               else f"none ({c.processes} process{'es' if c.processes > 1 else ''})")
        rows.append((fw, fmt.ratio(c.value), fmt.ratio(c.value / lead), sep,
                     fmt.ratio(s) if s is not None else "-", note))
    return tuple(rows)


def section(m: data.Machine) -> list[Any]:
    got = pairs(m)
    if not got:
        return [H("CPU, one core busy"),
                P("No cells timed on a busy host in these records (`python -m compare all --devices cpu "
                  "--precision float32 --busy 1`).")]
    n = max(_busy(b) for _, b in got)
    read = _under_load(m, "cpu")[1]
    bare = ranking.bare(list(cells(m, "cpu").values()))
    rows = []
    for idle, busy in sorted(read, key=lambda p: (p[0].scenario, p[0].backend)):
        s = slowdown(idle, busy)
        rows.append((idle.backend, idle.scenario, _spread(data.timing(idle, REGIME)),
                     _spread(data.timing(busy, REGIME)), fmt.ratio(s) if s else "-",
                     f"{_cores(idle, 'own_cores'):.2f}" if _cores(idle, "own_cores") is not None else "-",
                     f"{_cores(busy, 'others_cores'):.2f}" if _cores(busy, "others_cores") is not None else "-",
                     faster(idle, busy) or why(idle, busy) or "-"))
    return [H("CPU, one core busy"),
            P(f"Each CPU cell at the defaults timed idle and again right after itself, in the same run, with {n} "
              f"core(s) of the {m.cpu_name()} kept busy by another process: what a user waits for on a "
              "laptop or CI runner with other work on it (latency regime). The row ranks the time under "
              "load: the geometric mean over the scenarios of each framework's busy latency divided by the "
              "fastest busy latency on that scenario (1.00× = fastest under load everywhere). The slowdown, "
              "busy over idle, stands beside it and is not ranked: a framework can lose little to the busy "
              "core and still be slow under load."),
            P(("Not ranked: each figure is from one process per cell (no 95 % interval), and the row names a best "
               "only where every framework's figure has a 95 % interval across processes: the ratios below are "
               "to the leading figure. " if bare == "one process" else
               f"Not ranked: some figures are from {bare} (no 95 % interval), and the row names a best only "
               "where every framework's figure has one. " if bare else
               "Where every scenario's busy figure has a 95 % interval across processes, so does the framework's; "
               "the row names a best only where every framework's has one. ") + INTERVALS + "."),
            Table(("framework", "time under load (× fastest busy)", "in the matrix (÷ the leader)", "95 % interval",
                   "slowdown (busy / idle)",
                   "cells faster under load"), _framework_rows(m, read)),
            P("Every cell below: idle and busy latency with their spread (quartiles, or the 95 % interval "
              "across processes). A busy figure below its idle one is noise unless the records explain "
              f"it: \"{WITHIN}\" where the busy median lies inside the idle spread, else \"{UNEXPLAINED}\". "
              "Large slowdowns are explained from the cores the cell used while idle."),
            Table(("framework", "scenario", "idle latency", "busy latency", "slowdown", "cores used idle",
                   "others' cores busy", "why"), tuple(rows))]
