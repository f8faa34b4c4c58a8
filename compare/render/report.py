"""Tables (console, Markdown, CSV), results.json and plots from a list of records."""
from __future__ import annotations

import math
import os
import textwrap
from pathlib import Path
from typing import Any, Iterable, Mapping

from tabulate import tabulate

from compare.measuring import noise, timing
from compare.results.environment import RunEnvironment, tree_state
from compare.results.record import Record, Regime, Timing
from compare.render.results_csv import csv_text, params_text
from compare.results.store import atomic_write, run_environments

NOISY_MARK = noise.MARK

COLUMNS = ("backend", "device", "precision", "variant", "status", "first call", "latency", "IQR",
           "min", "events median", "throughput", "host issue", "graph", "hw fraction", "device mem", "err vs oracle",
           "tolerance", "err vs reference", "gradient", "note")
NOTE_WIDTH = 22
# the terminal's default view (fits 120 columns); --wide and the Markdown/CSV files have all
COMPACT = ("cell", "status", "latency", "throughput", "hw fraction", "err vs oracle", "tolerance", "note")
COMPACT_HEADERS = ("cell", "status", "latency", "throughput", "hw", "error", "tol", "note")


def fmt_time(s: Any) -> str:
    if not isinstance(s, (int, float)) or not math.isfinite(s):
        return "-"
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("µs", 1e-6)):
        if s >= scale:
            return f"{s / scale:.3g} {unit}"
    return f"{s * 1e9:.3g} ns"


def fmt_num(x: Any) -> str:
    if x is None:
        return "-"
    if isinstance(x, str):
        return x
    if isinstance(x, (list, tuple)):
        return "[" + ", ".join(fmt_num(v) for v in x) + "]"
    return "0" if x == 0 else f"{x:.3g}"


def fmt_gradient(rec: Record) -> str:
    g = rec.gradient
    if not g:
        return "-"
    rel = g.get("vs_oracle_rel")
    text = f"{g.get('method', '?')}: {fmt_num(rel)} rel vs {g.get('reference', '?')}"
    if g.get("vs_fd64_rel") is not None:
        text += f", {fmt_num(g['vs_fd64_rel'])} vs fd64"
    return text


def fmt_bytes(b: Any) -> str:
    if not isinstance(b, (int, float)) or not math.isfinite(b):
        return "-"
    for unit, scale in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if abs(b) >= scale:
            return f"{b / scale:.3g} {unit}"
    return f"{int(b)} B"


def row(rec: Record) -> list[str]:
    t = rec.time
    # the same clock for every backend: wall clock around run() + synchronize (latency), k calls
    # and one synchronize (throughput); where the framework offers device events their median is
    # shown in its own column
    lat: Regime | Timing | None = (t.latency or t.wall or t) if t else None
    thr, graph = (t.throughput, t.graph) if t else (None, None)
    e = rec.error
    note = rec.reason
    if rec.status == "ok" and e and e.ill_conditioned:
        note = f"{e.ill_conditioned} ill-conditioned particles not checked"
    checked = e.checked_items if e else None
    if rec.status in ("ok", "mismatch") and isinstance(checked, str) and checked != "all":
        note = "; ".join(filter(None, [note, f"oracle checked {checked}"]))
    if rec.status == "ok" and noise.reasons_for(rec):
        note = "; ".join(filter(None, [note, "noisy: " + "; ".join(noise.reasons_for(rec))]))
    device = rec.device + (f" ({rec.machine})" if rec.machine else "")
    hw, kind = hw_fraction(rec)

    def mark(regime: str) -> str:
        return NOISY_MARK if noise.reasons_for(rec, regime) else ""
    return [rec.backend, device, rec.precision, rec.variant,
            rec.status, fmt_time(t.first_call_s if t else None),
            fmt_time(lat.median_s if lat else None) + mark("latency"),
            fmt_time(lat.iqr_s if lat else None), fmt_time(lat.min_s if lat else None),
            fmt_time(ev.median_s if (ev := timing.events_of(t)) else None),
            fmt_time(thr.median_s if thr else None) + mark("throughput"), fmt_time(thr.host_s if thr else None),
            fmt_time(graph.median_s if graph else None) + mark("graph"),
            f"{hw:.2g} ({kind})" if isinstance(hw, (int, float)) else "-",
            fmt_bytes(rec.memory.device_bytes if rec.memory else None),
            fmt_num(e.vs_oracle if e else None), fmt_num(e.tolerance if e else None),
            fmt_num(e.vs_reference if e else None),
            fmt_gradient(rec), note]


