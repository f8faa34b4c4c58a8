"""Tables, plots and the Markdown page of the measurement sweeps (compare/sweep.py).

Pure functions of saved records: ``python -m compare sweep report sweep.json`` rebuilds everything
without rerunning. Definitions (docs/measurement.md):
  * achieved bandwidth = bytes the kernel must move (scenario ``work``) / median time per call;
  * copy roofline = the highest copy bandwidth of any backend on that device in the run;
  * launch share = trivial-launch wall time / the cell's wall time (>= 1/2: overhead-bound);
  * Pareto front = points no other point beats in both time and error.
Cross-backend plots use the wall-clock median (what a caller waits, the same clock for every
framework); CUDA-event medians, where a framework has events, are shown beside it.
"""
from __future__ import annotations

import math
import os
import statistics
from pathlib import Path
from typing import Any, Iterable

from tabulate import tabulate

from compare.report import fmt_num, fmt_time

OVERHEAD_SHARE = 0.5     # launch time >= half the cell's time: overhead-bound
BANDWIDTH_SHARE = 0.5    # >= half the copy roofline: bandwidth-bound
CACHE_SHARE = 1.25       # above the roofline by more than write-allocate accounting (9/8) explains
ERROR_FLOOR = 1e-17      # where an exact (0) error is drawn on a log axis


# ---- numbers ----------------------------------------------------------------------------------
def ok(records: Iterable[dict[str, Any]], **match: Any) -> list[dict[str, Any]]:
    return [r for r in records if r.get("status") == "ok" and r.get("time")
            and all(r.get(k) == v for k, v in match.items())]


def wall_s(rec: dict[str, Any]) -> float:
    t = rec["time"]
    return float((t.get("wall") or {}).get("median_s", t["median_s"]))


def event_s(rec: dict[str, Any]) -> float | None:
    t = rec["time"]
    return float(t["median_s"]) if t.get("timer") == "events" else None


def gbps(nbytes: float, seconds: float) -> float:
    """Achieved bandwidth in GB/s (10^9 bytes per second)."""
    return nbytes / seconds / 1e9 if seconds > 0 else math.nan


def roofline(records: list[dict[str, Any]], device: str) -> dict[str, Any] | None:
    """The best copy bandwidth on ``device`` (primary clock of each backend), or None."""
    best = None
    for r in ok(records, sweep="bandwidth", role="copy", device=device):
        bw = gbps(r["work"]["bytes"], r["time"]["median_s"])
        if best is None or bw > best["gbps"]:
            best = {"gbps": bw, "backend": r["backend"], "precision": r["precision"],
                    "n": r["params"]["n"], "clock": r["time"].get("timer", "wall")}
    return best


def launch_wall(records: list[dict[str, Any]], backend: str, device: str, precision: str) -> float | None:
    hits = ok(records, sweep="bandwidth", role="launch", backend=backend, device=device, precision=precision)
    return wall_s(hits[-1]) if hits else None


def regime(launch_share: float | None, roof_share: float | None) -> str:
    if launch_share is not None and launch_share >= OVERHEAD_SHARE:
        return "overhead-bound"
    if roof_share is not None and roof_share > CACHE_SHARE:
        return "cache-resident"
    if roof_share is not None and roof_share >= BANDWIDTH_SHARE:
        return "bandwidth-bound"
    return "mixed" if launch_share is not None and roof_share is not None else "-"


def bandwidth_row(rec: dict[str, Any], records: list[dict[str, Any]]) -> dict[str, Any]:
    """Achieved GB/s, % of the copy roofline, launch share and regime of one SAXPY/copy cell."""
    nbytes = rec["work"]["bytes"]
    bw = gbps(nbytes, rec["time"]["median_s"])
    roof = roofline(records, rec["device"])
    lw = launch_wall(records, rec["backend"], rec["device"], rec["precision"])
    share = lw / wall_s(rec) if lw else None
    frac = bw / roof["gbps"] if roof else None
    return {"gbps": bw, "wall_gbps": gbps(nbytes, wall_s(rec)), "roof_share": frac,
            "launch_share": share, "regime": regime(share, frac)}


def pareto_front(points: list[tuple[float, float]]) -> list[bool]:
    """For each (time, error) point: True if no other point is <= in both and < in one."""
    flags = []
    for i, (t, e) in enumerate(points):
        dominated = any((t2 <= t and e2 <= e) and (t2 < t or e2 < e)
                        for j, (t2, e2) in enumerate(points) if j != i)
        flags.append(not dominated)
    return flags


