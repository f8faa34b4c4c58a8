"""The measurement sweeps' plots (PNG), one set per device: achieved bandwidth against size, run
time against error with Pareto fronts, throughput and memory against size. Pure functions of
saved records (see compare/sweep/page.py for the numbers); each backend keeps its own colour
(``Backend.color``) in every plot, whatever else ran.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Callable

import backends
from backends.base import DEFAULT_VARIANT
from compare.render.colors import backend_color
from compare.render.figure_check import keep_apart
from compare.results.record import Record
from compare.files import save_figure
from compare.sweep import horizon
from compare.sweep.metrics import ERROR_FLOOR, ErrorPoint, device_bytes, error_points, gbps, launch_wall, roofline
from compare.sweep.page import error_scenarios, plot_key, swept, with_role
from compare.sweep.converged import Param
from compare.sweep.rows import converged, event_s, knob, knob_value, label, need, ok, wall_s
from scenarios.base import Precision

MARKERS = {"float64": "o", "float32": "^"}


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _tidy_log(ax) -> None:
    """Readable base-10 log axes: with two or more powers of ten in range, label only those;
    with fewer, label the 2x and 5x minor ticks too; under a decade, the 1-2-3-5-7 ticks
    (matplotlib's default, or every tick, overprints there)."""
    from matplotlib.ticker import FuncFormatter, NullFormatter

    def two_five(v: float, _pos: int) -> str:
        e = math.floor(math.log10(v) + 1e-9)
        m = round(v / 10**e, 6)
        return f"${m:g}\\times10^{{{e}}}$" if m in (2.0, 5.0) else ""
    for axis, (lo, hi) in ((ax.xaxis, ax.get_xlim()), (ax.yaxis, ax.get_ylim())):
        if axis.get_scale() != "log" or getattr(axis.get_transform(), "base", 10) != 10 or lo <= 0:
            continue
        powers = math.floor(math.log10(hi)) - math.ceil(math.log10(lo)) + 1
        if powers >= 2:
            axis.set_minor_formatter(NullFormatter())
        elif hi / lo >= 10:
            axis.set_minor_formatter(FuncFormatter(two_five))
        else:       # under a decade: the 1-2-3-5-7 ticks where two are in range, else all
            e0 = math.floor(math.log10(lo))
            few = [m for e in (e0, e0 + 1) for m in (1, 2, 3, 5, 7) if lo <= m * 10.0**e <= hi]
            keep = (1.0, 2.0, 3.0, 5.0, 7.0) if len(few) >= 2 else tuple(float(m) for m in range(1, 10))

            def some(v: float, _pos: int, keep: tuple[float, ...] = keep) -> str:
                m = round(v / 10**math.floor(math.log10(v) + 1e-9), 6)
                return f"{v:.3g}" if m in keep else ""
            axis.set_minor_formatter(FuncFormatter(some))
            axis.set_major_formatter(FuncFormatter(some))


def colors(records: list[Record]) -> dict[str, str]:
    """backend -> its fixed colour (``Backend.color``), in display order; a backend without one
    (or unknown here) gets a colour no registered backend uses."""
    present = {r.backend for r in records}
    known = {n: b for n, b in backends.BACKENDS.items() if n in present}
    names = sorted(known, key=lambda n: (known[n].display_order, n)) + sorted(present - set(known))
    taken = {b.color for b in backends.BACKENDS.values() if b.color}
    spare = [f"C{i}" for i in range(10) if f"C{i}" not in taken] or ["k"]
    out: dict[str, str] = {}
    for n in names:
        fixed = backend_color(n) if n in known and known[n].color else None
        if not fixed:
            fixed = spare[len([c for c in out.values() if c in spare]) % len(spare)]
        out[n] = fixed
    return out


def plot_bandwidth(records: list[Record], device: str, path: Path, scenario: str) -> bool:
    rows = ok(records, sweep="bandwidth", role="bandwidth", device=device, scenario=scenario)
    if not rows:
        return False
    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 5))
    for backend, c in colors(records).items():
        for prec in ("float32", "float64"):
            mine = sorted((r for r in rows if r.backend == backend and r.precision == prec),
                          key=lambda r: need(r, "work")["bytes"])
            if not mine:
                continue
            tag = "" if prec == "float32" else " f64"
            # a scenario's own variants (e.g. vector loads): their wall-clock curve, dashed
            for v in dict.fromkeys(r.variant for r in mine):
                if v != DEFAULT_VARIANT:
                    vs = [r for r in mine if r.variant == v]
                    ax.plot([need(r, "work")["bytes"] for r in vs],
                            [gbps(need(r, "work")["bytes"], wall_s(r)) for r in vs],
                            "--s", color=c, ms=4, label=f"{backend}{tag} {v} (wall clock)")
            mine = [r for r in mine if r.variant == DEFAULT_VARIANT]
            if not mine:
                continue
            x = [need(r, "work")["bytes"] for r in mine]
            ax.plot(x, [gbps(need(r, "work")["bytes"], wall_s(r)) for r in mine], "-o", color=c, ms=4,
                    label=f"{backend}{tag} (wall clock)")
            if any(event_s(r) for r in mine):
                ax.plot(x, [gbps(need(r, "work")["bytes"], event_s(r) or math.nan) for r in mine], "-.x",
                        color=c, ms=5, label=f"{backend}{tag} (CUDA events)")
            lw = launch_wall(records, backend, device, Precision(prec))
            if lw:
                ax.plot(x, [b / lw / 1e9 for b in x], ":", color=c, lw=1,
                        label=f"{backend}{tag}: bytes / launch time")
    roof = roofline(records, device)
    if roof:
        ax.axhline(roof["gbps"], color="k", ls="--", lw=1.2,
                   label=f"copy roofline {roof['gbps']:.3g} GB/s ({roof['backend']})")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    counted = label(scenario, "bytes")
    ax.set_xlabel(f"bytes moved per call{', ' + counted if counted else ''} [B] (log2)")
    ax.set_ylabel("achieved bandwidth [GB/s] (log)")
    ax.set_title(f"{label(scenario, 'name')} achieved bandwidth against size ({device})")
    ax.grid(True, which="both", alpha=0.3)
    seen = [gbps(need(r, "work")["bytes"], wall_s(r)) for r in rows]
    ax.set_ylim(bottom=max(min(seen) / 3, 1e-6), top=max(roof["gbps"] * 3 if roof else 0, max(seen) * 2))
    ax.legend(fontsize=7, ncol=2, loc="lower right")
    _tidy_log(ax)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return True


