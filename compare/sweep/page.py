"""The tables and the Markdown page of the measurement sweeps (compare/sweep).

Pure functions of saved records: ``python -m compare sweep report sweep.json`` rebuilds everything
without rerunning. Rows are found by the suite's tags (``rec.tags``: sweep kind, role, knob),
never by scenario name; the words for a scenario come from its sweeps (``points.Sweeps.labels``);
the derived figures (bandwidth, roofline, regime, Pareto fronts) from compare/sweep/metrics.py.
Cross-backend plots use the wall-clock median (what a caller waits, the same clock for every
framework); CUDA-event medians, where a framework has events, are shown beside it.
"""
from __future__ import annotations

import math
import os
import statistics
from pathlib import Path
from typing import Any, Iterable, NamedTuple

from tabulate import tabulate

import backends
from backends.base import DEFAULT_VARIANT
import scenarios
from compare.results.environment import RunEnvironment, tree_state
from compare.results.record import Record
from compare.render.report import fmt_bytes, fmt_num, fmt_time
from compare.sweep import horizon
from compare.sweep.metrics import bandwidth_row, device_bytes, error_points, gbps, roofline
from compare.sweep.points import sweeps
from compare.sweep.rows import (checked_items, converged, event_s, knob, knob_value, label, need, ok, tag, throughput_s,
                                timed, wall_s)

class Contents(NamedTuple):
    """What the page and plots are built from: the runs' environments and every record."""
    runs: list[RunEnvironment]
    records: list[Record]


# ---- records and scenarios --------------------------------------------------------------------
def with_role(role: str) -> list[str]:
    """The scenarios that measure ``role`` ('launch', 'copy', 'bandwidth'), in registry order."""
    return [name for name in scenarios.SCENARIOS if sweeps(name).measures == role]


def in_registry_order(names: Iterable[str]) -> list[str]:
    names = set(names)
    return [n for n in scenarios.SCENARIOS if n in names] + sorted(names - set(scenarios.SCENARIOS))


def swept(records: list[Record], kind: str, device: str) -> list[str]:
    """Scenarios with records of sweep ``kind`` on ``device`` (a sweep not run has no section)."""
    return in_registry_order(r.scenario for r in records if tag(r, "sweep") == kind and r.device == device)


def error_scenarios(records: list[Record], device: str) -> list[str]:
    """Scenarios with time-against-error points on ``device``, in registry order."""
    return [s for s in in_registry_order(r.scenario for r in records if tag(r, "sweep") == "error")
            if error_points(records, device, s)]


def fmt_rate(x: float | None, unit: str = "") -> str:
    if x is None or not math.isfinite(x):
        return "-"
    for suffix, scale in (("T", 1e12), ("G", 1e9), ("M", 1e6), ("k", 1e3)):
        if abs(x) >= scale:
            return f"{x / scale:.3g} {suffix}{unit}"
    return f"{x:.3g} {unit}".strip()


def pct(x: float | None) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{100 * x:.0f}%"


def knob_text(rec: Record) -> str:
    k = knob(rec)
    return "-" if k.value is None else f"{k.name}={k.value}"


# ---- tables -----------------------------------------------------------------------------------
def _table(rows: list[list[Any]], headers: list[str]) -> str:
    return tabulate(rows, headers=headers, tablefmt="github", disable_numparse=True) + "\n"


def _img(written: dict[str, Path], name: str, page: Path, alt: str) -> str:
    if name not in written:
        return ""
    rel = os.path.relpath(written[name], page.parent)
    return f"![{alt}]({rel})\n\n"


def launch_table(records, device) -> str:
    rows = []
    for r in ok(records, sweep="bandwidth", role="launch", device=device):
        t = timed(r)
        ev = event_s(r)
        rows.append([r.backend, r.precision, fmt_time(wall_s(r)), fmt_time(t.wall.iqr_s if t.wall else t.iqr_s),
                     fmt_time(t.wall.min_s if t.wall else t.min_s), fmt_time(ev), fmt_time(t.first_call_s),
                     t.repeats])
    return _table(rows, ["backend", "precision", "wall median", "wall IQR", "wall min",
                         "CUDA-event median", "first call (cold)", "timed calls"]) if rows else ""