def error_points(records: list[dict[str, Any]], device: str, scenario: str) -> list[dict[str, Any]]:
    """Time-against-error points (ok cells with a finite error), with Pareto flags."""
    pts = []
    for r in ok(records, sweep="error", device=device, scenario=scenario):
        e = (r.get("converged") or {}).get("error")
        if isinstance(e, (int, float)) and math.isfinite(e):
            pts.append({"rec": r, "time": wall_s(r), "error": max(float(e), ERROR_FLOOR)})
    overall = pareto_front([(p["time"], p["error"]) for p in pts])
    for backend in {p["rec"]["backend"] for p in pts}:
        mine = [p for p in pts if p["rec"]["backend"] == backend]
        for p, f in zip(mine, pareto_front([(p["time"], p["error"]) for p in mine])):
            p["front_backend"] = f
    for p, f in zip(pts, overall):
        p["front_all"] = f
    return pts


def device_bytes(rec: dict[str, Any]) -> tuple[int | None, str]:
    m = rec.get("memory") or {}
    for k, src in (("device_peak_bytes", m.get("device_memory_source", "framework")),
                   ("nvml_process_peak_bytes", "nvml process"),
                   ("nvml_device_delta_peak_bytes", "nvml device delta")):
        if isinstance(m.get(k), (int, float)):
            return int(m[k]), src
    return None, m.get("nvml_note", "-") if rec["device"] != "cpu" else "-"


def fmt_bytes(b: float | None) -> str:
    if b is None or not math.isfinite(b):
        return "-"
    for unit, scale in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if b >= scale:
            return f"{b / scale:.3g} {unit}"
    return f"{int(b)} B"


def fmt_rate(x: float | None, unit: str = "") -> str:
    if x is None or not math.isfinite(x):
        return "-"
    for suffix, scale in (("T", 1e12), ("G", 1e9), ("M", 1e6), ("k", 1e3)):
        if abs(x) >= scale:
            return f"{x / scale:.3g} {suffix}{unit}"
    return f"{x:.3g} {unit}".strip()


def pct(x: float | None) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{100 * x:.0f}%"


# ---- plots ------------------------------------------------------------------------------------
def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _tidy_log(ax) -> None:
    """Readable base-10 log axes: with two or more powers of ten in range, label only those;
    with fewer, label the 2x and 5x minor ticks too (matplotlib's default overprints there)."""
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
        else:                                 # under a decade: label every tick, plainly
            axis.set_minor_formatter(FuncFormatter(lambda v, _pos: f"{v:.3g}"))
            axis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:.3g}"))


def _colors(records: list[dict[str, Any]]) -> dict[str, str]:
    import backends
    names = [b for b in backends.BACKENDS if any(r["backend"] == b for r in records)]
    names += sorted({r["backend"] for r in records} - set(names))
    return {b: f"C{i}" for i, b in enumerate(names)}


def plot_bandwidth(records: list[dict[str, Any]], device: str, path: Path) -> bool:
    rows = ok(records, sweep="bandwidth", role="saxpy", device=device)
    if not rows:
        return False
    plt = _plt()
    colors = _colors(records)
    fig, ax = plt.subplots(figsize=(8, 5))
    for backend, c in colors.items():
        for prec in ("float32", "float64"):
            mine = sorted((r for r in rows if r["backend"] == backend and r["precision"] == prec),
                          key=lambda r: r["work"]["bytes"])
            if not mine:
                continue
            tag = "" if prec == "float32" else " f64"
            x = [r["work"]["bytes"] for r in mine]
            ax.plot(x, [gbps(r["work"]["bytes"], wall_s(r)) for r in mine], "-o", color=c, ms=4,
                    label=f"{backend}{tag} (wall clock)")
            if any(event_s(r) for r in mine):
                ax.plot(x, [gbps(r["work"]["bytes"], event_s(r) or math.nan) for r in mine], "-.x",
                        color=c, ms=5, label=f"{backend}{tag} (CUDA events)")
            lw = launch_wall(records, backend, device, prec)
            if lw:
                ax.plot(x, [b / lw / 1e9 for b in x], ":", color=c, lw=1,
                        label=f"{backend}{tag}: bytes / launch time")
    roof = roofline(records, device)
    if roof:
        ax.axhline(roof["gbps"], color="k", ls="--", lw=1.2,
                   label=f"copy roofline {roof['gbps']:.3g} GB/s ({roof['backend']})")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xlabel("bytes moved per call, 3·n·itemsize [B] (log2)")
    ax.set_ylabel("achieved bandwidth [GB/s] (log)")
    ax.set_title(f"SAXPY achieved bandwidth against size ({device})")
    ax.grid(True, which="both", alpha=0.3)
    seen = [gbps(r["work"]["bytes"], wall_s(r)) for r in rows]
    ax.set_ylim(bottom=max(min(seen) / 3, 1e-6), top=max(roof["gbps"] * 3 if roof else 0, max(seen) * 2))
    ax.legend(fontsize=7, ncol=2, loc="lower right")
    _tidy_log(ax)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