def summary_lines(records: list[Record]) -> list[str]:
    """The end of a run in a few lines: cells by status (and noisy); per scenario, device and
    precision the fastest framework (its best variant, throughput regime) and its lead over the
    next; on the CPU each framework's speed-up against the baseline (NumPy)."""
    import backends
    counts: dict[str, int] = {}
    for r in records:
        counts[r.status] = counts.get(r.status, 0) + 1
    noisy = sum(1 for r in records if r.status == "ok" and noise.reasons_for(r))
    out = [f"{len(records)} cells: " + ", ".join(f"{n} {st}" + (f" ({noisy} noisy {NOISY_MARK})" if st == "ok" and noisy
                                                                 else "") for st, n in counts.items())]
    base = backends.cpu_baseline()
    groups: dict[tuple, dict[str, Record]] = {}
    for r in records:
        med = call_time(r)[0] if r.status == "ok" else None
        if med:
            fastest = groups.setdefault((r.scenario, r.device, r.precision, params_text(r)), {})
            if r.backend not in fastest or med < _median(fastest[r.backend]):
                fastest[r.backend] = r      # a framework's best variant
    for (scenario, device, precision, _), fastest in groups.items():
        if len(fastest) < 2:
            continue
        best = {b: _median(r) for b, r in fastest.items()}
        order = sorted(best, key=lambda b: best[b])
        line = f"  {scenario} {device} {precision}: " + _lead(fastest[order[0]], fastest[order[1]])
        if device == "cpu" and base in best:
            ups = ", ".join(f"{b} {best[base] / best[b]:.3g}x" + (NOISY_MARK if _noisy(fastest[b]) else "")
                            for b in order if b != base)
            line += f"; against {backends.display_name(base)}: {ups}"
        out += textwrap.wrap(line, 118, subsequent_indent="      ", break_on_hyphens=False)
    return out


TIE = 1.05          # two figures within 5 % are not ranked, whatever their spread


def _median(rec: Record) -> float:
    """The per-call median of a cell the summary ranks (only cells that have one are grouped)."""
    med = call_time(rec)[0]
    if med is None:
        raise ValueError(f"{rec.key}: no per-call time to rank")
    return float(med)


def hw_fraction(rec: Record) -> tuple[float | None, str]:
    """The record's hardware fraction (None: not judged) and the kind of floor it is of."""
    thr = rec.throughput
    return (thr.hw_fraction, thr.floor_kind or "") if thr is not None else (None, "")


def _noisy(rec: Record) -> bool:
    """The cell's figures are not to be read as they stand: a stored noise reason (any regime),
    or the summary's own regime spread too wide or too few repeats."""
    t = rec.time
    regime = call_time(rec)[2]
    part = (t.throughput if regime == "throughput" else t) if t else None
    return bool(noise.reasons_for(rec) or noise.regime_reasons(part) or (t and t.noise and t.noise.noisy))


def _interval(rec: Record) -> tuple[float, float]:
    """Where the cell's per-call time lies: the interval across worker processes where several
    measured it (``time.processes.<regime>``), else the median's quartile range."""
    _, iqr, regime = call_time(rec)
    med = _median(rec)
    procs = rec.time.processes if rec.time else None
    part = procs.get(regime) if isinstance(procs, Mapping) else None
    if isinstance(part, Mapping):
        lo, hi = part.get("ci_lo_s"), part.get("ci_hi_s")
        if isinstance(lo, (int, float)) and isinstance(hi, (int, float)) and math.isfinite(lo) and math.isfinite(hi):
            return float(lo), float(hi)
    half = iqr / 2 if isinstance(iqr, (int, float)) and math.isfinite(iqr) else 0.0
    return med - half, med + half


def _lead(first: Record, second: Record) -> str:
    """The fastest cell's lead over the next, claimed only where the figures can tell them apart:
    neither noisy, their intervals apart and more than 5 % between them."""
    a, b = _median(first), _median(second)
    noisy = [r.backend for r in (first, second) if _noisy(r)]
    if noisy:
        return (f"noisy: rerun {' and '.join(noisy)} before ranking (the two fastest: {first.backend} "
                f"{fmt_time(a)}, {second.backend} {fmt_time(b)} a call)")
    (_, hi_a), (lo_b, _) = _interval(first), _interval(second)
    if hi_a >= lo_b or b < a * TIE:
        why = "within 5 %" if b < a * TIE else "their spreads overlap"
        return f"tie: {first.backend}, {second.backend} ({fmt_time(a)}, {fmt_time(b)} a call: {why})"
    return f"fastest {first.backend} ({fmt_time(a)} a call), {b / a:.3g}x ahead of {second.backend}"