def copy_table(records, device) -> str:
    rows = []
    for r in ok(records, sweep="bandwidth", role="copy", device=device):
        t, w = timed(r), need(r, "work")
        rows.append([r.backend, r.precision, need(r, "params")["n"], fmt_bytes(w["bytes"]),
                     fmt_time(wall_s(r)), fmt_time(event_s(r)),
                     f"{gbps(w['bytes'], t.median_s):.3g}",
                     t.timer if t.timer is not None else "wall"])
    return _table(rows, ["backend", "precision", "n", "bytes/call (read + write)", "wall median",
                         "CUDA-event median", "GB/s", "clock of GB/s"]) if rows else ""


def size_table(records, device, scenario) -> str:
    """The size sweep (role 'bandwidth') of one scenario: GB/s, roofline and launch shares."""
    rows = []
    mine = sorted(ok(records, sweep="bandwidth", role="bandwidth", device=device, scenario=scenario),
                  key=lambda r: (r.backend, r.variant != DEFAULT_VARIANT,
                                 r.variant, r.precision, knob(r).value or 0))
    for r in mine:
        b = bandwidth_row(r, records)
        thr = throughput_s(r)
        w = need(r, "work")
        rows.append([r.backend, r.variant, r.precision,
                     f"2^{int(math.log2(knob_value(r)))}",
                     fmt_bytes(w["bytes"]), fmt_time(wall_s(r)), fmt_time(event_s(r)),
                     f"{b['gbps']:.3g}", pct(b["roof_share"]), pct(b["launch_share"]), b["regime"],
                     fmt_time(thr), f"{gbps(w['bytes'], thr):.3g}" if thr else "-",
                     pct(r.throughput.hw_fraction if r.throughput else None)])
    return _table(rows, ["backend", "variant", "precision", knob(mine[0]).name or "size", "bytes/call",
                         "wall median", "CUDA-event median", "GB/s", "% of copy roofline",
                         "launch share", "regime", "throughput: per call", "throughput: GB/s",
                         "hw fraction"]) if rows else ""


def error_table(records, device, scenario) -> str:
    pts = error_points(records, device, scenario)
    rows = []
    for p in sorted(pts, key=lambda p: (p["rec"].backend, p["rec"].variant,
                                        p["rec"].precision, knob(p["rec"]).value or 0)):
        r = p["rec"]
        rows.append([r.backend, r.variant, r.precision, knob_text(r),
                     fmt_time(p["time"]), fmt_time(event_s(r)), fmt_num(converged(r).error),
                     "yes" if p["front_backend"] else "", "yes" if p["front_all"] else ""])
    return _table(rows, ["backend", "variant", "precision", "knob", "wall median",
                         "CUDA-event median", "error", "on backend's front",
                         "on overall front"]) if rows else ""


def front_table(records, device, scenario) -> str:
    """The overall Pareto front, fastest first: for a target error, the first row at or below it
    is the fastest cell measured that reaches it."""
    rows = []
    for p in sorted((p for p in error_points(records, device, scenario) if p["front_all"]),
                    key=lambda p: p["time"]):
        r = p["rec"]
        iqr = r.time.wall.iqr_s if r.time and r.time.wall else None
        rows.append([fmt_num(converged(r).error), fmt_time(p["time"]), fmt_time(iqr),
                     r.backend, r.variant, r.precision, knob_text(r)])
    return _table(rows, ["error reached", "wall median", "wall IQR", "backend", "variant",
                         "precision", "knob"]) if rows else ""