MARKERS = {"float64": "o", "float32": "^"}


def plot_time_vs_error(records: list[dict[str, Any]], device: str, path: Path) -> bool:
    scen = [s for s in ("saxpy", "sdf", "particles", "projectile") if error_points(records, device, s)]
    if not scen:
        return False
    plt = _plt()
    colors = _colors(records)
    cols = min(2, len(scen))
    rows_n = -(-len(scen) // cols)
    fig, axes = plt.subplots(rows_n, cols, figsize=(6.2 * cols, 4.6 * rows_n), squeeze=False)
    for ax, s in zip(axes.flat, scen):
        pts = error_points(records, device, s)
        for p in pts:
            r = p["rec"]
            c = colors[r["backend"]]
            hollow = r.get("variant", "default") != "default"
            ax.scatter(p["time"], p["error"], marker=MARKERS.get(r["precision"], "s"), s=36,
                       color=c, facecolors="none" if hollow else c, linewidths=1.2)
        for backend, c in colors.items():
            front = sorted((p["time"], p["error"]) for p in pts
                           if p["rec"]["backend"] == backend and p.get("front_backend"))
            if front:
                ax.step(*zip(*front), where="post", color=c, lw=1, alpha=0.8)
        front = sorted((p["time"], p["error"]) for p in pts if p["front_all"])
        ax.step(*zip(*front), where="post", color="0.3", lw=3, alpha=0.35)
        ax.set_xscale("log")
        ax.set_yscale("log")
        knob = {"sdf": "resolution, ", "particles": "dt, ", "projectile": "dt, ", "saxpy": ""}[s]
        ax.set_title(f"{s} (knobs: {knob}precision, variant)", fontsize=10)
        labelled: dict[Any, tuple[float, float]] = {}
        for p in sorted(pts, key=lambda p: p["time"]):   # label the overall front, once per value
            k = p["rec"].get("knob") or {}
            at = (math.log10(p["time"]), math.log10(p["error"]))
            crowded = any(abs(at[0] - q[0]) < 0.3 and abs(at[1] - q[1]) < 0.12
                          for q in labelled.values())
            if p["front_all"] and k.get("value") is not None and k["value"] not in labelled \
                    and not crowded:
                labelled[k["value"]] = at
                ax.annotate(f"{k['name']}={k['value']}", (p["time"], p["error"]), fontsize=6,
                            color="0.25", xytext=(4, 3), textcoords="offset points")
        ax.set_xlabel("median wall time per run [s] (log)")
        ax.set_ylabel(_error_label(s), fontsize=8)
        ax.grid(True, which="both", alpha=0.3)
        _tidy_log(ax)
    for ax in list(axes.flat)[len(scen):]:
        ax.axis("off")
    handles = [plt.Line2D([], [], color=c, marker="o", ls="-", label=b) for b, c in colors.items()
               if any(p["rec"]["backend"] == b for s in scen for p in error_points(records, device, s))]
    handles += [plt.Line2D([], [], color="k", marker="o", ls="", label="float64"),
                plt.Line2D([], [], color="k", marker="^", ls="", label="float32"),
                plt.Line2D([], [], color="k", marker="o", ls="", mfc="none", label="fastmath (hollow)"),
                plt.Line2D([], [], color="0.3", lw=3, alpha=0.35, label="Pareto front, all backends"),
                plt.Line2D([], [], color="k", lw=1, label="Pareto front per backend (its colour)")]
    fig.suptitle(f"Run time against error ({device})", y=0.99, fontsize=11)
    fig.legend(handles=handles, loc="upper center", ncol=5, fontsize=8, bbox_to_anchor=(0.5, 0.965))
    fig.tight_layout(rect=(0, 0, 1, 0.925 if rows_n > 1 else 0.82))
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def _error_label(scenario: str) -> str:
    return {"saxpy": f"max |err|/(|a x|+|y|) vs float64 oracle (0 drawn at {ERROR_FLOOR:g})",
            "sdf": "max |bilinear(image) - field| (log)",
            "particles": "RMS position error vs converged ref. [m] (log)",
            "projectile": "max rel. error of loss, grad vs converged ref. (log)"}[scenario]


def plot_scaling(records: list[dict[str, Any]], device: str, path: Path) -> bool:
    rows = ok(records, sweep="scaling", device=device)
    if not rows:
        return False
    plt = _plt()
    colors = _colors(records)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 4.6))
    for backend, c in colors.items():
        for prec in ("float32", "float64"):
            mine = sorted((r for r in rows if r["backend"] == backend and r["precision"] == prec),
                          key=lambda r: r["params"]["n"])
            if not mine:
                continue
            tag = "" if prec == "float32" else " f64"
            n = [r["params"]["n"] for r in mine]
            a1.plot(n, [r["params"]["n"] * r["params"]["steps"] / wall_s(r) for r in mine], "-o",
                    color=c, ms=4, label=f"{backend}{tag}")
            a2.plot(n, [r["memory"]["peak_host_rss_bytes"] / 2**20 for r in mine], "-o", color=c,
                    ms=4, label=f"{backend}{tag}: peak host RSS")
            dev = [device_bytes(r)[0] for r in mine]
            if any(d is not None for d in dev):
                a2.plot(n, [d / 2**20 if d is not None else math.nan for d in dev], "--s", color=c,
                        ms=4, label=f"{backend}{tag}: device memory")
    for ax in (a1, a2):
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xlabel("particles n (log2)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        _tidy_log(ax)
    steps = rows[0]["params"]["steps"]
    a1.set_ylabel("particle-steps per second [1/s] (log)")
    a1.set_title(f"particles throughput, {steps} steps per run, wall clock ({device})", fontsize=10)
    a2.set_ylabel("memory [MiB] (log)")
    a2.set_title(f"particles memory ({device})", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def write_plots(records: list[dict[str, Any]], out: Path) -> dict[str, Path]:
    """Every plot the records allow, per device: {'bandwidth-cpu': path, ...}."""
    out.mkdir(parents=True, exist_ok=True)
    written = {}
    for device in sorted({r["device"] for r in records}):
        for name, fn in (("bandwidth", plot_bandwidth), ("time_vs_error", plot_time_vs_error),
                         ("scaling", plot_scaling)):
            path = out / f"{name}_{device}.png"
            if fn(records, device, path):
                written[f"{name}-{device}"] = path
    return written


# ---- Markdown ---------------------------------------------------------------------------------
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
        t = r["time"]
        ev = event_s(r)
        rows.append([r["backend"], r["precision"], fmt_time(wall_s(r)), fmt_time(t["wall"]["iqr_s"]
                     if t.get("wall") else t["iqr_s"]), fmt_time(t["wall"]["min_s"] if t.get("wall")
                     else t["min_s"]), fmt_time(ev), fmt_time(t["first_call_s"]), t["repeats"]])
    return _table(rows, ["backend", "precision", "wall median", "wall IQR", "wall min",
                         "CUDA-event median", "first call (cold)", "timed calls"]) if rows else ""


def copy_table(records, device) -> str:
    rows = []
    for r in ok(records, sweep="bandwidth", role="copy", device=device):
        rows.append([r["backend"], r["precision"], r["params"]["n"], fmt_bytes(r["work"]["bytes"]),
                     fmt_time(wall_s(r)), fmt_time(event_s(r)),
                     f"{gbps(r['work']['bytes'], r['time']['median_s']):.3g}",
                     r["time"].get("timer", "wall")])
    return _table(rows, ["backend", "precision", "n", "bytes/call (read + write)", "wall median",
                         "CUDA-event median", "GB/s", "clock of GB/s"]) if rows else ""


def saxpy_table(records, device) -> str:
    rows = []
    for r in sorted(ok(records, sweep="bandwidth", role="saxpy", device=device),
                    key=lambda r: (r["backend"], r["precision"], r["params"]["n"])):
        b = bandwidth_row(r, records)
        rows.append([r["backend"], r["precision"], f"2^{int(math.log2(r['params']['n']))}",
                     fmt_bytes(r["work"]["bytes"]), fmt_time(wall_s(r)), fmt_time(event_s(r)),
                     f"{b['gbps']:.3g}", pct(b["roof_share"]), pct(b["launch_share"]), b["regime"]])
    return _table(rows, ["backend", "precision", "n", "bytes/call", "wall median",
                         "CUDA-event median", "GB/s", "% of copy roofline", "launch share",
                         "regime"]) if rows else ""


def error_table(records, device, scenario) -> str:
    pts = error_points(records, device, scenario)
    rows = []
    for p in sorted(pts, key=lambda p: (p["rec"]["backend"], p["rec"].get("variant", ""),
                                        p["rec"]["precision"], p["rec"]["knob"].get("value") or 0)):
        r = p["rec"]
        knob = r.get("knob") or {}
        rows.append([r["backend"], r.get("variant", "default"), r["precision"],
                     "-" if knob.get("value") is None else f"{knob['name']}={knob['value']}", fmt_time(p["time"]), fmt_time(event_s(r)),
                     fmt_num(r["converged"]["error"]), "yes" if p["front_backend"] else "",
                     "yes" if p["front_all"] else ""])
    return _table(rows, ["backend", "variant", "precision", "knob", "wall median",
                         "CUDA-event median", "error", "on backend's front",
                         "on overall front"]) if rows else ""


def front_table(records, device, scenario) -> str:
    """The overall Pareto front, fastest first: for a target error, the first row at or below it
    is the fastest cell measured that reaches it."""
    rows = []
    for p in sorted((p for p in error_points(records, device, scenario) if p["front_all"]),
                    key=lambda p: p["time"]):
        r, knob = p["rec"], p["rec"].get("knob") or {}
        iqr = ((r.get("time") or {}).get("wall") or {}).get("iqr_s")
        rows.append([fmt_num(r["converged"]["error"]), fmt_time(p["time"]), fmt_time(iqr),
                     r["backend"], r.get("variant", "default"), r["precision"],
                     "-" if knob.get("value") is None else f"{knob['name']}={knob['value']}"])
    return _table(rows, ["error reached", "wall median", "wall IQR", "backend", "variant",
                         "precision", "knob"]) if rows else ""


def scaling_table(records, device) -> str:
    rows = []
    for r in sorted(ok(records, sweep="scaling", device=device),
                    key=lambda r: (r["backend"], r["precision"], r["params"]["n"])):
        n, steps, t = r["params"]["n"], r["params"]["steps"], wall_s(r)
        db, src = device_bytes(r)
        rows.append([r["backend"], r["precision"], n, fmt_time(t), fmt_time(event_s(r)),
                     fmt_rate(steps / t, "steps/s"), fmt_rate(n * steps / t, "/s"),
                     fmt_bytes(r["memory"]["peak_host_rss_bytes"]),
                     f"{fmt_bytes(db)} ({src})" if db is not None else src,
                     r["error"].get("checked_items", "all")])
    return _table(rows, ["backend", "precision", "n", "wall median", "CUDA-event median",
                         "steps/s", "particle-steps/s", "peak host RSS", "device memory",
                         "checked vs oracle"]) if rows else ""


def problems(records) -> str:
    bad = [r for r in records if r.get("status") != "ok"]
    lines = [f"- {r.get('sweep')} {r['scenario']}/{r['backend']}/{r['device']}/{r['precision']}/"
             f"{r.get('variant', 'default')} {_knob(r)}: **{r['status']}**: {r.get('reason', '')}"
             for r in bad]
    return "\n".join(lines) + "\n" if lines else "None: every cell ran and passed its check.\n"


def _knob(r) -> str:
    k = r.get("knob") or {}
    return f"({k['name']}={k['value']})" if k.get("name") and k.get("value") is not None else ""


def environment(runs: list[dict[str, Any]], records: list[dict[str, Any]]) -> str:
    if not runs:
        return ""
    env = runs[-1]
    gpus = "; ".join(f"{g['name']} ({g['memory']}, driver {g['driver']})" for g in env.get("gpus", []))
    pk = ", ".join(f"{k} {v}" for k, v in env.get("packages", {}).items())
    loads = [r["host_load_1m"] for r in records if isinstance(r.get("host_load_1m"), (int, float))]
    lines = [f"- CPU: {env.get('cpu')}, {env.get('cores')} cores available, {env.get('memory_gib')} GiB",
             f"- GPU: {gpus or 'none visible'}" + (f"; CUDA toolkit: {env['cuda_toolkit']}"
                                                   if env.get("cuda_toolkit") else ""),
             f"- OS: {env.get('os')}; Python {env.get('python')}; host {env.get('hostname')}",
             f"- packages: {pk}",
             f"- git commit of the last run {env.get('git_commit') or 'not recorded'}"
             f"{' (with uncommitted changes)' if env.get('git_dirty') else ''}",
             f"- runs from {runs[0].get('created')} to {env.get('created')}"]
    if loads:
        lines.append(f"- host 1-minute load average at the end of each cell: min {min(loads):.2f}, "
                     f"median {statistics.median(loads):.2f}, max {max(loads):.2f} "
                     f"({env.get('cores')} cores: a load above that means more runnable threads than cores)")
    return "\n".join(lines) + "\n"


def page(data: dict[str, Any], written: dict[str, Path], page_path: Path, title: str | None,
         sources: list[str], rebuild: str = "", notes: str = "") -> str:
    """The Markdown page: commands, environment, optional notes, then one set of sections per
    device (launch, copy roofline, SAXPY sweep, time against error, scaling) and the problems."""
    records, runs = data["records"], data["runs"]
    devices = [d for d in ("cpu", "cuda") if any(r["device"] == d and r["status"] != "skipped"
                                                 for r in records)]
    proto = os.path.relpath(Path(__file__).resolve().parent.parent / "docs" / "measurement.md",
                            page_path.resolve().parent)
    out = [f"# {title or 'Measurement sweeps'}\n",
           f"Generated from `{'`, `'.join(sources)}` by `compare/plots_measure.py`; every number "
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
        out.append(f"## {d}: launch overhead\n")
        out.append("A trivial launch (`launch` scenario, n = 1). Small cells whose time is mostly "
                   "this are overhead-bound.\n\n" + (launch_table(records, d) or "No data.\n"))
        out.append(f"## {d}: copy bandwidth (roofline)\n")
        out.append(copy_table(records, d) or "No data.\n")
        if roof:
            out.append(f"\nRoofline for this device: **{roof['gbps']:.3g} GB/s** "
                       f"({roof['backend']}, {roof['precision']}, n = {roof['n']}, "
                       f"{roof['clock']} clock).\n")
        out.append(f"## {d}: SAXPY bandwidth against size\n")
        out.append(_img(written, f"bandwidth-{d}", page_path, f"SAXPY bandwidth vs size, {d}"))
        out.append(saxpy_table(records, d) or "No data.\n")
        out.append(f"## {d}: run time against error\n")
        out.append(_img(written, f"time_vs_error-{d}", page_path, f"time vs error, {d}"))
        for s in ("saxpy", "sdf", "particles", "projectile"):
            tab = error_table(records, d, s)
            if not tab:
                continue
            rec = error_points(records, d, s)[0]["rec"]
            ref = rec["converged"].get("reference", {})
            refline = "; ".join(f"{k} = {fmt_num(v) if not isinstance(v, str) else v}"
                                for k, v in ref.items())
            out.append(f"### {s}\n\nError: {rec['converged']['metric']}. Reference: {refline}.\n\n"
                       "Fastest at each accuracy (the Pareto front over all backends; rows whose "
                       "times differ by less than their IQRs are ties):\n\n"
                       f"{front_table(records, d, s)}\nAll cells:\n\n{tab}")
        out.append(f"## {d}: particles scaling\n")
        out.append(_img(written, f"scaling-{d}", page_path, f"particles scaling, {d}"))
        out.append(scaling_table(records, d) or "No data.\n")
    out.append("## Skipped and failed cells\n")
    out.append(problems(records))
    return "\n".join(out)


def summary(records: list[dict[str, Any]]) -> str:
    counts: dict[str, int] = {}
    for r in records:
        counts[r["status"]] = counts.get(r["status"], 0) + 1
    parts = [", ".join(f"{v} {k}" for k, v in sorted(counts.items()))]
    for d in ("cpu", "cuda"):
        roof = roofline(records, d)
        if roof:
            parts.append(f"{d} copy roofline: {roof['gbps']:.3g} GB/s ({roof['backend']})")
    return "; ".join(parts)