def noise_lines(records: list[Record]) -> list[str]:
    """The closing lines: which timed cells are noisy (``~`` in the tables), why, what to do."""
    noisy = [r for r in records if r.status == "ok" and noise.reasons_for(r)]
    if not noisy:
        return []
    busy = any("host busy" in why or "taken between calls" in why for r in noisy for why in noise.reasons_for(r))
    out = [f"{NOISY_MARK} {len(noisy)} of {sum(r.status == 'ok' for r in records)} timed cells are noisy "
           "(their figures are not to be trusted as they stand):"]
    out += [f"  {r.scenario}/{r.backend}/{r.device}/{r.precision}/{r.variant}: "
            + "; ".join(noise.reasons_for(r)) for r in noisy]
    out.append("  what to do: " + ("stop the other work on this machine, then " if busy else "")
               + "rerun these cells (more repeats: --repeat, --min-time) into a new --out and compare")
    return out


SHORT_KIND = {"bandwidth": "bw", "serial latency": "lat", "launch": "launch", "flops": "flops"}


def compact(records: list[Record], brief: bool = False) -> list[list[str]]:
    """The terminal view (COMPACT columns, at most 120 wide): backend, device, precision and
    variant in one column, the hardware fraction with its floor's short name, and one line per
    backend and device whose cells were all skipped for the same reason. ``brief``: a noisy
    cell's note leaves out its reasons (its figures carry the mark; ``compare.render.console`` counts them)
    and the particles not checked are said in one line."""
    idx = [COLUMNS.index(c) for c in COMPACT[1:]]
    out, seen = [], set()
    for r in records:
        if r.status == "skipped":
            same = [q for q in records if q.backend == r.backend and q.device == r.device]
            if all(q.status == "skipped" and q.reason == r.reason for q in same):
                if (r.backend, r.device) in seen:
                    continue
                seen.add((r.backend, r.device))
                out.append([f"{r.backend} {r.device}", "skipped", "-", "-", "-", "-", "-", r.reason])
                continue
        full = row(r)
        hw, kind = hw_fraction(r)
        cells = [full[i] for i in idx]
        cells[COMPACT.index("hw fraction") - 1] = (f"{hw:.2g} {SHORT_KIND.get(kind, kind)}"
                                                   if isinstance(hw, (int, float)) else "-")
        cut = cells[-1].find("noisy: ")
        if brief and cut >= 0 and r.status == "ok" and noise.reasons_for(r):
            cells[-1] = cells[-1][:cut].rstrip("; ")
        ill = r.error.ill_conditioned if r.error else None
        if brief and ill:               # one line of the note column (results.md has the words)
            cells[-1] = cells[-1].replace(f"{ill} ill-conditioned particles not checked", f"{ill} ill-cond. unchecked")
        out.append([" ".join([r.backend, full[1], r.precision.replace("float", "f"), full[3]])] + cells)
    return out


def by_scenario(records: Iterable[Record]) -> dict[str, list[Record]]:
    groups: dict[str, list[Record]] = {}
    for r in records:
        groups.setdefault(r.scenario, []).append(r)
    return groups


def params_line(recs: list[Record]) -> str:
    p = next((r.params for r in recs if r.params), {})
    return ", ".join(f"{k}={v}" for k, v in p.items())


def tables(records: list[Record], fmt: str = "simple", images: dict[str, str] | None = None,
           wide: bool = True, brief: bool = False) -> str:
    """One table per scenario; in Markdown, each followed by its picture when ``images`` has one.
    ``wide=False``: the terminal's compact view (``compact``)."""
    parts = []
    for scenario, recs in by_scenario(records).items():
        head = f"{scenario} ({params_line(recs)})"
        pics = [(name, (images or {}).get(name)) for name in (f"speed_{scenario}", scenario)]
        body, headers = ([row(r) for r in recs], COLUMNS) if wide else (compact(recs, brief), COMPACT_HEADERS)
        if not wide:
            head = textwrap.fill(head, 120, subsequent_indent="    ", break_on_hyphens=False)
        # the terminal's note column wraps a long reason under its row (an install command whole)
        widths = None if wide else [None] * (len(COMPACT) - 1) + [NOTE_WIDTH]
        parts.append(("## " if fmt == "github" else "") + head + ("\n" if brief else "\n\n") +
                     tabulate(body, headers=headers, tablefmt=fmt, disable_numparse=True, maxcolwidths=widths)
                     + "".join(f"\n\n![{name}]({img})" for name, img in pics if img))
    return "\n\n".join(parts) + "\n"