def scaling_table(records, device, scenario) -> str:
    """Throughput and memory against the swept size; the per-run count and the work item are
    the scenario's words ('per_run', 'item_rate')."""
    per_run, items = label(scenario, "per_run"), label(scenario, "item_rate", "items")
    work = label(scenario, "rate_work", "items")       # the work() key the rate counts
    rows = []
    mine = sorted(ok(records, sweep="scaling", device=device, scenario=scenario),
                  key=lambda r: (r.backend, r.precision, knob(r).value or 0))
    for r in mine:
        t = wall_s(r)
        db, src = device_bytes(r)
        rates = [fmt_rate(need(r, "params")[per_run] / t, f"{per_run}/s")] if per_run else []
        thr = throughput_s(r)
        rows.append([r.backend, r.precision, knob(r).value, fmt_time(t),
                     fmt_time(event_s(r)), fmt_time(thr), *rates,
                     fmt_rate(need(r, "work")[work] / (thr or t), "/s"),
                     fmt_bytes(need(r, "memory")["peak_host_rss_bytes"]),
                     f"{fmt_bytes(db)} ({src})" if db is not None else src,
                     checked_items(r)])
    return _table(rows, ["backend", "precision", knob(mine[0]).name or "size", "wall median",
                         "CUDA-event median", "throughput: per call", *([f"{per_run}/s"] if per_run else []),
                         f"{items}/s (throughput regime where measured)",
                         "peak host RSS", "device memory", "checked vs oracle"]) if rows else ""


def problems(records) -> str:
    bad = [r for r in records if r.status != "ok"]
    lines = [f"- {tag(r, 'sweep')} {r.scenario}/{r.backend}/{r.device}/{r.precision}/"
             f"{r.variant} {_knob(r)}: **{r.status}**: {r.reason}"
             for r in bad]
    return "\n".join(lines) + "\n" if lines else "None: every cell ran and passed its check.\n"


def _knob(r) -> str:
    k = knob(r)
    return f"({k.name}={k.value})" if k.name and k.value is not None else ""


def environment(runs: list[RunEnvironment], records: list[Record]) -> str:
    if not runs:
        return ""
    env = runs[-1]
    gpus = "; ".join(f"{g['name']} ({g['memory']}, driver {g['driver']})" for g in env.get("gpus", []))
    pk = ", ".join(f"{k} {v}" for k, v in env.get("packages", {}).items())
    loads = [r.host_load_1m for r in records if isinstance(r.host_load_1m, (int, float))]
    lines = [f"- CPU: {env.get('cpu')}, {env.get('cores')} cores available, {env.get('memory_gib')} GiB",
             f"- GPU: {gpus or 'none visible'}" + (f"; CUDA toolkit: {env['cuda_toolkit']}"
                                                   if env.get("cuda_toolkit") else ""),
             f"- OS: {env.get('os')}; Python {env.get('python')}; host {env.get('hostname')}",
             f"- packages: {pk}",
             f"- git commit of the last run {env.get('git_commit') or 'not recorded'}"
             f"{f' ({words})' if (words := tree_state(env.get('git_dirty'))) else ''}",
             f"- runs from {runs[0].get('created')} to {env.get('created')}"]
    if loads:
        lines.append(f"- host 1-minute load average at the end of each cell: min {min(loads):.2f}, "
                     f"median {statistics.median(loads):.2f}, max {max(loads):.2f} "
                     f"({env.get('cores')} cores: a load above that means more runnable threads than cores)")
    return "\n".join(lines) + "\n"


# ---- the page ---------------------------------------------------------------------------------
def plot_key(kind: str, device: str, scenario: str, scenarios_of_kind: list[str]) -> str:
    """The key (and file stem) of a per-scenario plot: one scenario of a kind keeps the short name."""
    return f"{kind}-{device}" if len(scenarios_of_kind) <= 1 else f"{kind}-{scenario}-{device}"


def _launch_section(records, d) -> list[str]:
    intro = "A trivial launch"
    for name in with_role("launch")[:1]:
        pts = sweeps(name).points("bandwidth", d, False)
        size = ", ".join(f"{k} = {v}" for k, v in (pts[0].params if pts else {}).items())
        intro += f" (`{name}` scenario" + (f", {size})" if size else ")")
    return [f"## {d}: launch overhead\n",
            f"{intro}. Small cells whose time is mostly this are overhead-bound.\n\n"
            + (launch_table(records, d) or "No data.\n")]


def _error_section(records, d, s) -> str:
    rec = error_points(records, d, s)[0]["rec"]
    conv = converged(rec)         # an error point has its converged error
    ref = conv.reference if conv.reference is not None else {}
    refline = "; ".join(f"{k} = {fmt_num(v) if not isinstance(v, str) else v}" for k, v in ref.items())
    return (f"### {s}\n\nError: {conv.metric}. Reference: {refline}.\n\n"
            "Fastest at each accuracy (the Pareto front over all backends; rows whose "
            "times differ by less than their IQRs are ties):\n\n"
            f"{front_table(records, d, s)}\nAll cells:\n\n{error_table(records, d, s)}")


