"""The pictures of one run in its plots/ folder: speed per scenario (throughput regime, spread as
whiskers), the CPU speed-up against the baseline backend, time against error, and each scenario's
own picture of its outputs; and the clean-up of an earlier run's pictures."""
from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any, Callable

import numpy as np

from backends.base import DEFAULT_VARIANT
from compare.results.record import Record, plain
from compare.render.report import by_scenario, call_time, fmt_time
from compare.files import save_figure


def plot_time_vs_error(records: list[Record], path: Path) -> None:
    """Latency-regime time against error, one panel per scenario (two columns)."""
    from compare.render import charts
    plt = charts.pyplot()
    groups = by_scenario(r for r in records if r.status in ("ok", "mismatch") and r.time)
    if not groups:
        return
    cmap = charts.colors(r.backend for rs in groups.values() for r in rs)
    cols, rows = min(2, len(groups)), -(-len(groups) // 2)
    import matplotlib
    with matplotlib.rc_context(charts.RC):
        fig, axes = plt.subplots(rows, cols, figsize=(5.2 * cols, 3.9 * rows + 0.9), squeeze=False,
                                 layout="constrained")
        for ax, (scenario, recs) in zip(axes.flat, groups.items()):
            for r in recs:
                c, err = cmap[r.backend], r.error.vs_oracle if r.error else None
                t = r.time        # (a timed record: by_scenario was given those only)
                lat = (t.latency or t.wall or t) if t else None
                x = lat.median_s if lat else None
                if not (isinstance(err, (int, float)) and math.isfinite(err)
                        and isinstance(x, (int, float)) and math.isfinite(x)) or x <= 0:
                    continue
                ax.scatter(x, max(err, 1e-17), color=c,
                           marker="o" if r.device == "cpu" else "^",
                           facecolors=c if r.precision == "float64" else "none", s=44)
            ax.set_xscale("log"); ax.set_yscale("log")
            ax.set_xlabel("median time per call, latency regime [s]")
            ax.set_ylabel("error vs float64 oracle (0 drawn at 1e-17)", fontsize=8)
            ax.set_title(scenario, loc="left")
            ax.grid(True, which="major", alpha=0.3)
            charts.tidy_log(ax)
        for ax in list(axes.flat)[len(groups):]:
            ax.axis("off")
        handles = [plt.Line2D([], [], color=c, marker="o", ls="", label=b) for b, c in cmap.items()]
        handles += [plt.Line2D([], [], color="k", marker="o", ls="", label="cpu"),
                    plt.Line2D([], [], color="k", marker="^", ls="", label="cuda"),
                    plt.Line2D([], [], color="k", marker="o", ls="", markerfacecolor="none", label="float32 (hollow)")]
        fig.suptitle("Time against error: latency regime (one call + synchronize, wall clock)", fontsize=10)
        fig.legend(handles=handles, loc="outside lower center", ncol=min(6, len(handles)), frameon=False)
        charts.save(fig, path)


def _spread(med: float, iqr: Any) -> tuple[float | None, float | None]:
    # the quartiles themselves are not stored: a whisker of one IQR centred on the median
    if not isinstance(iqr, (int, float)) or not math.isfinite(iqr):
        return None, None
    return max(med - iqr / 2, med * 1e-3), med + iqr / 2


def speed_bar(rec: Record, base: Record | None = None) -> Any:
    """A cell's ``charts.Bar``: its time per call, or with ``base`` base's time over its own
    (a speed-up, the spread of both cells combined); a failed or skipped cell has no value."""
    from compare.render import charts
    t, i, regime = call_time(rec) if rec.status in ("ok", "mismatch") else (None, None, "")
    lo, hi = _spread(t, i) if t else (None, None)
    marks = ([rec.status] if rec.status != "ok" else []) + (["latency regime"] if regime == "latency" else [])
    if base is not None and t:
        bt, bi, _ = call_time(base)
        if bt is None:      # plot_speedup_vs_baseline picks a base with a time per call
            raise ValueError(f"speed_bar: the base {base.key} has no time per call")
        blo, bhi = _spread(bt, bi)
        t, lo, hi = bt / t, (blo or bt) / hi if hi else None, (bhi or bt) / lo if lo else None
    return charts.Bar(rec.backend, rec.variant, t or None, lo, hi, ", ".join(marks))


def speed_panels(records: list[Record]) -> dict[str, list[Record]]:
    """Panel title -> records of one scenario measured together (machine, device, precision,
    parameters); the title names the parameters and machines only where panels differ in them."""
    groups: dict[tuple[str, ...], list[Record]] = {}
    for r in records:
        k = (r.machine or "", r.device, r.precision, json.dumps(plain(r.params), sort_keys=True))
        groups.setdefault(k, []).append(r)
    params = [json.loads(k[3]) or {} for k in groups]
    differ = {p for q in params for p in q if len({json.dumps(o.get(p)) for o in params}) > 1}
    many = len({k[0] for k in groups}) > 1
    return {(f"{k[0]}: " if many else "") + f"{k[1]} {k[2]}"
            + "".join(f", {p}={v}" for p, v in (json.loads(k[3]) or {}).items() if p in differ): rs
            for k, rs in groups.items()}


def plot_speed(records: list[Record], out: Path) -> list[Path]:
    """speed_<scenario>.png: time per call in the throughput regime per framework and variant,
    one panel per device, precision and size; a failed or skipped cell is an empty slot."""
    from compare.render import charts
    written = []
    for scenario, recs in by_scenario(records).items():
        panels = [charts.Panel(title, [speed_bar(r) for r in rs]) for title, rs in speed_panels(recs).items()]
        if not any(b.value for p in panels for b in p.bars):
            continue
        written.append(out / f"speed_{scenario}.png")
        charts.bar_panels(written[-1], f"{scenario}: time per call, throughput regime", "time per call [s]",
                          panels, log=None, fmt=fmt_time, ratios=True,
                          note="throughput regime: k calls then one synchronize, per call; "
                               "bar: median, whiskers: one IQR")
    return written


def plot_speedup_vs_baseline(records: list[Record], path: Path, baseline: str) -> bool:
    """speedup_vs_<baseline>_cpu.png: per scenario, precision and size on the CPU, the baseline's
    (NumPy's) time per call over each framework's (same run, same regime); groups without an ok
    baseline cell left out."""
    from compare.render import charts
    import backends
    who = backends.display_name(baseline)
    panels = []
    for scenario, recs in by_scenario(r for r in records if r.device == "cpu").items():
        for title, rs in speed_panels(recs).items():
            base = next((r for r in rs if r.backend == baseline and r.status == "ok"
                         and r.variant == DEFAULT_VARIANT and call_time(r)[0]), None)
            bars = [speed_bar(r, base) for r in rs if r is not base]
            if base is not None and bars:
                panels.append(charts.Panel(f"{scenario}: {title}", bars))
    if not panels:
        return False
    charts.bar_panels(path, f"CPU: speed-up against {who}, same run, throughput regime",
                      f"{who}'s time per call / the framework's (log)", panels, log=True, better="higher",
                      reference=(1.0, f"{who} = 1"), fmt=lambda v: f"{v:.3g}×",
                      note="whiskers: both cells' IQR combined")
    return True


def plot_outputs(records: list[Record], outputs: dict[int, dict[str, np.ndarray]], out: Path) -> list[Path]:
    """One picture per scenario (``compare.render.figures``) from the runs whose outputs are at hand,
    reference backend first."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import backends
    from compare.render import figures
    ref = backends.reference()
    written = []
    for scenario in by_scenario(records):
        runs = [(r, outputs[i]) for i, r in enumerate(records) if r.scenario == scenario and i in outputs]
        runs.sort(key=lambda ro: ro[0].backend != ref)
        fig = figures.figure(scenario, runs)
        if fig is None:
            continue
        p = out / f"{scenario}.png"
        save_figure(fig, p, dpi=110, metadata={"Software": None})
        plt.close(fig)
        written.append(p)
    return written


def remove_pictures(plots: Path) -> None:
    """An earlier run's pictures in ``plots`` (only the names ``write_plots`` writes), so that
    none stays beside a new run's results."""
    import scenarios
    ours = re.compile(r"(speed_\w+|speedup_vs_\w+_cpu|time_vs_error|" + "|".join(scenarios.SCENARIOS) + r")\.(png|csv)")
    if plots.is_dir() and not plots.is_symlink():
        for old in plots.iterdir():
            if ours.fullmatch(old.name) and old.is_file() and not old.is_symlink():
                old.unlink()


Job = tuple[Callable[..., Any], tuple[Any, ...]]
_jobs: list[Job] = []       # a forked drawing process's jobs, inherited: records do not pickle


def frameworks_loaded() -> list[str]:
    """The modules of a backend's distributions (``Backend.package``, ``related_packages``; the CPU
    baseline's left out: the driver itself computes with it) that this process has imported:
    frameworks start threads of their own, which ``threading`` cannot see."""
    import importlib.metadata
    import sys
    import backends
    dists = {d for b in backends.BACKENDS.values() if not b.is_cpu_baseline
             for d in (b.package, *b.related_packages)}
    return sorted(m for m, ds in importlib.metadata.packages_distributions().items()
                  if m in sys.modules and dists & set(ds))


def plot_jobs(records: list[Record], outputs: dict[int, dict[str, np.ndarray]],
              plots: Path) -> list[Job]:
    """Every picture of a run as its own job (function, arguments), each writing its own files:
    the CPU speed-up, speed per scenario, time against error, each scenario's own picture (its
    records and their outputs, renumbered)."""
    import backends
    base = backends.cpu_baseline()
    groups = by_scenario(records)
    jobs: list[Job] = []
    if base:
        jobs.append((plot_speedup_vs_baseline, (records, plots / f"speedup_vs_{base}_cpu.png", base)))
    jobs += [(plot_speed, (recs, plots)) for recs in groups.values()]
    jobs.append((plot_time_vs_error, (records, plots / "time_vs_error.png")))
    for scenario in groups:
        mine = [i for i, r in enumerate(records) if r.scenario == scenario and i in outputs]
        if mine:
            jobs.append((plot_outputs, ([records[i] for i in mine], {k: outputs[i] for k, i in enumerate(mine)}, plots)))
    return jobs


def _draw(k: int) -> None:
    fn, args = _jobs[k]
    fn(*args)


def write_plots(records: list[Record], outputs: dict[int, dict[str, np.ndarray]], plots: Path,
                workers: int | None = None) -> None:
    """Every picture of a run in ``plots``: speed per scenario, the CPU speed-up against NumPy,
    time against error, and each scenario's own picture of its outputs. The pictures are
    independent, so they are drawn side by side in ``workers`` forked processes (default: one
    per usable core; one, or not Linux: here, in turn); this runs after every cell's clocks."""
    global _jobs
    plots.mkdir(parents=True, exist_ok=True)
    jobs = plot_jobs(records, outputs, plots)
    if workers is None:
        from compare.measuring.environment import usable_cores
        workers = usable_cores()
    import multiprocessing
    import sys
    import threading
    # a fork copies no other thread (nor the locks one holds): only a driver with none forks (no
    # Python thread, and no framework loaded whose native threads Python cannot see: the driver
    # imports none, a test process may), and only on Linux (macOS's libraries are not fork-safe)
    if (min(workers, len(jobs)) <= 1 or threading.active_count() > 1
            or not sys.platform.startswith("linux") or frameworks_loaded()):
        for fn, args in jobs:
            fn(*args)
        return
    import concurrent.futures
    from compare.render import charts
    charts.pyplot()         # imported (and matplotlib's font list built) once, before the fork
    _jobs = jobs
    try:
        with concurrent.futures.ProcessPoolExecutor(min(workers, len(jobs)),
                                                    mp_context=multiprocessing.get_context("fork")) as pool:
            for done in [pool.submit(_draw, k) for k in range(len(jobs))]:
                done.result()
    finally:
        _jobs = []