def images_in(plots: Path, relative_to: Path) -> dict[str, str]:
    """scenario (or 'speed_<scenario>', 'time_vs_error', ...) -> path of its PNG in ``plots``, relative to a page's folder."""
    if not plots.is_dir():
        return {}
    return {p.stem: os.path.relpath(p, relative_to) for p in sorted(plots.glob("*.png"))}


def header_lines(env: RunEnvironment) -> list[str]:
    """results.md's opening: each run's environment and yardstick, a merge's inputs first."""
    merged = env.get("merged_from")
    lines = [f"- merged from: {', '.join(f'`{f}`' for f in merged)}"] if merged else []
    for e in run_environments(env):
        lines += ([""] if lines else []) + environment_lines(e) + yardstick_lines(e)
    return lines


def environment_lines(env: RunEnvironment) -> list[str]:
    gpus = ", ".join(f"{g.get('name')} ({g.get('memory')}, driver {g.get('driver')})" for g in env.get("gpus") or [])
    pkgs = ", ".join(f"{k} {v}" for k, v in env.get("packages", {}).items())
    dirty = f" ({words})" if (words := tree_state(env.get("git_dirty"))) else ""
    return [f"- command: `{env.get('command')}`",
            f"- run {env.get('created')} on {env.get('hostname')}, git commit {env.get('git_commit') or 'not recorded'}{dirty}",
            f"- CPU: {env.get('cpu')}, {env.get('cores')} cores, {env.get('memory_gib')} GiB; GPU: {gpus or 'none'}"
            + (f"; CUDA toolkit: {env['cuda_toolkit']}" if env.get("cuda_toolkit") else ""),
            f"- OS: {env.get('os')}; Python {env.get('python')}", f"- packages: {pkgs}"]


def yardstick_lines(env: RunEnvironment) -> list[str]:
    """The run's hardware yardstick per device, in words (``env['hardware']``)."""
    out = []
    for device, hw in (env.get("hardware") or {}).items():
        if not isinstance(hw, dict):
            continue
        if hw.get("error"):
            out.append(f"- yardstick ({device}): not measured ({hw['error']})")
            continue
        bw = hw.get("copy_bytes_per_s")
        launch = hw.get("launch_pipelined_s")
        out.append(f"- yardstick ({device}): copy {bw / 1e9:.3g} GB/s ({hw.get('copy_how', '')})"
                   + (f"; empty-kernel launch {fmt_time(launch)} pipelined" if launch else "")
                   if isinstance(bw, (int, float)) else f"- yardstick ({device}): -")
    return out


def page(title: str, envs: list[RunEnvironment], records: list[Record], images: dict[str, str],
         notes: str = "", rebuild: str = "") -> str:
    """A results page: title, hand-written notes, environments, time against error, then each
    scenario's table and picture. Every number comes from ``records``."""
    out = [f"# {title}", ""]
    if notes:
        out += [notes.strip(), ""]
    if rebuild:
        out += ["Page rebuilt, without rerunning, by:", "", f"    {rebuild}", ""]
    out += ["## Environment", ""]
    for e in (e for env in envs for e in run_environments(env)):
        out += environment_lines(e) + [""]
    import backends
    base = backends.cpu_baseline()
    if base and f"speedup_vs_{base}_cpu" in images:
        who = backends.display_name(base)
        out += [f"## Speed-up against {who} (CPU)", "", f"![speed-up vs {who}]({images[f'speedup_vs_{base}_cpu']})", ""]
    if "time_vs_error" in images:
        out += ["## Run time against error", "", f"![time vs error]({images['time_vs_error']})", ""]
    return "\n".join(out) + "\n" + tables(records, "github", images)


def write_tables(out: Path, environment: RunEnvironment, records: list[Record],
                 images: dict[str, str] | None = None) -> None:
    """results.csv and results.md beside results.json (which the store writes), atomically."""
    atomic_write(out / "results.csv", csv_text(records))
    env_lines = "\n".join(header_lines(environment))
    closing = "\n".join(noise_lines(records))
    atomic_write(out / "results.md", f"# Results\n\n{env_lines}\n\n"
                 + tables(records, "github", images) + (f"\n```\n{closing}\n```\n" if closing else ""))


def call_time(rec: Record) -> tuple[float | None, float | None, str]:
    """(median, IQR, regime) of one call: the throughput regime (k calls, one synchronize), or
    the cell's own clock where it has no throughput regime."""
    t = rec.time
    if t is None:
        return None, None, "latency"
    thr = t.throughput
    if thr is not None and isinstance(thr.median_s, (int, float)):
        return thr.median_s, thr.iqr_s, "throughput"
    med = t.median_s
    return (med if isinstance(med, (int, float)) else None), t.iqr_s, "latency"