def page(data: Contents, written: dict[str, Path], page_path: Path, title: str | None,
         sources: list[str], rebuild: str = "", notes: str = "") -> str:
    """The Markdown page: commands, environment, optional notes, then one set of sections per
    device (launch, copy roofline, size sweep, time against error, scaling, horizon) and the
    problems."""
    records, runs = data.records, data.runs
    devices = [d for d in backends.DEVICES if any(r.device == d and r.status != "skipped"
                                                  for r in records)]
    proto = os.path.relpath(Path(__file__).resolve().parents[2] / "docs" / "measurement.md",
                            page_path.resolve().parent)
    out = [f"# {title or 'Measurement sweeps'}\n",
           f"Generated from `{'`, `'.join(sources)}` by `compare/sweep/page.py`; every number "
           f"below is a measured value "
           f"from those records. The protocol (clocks, caches, definitions) is in [{proto}]({proto}).\n",
           "## Commands\n", "Measured with (in order; each run's start time and commit):\n\n"
           + "\n".join(f"    {r.get('command')}\n        # {r.get('created')}, commit "
                       f"{r.get('git_commit') or 'not recorded'}" for r in runs)
           + "\n" + (f"\nThis page and its plots rebuilt, without rerunning, by:\n\n    {rebuild}\n"
                      if rebuild else ""),
           "## Environment\n", environment(runs, records)]
    if notes:
        out += ["## Notes\n", notes.strip() + "\n"]
    for d in devices:
        roof = roofline(records, d)
        out += _launch_section(records, d)
        out.append(f"## {d}: copy bandwidth (roofline)\n")
        out.append(copy_table(records, d) or "No data.\n")
        if roof and roof["backend"] == "hardware yardstick":
            out.append(f"\nRoofline for this device: **{roof['gbps']:.3g} GB/s**, the same-run "
                       f"hardware yardstick ({roof['n']}); no backend's kernel is involved.\n")
        elif roof:
            out.append(f"\nRoofline for this device: **{roof['gbps']:.3g} GB/s** "
                       f"({roof['backend']}, {roof['precision']}, n = {roof['n']}, "
                       f"{roof['clock']} clock; recorded before the hardware yardstick existed, so "
                       f"the best of the contestants' own copies).\n")
        sized = with_role("bandwidth")
        for s in sized:
            name = label(s, "name")
            out.append(f"## {d}: {name} bandwidth against size\n")
            out.append(_img(written, plot_key("bandwidth", d, s, sized), page_path,
                            f"{name} bandwidth vs size, {d}"))
            out.append(size_table(records, d, s) or "No data.\n")
        out.append(f"## {d}: run time against error\n")
        out.append(_img(written, f"time_vs_error-{d}", page_path, f"time vs error, {d}"))
        out += [_error_section(records, d, s) for s in error_scenarios(records, d)]
        scaled = swept(records, "scaling", d)
        for s in scaled:
            name = label(s, "name")
            out.append(f"## {d}: {name} scaling\n")
            out.append(_img(written, plot_key("scaling", d, s, scaled), page_path, f"{name} scaling, {d}"))
            out.append(scaling_table(records, d, s) or "No data.\n")
        long = swept(records, "horizon", d)
        for s in long:
            name = label(s, "name")
            out.append(f"## {d}: {name} against the horizon\n")
            out.append(_img(written, plot_key("horizon", d, s, long), page_path, f"{name} horizon, {d}"))
            out.append(horizon.table(records, d, s) or "No data.\n")
    out.append("## Skipped and failed cells\n")
    out.append(problems(records))
    return "\n".join(out)


def summary(records: list[Record]) -> str:
    counts: dict[str, int] = {}
    for r in records:
        counts[r.status] = counts.get(r.status, 0) + 1
    parts = [", ".join(f"{v} {k}" for k, v in sorted(counts.items()))]
    for d in backends.DEVICES:
        roof = roofline(records, d)
        if roof:
            parts.append(f"{d} copy roofline: {roof['gbps']:.3g} GB/s ({roof['backend']})")
    return "; ".join(parts)