def _knobs(pts: list[ErrorPoint]) -> str:
    """'name, ' for each knob the points sweep (precision and variant always are)."""
    names = dict.fromkeys(knob(p["rec"]).name for p in pts if knob(p["rec"]).value is not None)
    return "".join(f"{n}, " for n in names if n)


def plot_time_vs_error(records: list[Record], device: str, path: Path) -> bool:
    scen = error_scenarios(records, device)
    if not scen:
        return False
    plt = _plt()
    cmap = colors(records)
    cols = min(2, len(scen))
    rows_n = -(-len(scen) // cols)
    fig, axes = plt.subplots(rows_n, cols, figsize=(6.2 * cols, 4.6 * rows_n), squeeze=False)
    notes: list[Any] = []           # the front's knob labels, dropped where they would overlap
    for ax, s in zip(axes.flat, scen):
        pts = error_points(records, device, s)
        for p in pts:
            r = p["rec"]
            c = cmap[r.backend]
            hollow = r.variant != DEFAULT_VARIANT
            ax.scatter(p["time"], p["error"], marker=MARKERS.get(r.precision, "s"), s=36,
                       color=c, facecolors="none" if hollow else c, linewidths=1.2)
        for backend, c in cmap.items():
            front = sorted((p["time"], p["error"]) for p in pts
                           if p["rec"].backend == backend and p.get("front_backend"))
            if front:
                ax.step(*zip(*front), where="post", color=c, lw=1, alpha=0.8)
        front = sorted((p["time"], p["error"]) for p in pts if p["front_all"])
        ax.step(*zip(*front), where="post", color="0.3", lw=3, alpha=0.35)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(f"{s} (knobs: {_knobs(pts)}precision, variant)", fontsize=10)
        labelled: dict[Param, tuple[float, float]] = {}
        for p in sorted(pts, key=lambda p: p["time"]):   # label the overall front, once per value
            k = knob(p["rec"])
            at = (math.log10(p["time"]), math.log10(p["error"]))
            crowded = any(abs(at[0] - q[0]) < 0.3 and abs(at[1] - q[1]) < 0.12
                          for q in labelled.values())
            if p["front_all"] and k.value is not None and k.value not in labelled and not crowded:
                labelled[k.value] = at
                notes.append(ax.annotate(f"{k.name}={k.value}", (p["time"], p["error"]), fontsize=6,
                                         color="0.25", xytext=(4, 3), textcoords="offset points"))
        ax.set_xlabel("median wall time per run [s] (log)")
        metric = converged(pts[0]["rec"]).metric
        ax.set_ylabel(label(s, "error_axis", metric).format(floor=ERROR_FLOOR), fontsize=8)
        ax.grid(True, which="both", alpha=0.3)
        _tidy_log(ax)
    for ax in list(axes.flat)[len(scen):]:
        ax.axis("off")
    handles = [plt.Line2D([], [], color=c, marker="o", ls="-", label=b) for b, c in cmap.items()
               if any(p["rec"].backend == b for s in scen for p in error_points(records, device, s))]
    handles += [plt.Line2D([], [], color="k", marker="o", ls="", label="float64"),
                plt.Line2D([], [], color="k", marker="^", ls="", label="float32"),
                plt.Line2D([], [], color="k", marker="o", ls="", mfc="none", label="fastmath (hollow)"),
                plt.Line2D([], [], color="0.3", lw=3, alpha=0.35, label="Pareto front, all backends"),
                plt.Line2D([], [], color="k", lw=1, label="Pareto front per backend (its colour)")]
    fig.suptitle(f"Run time against error ({device})", y=0.99, fontsize=11)
    legend = fig.legend(handles=handles, loc="upper center", ncol=5 if cols > 1 else 3, fontsize=8,
                        bbox_to_anchor=(0.5, 0.965))
    under = legend.get_window_extent(fig.canvas.get_renderer()).y0 / fig.bbox.height   # axes below it
    fig.tight_layout(rect=(0, 0, 1, under - 0.01))
    keep_apart(notes)
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return True


def plot_scaling(records: list[Record], device: str, path: Path, scenario: str) -> bool:
    """Throughput (work items per second) and memory against the swept size of one scenario."""
    rows = ok(records, sweep="scaling", device=device, scenario=scenario)
    if not rows:
        return False
    plt = _plt()
    name, per_run = label(scenario, "name"), label(scenario, "per_run")
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 4.6))
    for backend, c in colors(records).items():
        for prec in ("float32", "float64"):
            mine = sorted((r for r in rows if r.backend == backend and r.precision == prec),
                          key=knob_value)
            if not mine:
                continue
            tag = "" if prec == "float32" else " f64"
            n = [knob_value(r) for r in mine]
            a1.plot(n, [need(r, "work")[label(scenario, "rate_work", "items")] / wall_s(r) for r in mine], "-o",
                    color=c, ms=4, label=f"{backend}{tag}")
            a2.plot(n, [need(r, "memory")["peak_host_rss_bytes"] / 2**20 for r in mine], "-o", color=c,
                    ms=4, label=f"{backend}{tag}: peak host RSS")
            dev = [device_bytes(r)[0] for r in mine]
            if any(d is not None for d in dev):
                a2.plot(n, [d / 2**20 if d is not None else math.nan for d in dev], "--s", color=c,
                        ms=4, label=f"{backend}{tag}: device memory")
    size = f"{label(scenario, 'items', name)} {knob(rows[0]).name or 'size'}"
    for ax in (a1, a2):
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xlabel(f"{size} (log2)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        _tidy_log(ax)
    per = f"{need(rows[0], 'params')[per_run]} {per_run} per run, " if per_run else ""
    a1.set_ylabel(f"{label(scenario, 'item_rate', 'items')} per second [1/s] (log)")
    a1.set_title(f"{name} throughput, {per}wall clock ({device})", fontsize=10)
    a2.set_ylabel("memory [MiB] (log)")
    a2.set_title(f"{name} memory ({device})", fontsize=10)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return True


def plot_horizon(records: list[Record], device: str, path: Path, scenario: str, part: str = "all") -> bool:
    """The horizon plot: all three panels ('all', the sweep's report), or one part as small multiples
    per framework ('memory', 'time') or alone ('quality'): compare/sweep/horizon_panels.py."""
    if part == "all":
        return horizon.plot(records, device, path, scenario, colors(records), _plt())
    from compare.sweep import horizon_panels
    if part == "quality":
        return horizon_panels.quality(records, device, path, scenario, _plt())
    return horizon_panels.panels(records, device, path, scenario, colors(records), _plt(), part)


def write_plots(records: list[Record], out: Path) -> dict[str, Path]:
    """Every plot the records allow, per device: {'bandwidth-cpu': path, ...} (file names as the
    keys, '-' -> '_': bandwidth_cpu.png; with several scenarios of a kind, one file each)."""
    out.mkdir(parents=True, exist_ok=True)
    written = {}
    for device in sorted({r.device for r in records}):
        sized = with_role("bandwidth")
        scaled = swept(records, "scaling", device)
        jobs: list[tuple[str, Callable[..., bool], tuple[str, ...]]] = [
            (plot_key("bandwidth", device, s, sized), plot_bandwidth, (s,)) for s in sized]
        jobs += [(f"time_vs_error-{device}", plot_time_vs_error, ())]
        jobs += [(plot_key("scaling", device, s, scaled), plot_scaling, (s,)) for s in scaled]
        long = swept(records, "horizon", device)
        jobs += [(plot_key("horizon", device, s, long), plot_horizon, (s,)) for s in long]
        for key, fn, extra in jobs:
            path = out / f"{key.replace('-', '_')}.png"
            if fn(records, device, path, *extra):
                written[key] = path
    return written
