"""The horizon sweep as small multiples (the site's gradients page): memory or time against the
horizon, one panel per framework with its variants and precisions (one axes of 20-30 lines hid
them in each other), and the gradient quality panel on its own. Same data and definitions as
compare/sweep/horizon.py's three-panel plot, which the sweep's own report keeps."""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from backends.base import DEFAULT_VARIANT
from compare.files import save_figure
from compare.render.figure_check import place_legends
from compare.results.record import Record
from compare.sweep import horizon
from compare.sweep.points import sweeps
from compare.sweep.rows import knob, knob_value, label, need, throughput_s, wall_s

LOOK = {
    "memory": "Device memory against the number of steps, one panel per framework: its default (solid) and "
              "memory-saving variants (dotted), float32 (triangles) and float64 (circles), and the dashed "
              "black floor a float32 tape of every step's state needs. A line along the floor keeps every state; a "
              "flat line does not grow with the horizon.",
    "time": "Time per loss and gradient against the number of steps, one panel per framework and its "
            "variants: a slope of one on these log axes is time linear in the horizon.",
    "quality": "The share of gradients that agree with float64 finite differences against the number of "
               "steps, per contact and precision (the line: the mean over frameworks; the band: their range). "
               "A narrow band is the frameworks agreeing with one another: a loss of agreement there is the "
               "problem's, not a port's.",
}


def panels(records: list[Record], device: str, path: Path, scenario: str, colors: dict[str, str],
           plt: Any, what: str) -> bool:
    """``what`` = 'memory' or 'time' against the horizon, small multiples per framework."""
    groups = horizon.series(records, device, scenario)
    want = dict(json.loads(label(scenario, "horizon_memory", "{}")))
    per: dict[str, list[tuple[tuple, list[Record]]]] = {}
    for key, rows in groups.items():
        if all(need(rows[0], "params").get(k) == v for k, v in want.items()):
            per.setdefault(key[0], []).append((key, rows))
    if not per:
        return False
    every = [r for rows in groups.values() for r in rows]
    kname = knob(every[0]).name or "size"
    order = [b for b in colors if b in per] + sorted(set(per) - set(colors))
    cols = min(5, len(order))
    nrows = math.ceil(len(order) / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(2.9 * cols + 0.6, 2.5 * nrows + 0.9), sharex=True,
                             sharey=True, squeeze=False)
    flat = list(axes.ravel())
    for ax in flat[len(order):]:
        ax.set_visible(False)
    tape = sweeps(scenario)
    for ax, backend in zip(flat, order):
        for (_, variant, prec, _), rows in per[backend]:
            n = [knob_value(r) for r in rows]
            if what == "memory":
                ys = [m / 2**20 if (m := horizon.memory(r)[0]) else math.nan for r in rows]
            else:
                ys = [throughput_s(r) or wall_s(r) or math.nan for r in rows]
            ax.plot(n, ys, ("-" if variant == DEFAULT_VARIANT else ":") + ("^" if prec == "float32" else "o"),
                    color=colors.get(backend), ms=4, lw=1.2,
                    label=f"{variant}{'' if prec == 'float32' else ' f64'}")
            floor = tape.state_bytes_per_step(prec) if what == "memory" and prec == "float32" else None
            if floor and "tape floor (f32)" not in ax.get_legend_handles_labels()[1]:      # once a panel
                ax.plot(n, [floor * horizon.items(r) * knob_value(r) / 2**20 for r in rows], "k--", lw=0.8,
                        label="tape floor (f32)")
        ax.set_title(backend, fontsize=9)
        ax.set_xscale("log"); ax.set_yscale("log"); ax.grid(True, which="both", alpha=0.3)
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=5)
    for ax in flat[:len(order)]:
        if ax.get_subplotspec().is_first_col():
            ax.set_ylabel("memory [MiB]" if what == "memory" else "time per call [s]", fontsize=8)
        ax.set_xlabel(f"{kname}", fontsize=8)
    where = ", ".join(f"{k}={v}" for k, v in want.items())
    fig.suptitle(f"{'device memory' if what == 'memory' else 'time per call'} against the horizon "
                 f"({where}, {device})", fontsize=9)
    place_legends(flat[:len(order)], fontsize=5)        # each clear of its panel's data, else below it
    save_figure(fig, path, dpi=100)
    plt.close(fig)
    return True


def quality(records: list[Record], device: str, path: Path, scenario: str, plt: Any) -> bool:
    """FD agreement against the horizon per contact and precision: mean over frameworks, band min..max."""
    cells = horizon.gradient_cells(records, device, scenario)
    if not cells:
        return False
    kname = knob(cells[0]).name or "size"
    extra = [k for k in horizon.varying(cells, kname) if k not in ("batch",)]
    shares: dict[tuple[str, str], dict[float, list[float]]] = {}
    for r in cells:
        if (s := r.fd_agreement) is not None:
            key = (", ".join(f"{k}={need(r, 'params').get(k)}" for k in extra), r.precision)
            shares.setdefault(key, {}).setdefault(knob_value(r), []).append(s)
    if not shares:
        return False
    fig, ax = plt.subplots(figsize=(6.5, 3.8))
    for (what, prec), pts in sorted(shares.items()):
        n = sorted(pts)
        line, = ax.plot(n, [100 * sum(pts[k]) / len(pts[k]) for k in n], "-" if prec == "float32" else "--",
                        marker="o", ms=4, label=f"{what} {prec}")
        ax.fill_between(n, [100 * min(pts[k]) for k in n], [100 * max(pts[k]) for k in n],
                        color=line.get_color(), alpha=0.15)
    ax.set_xscale("log"); ax.set_xlabel(f"{kname} (log)"); ax.set_ylim(-5, 105)
    ax.set_ylabel("gradients agreeing with float64 FD [%]", fontsize=8)
    ax.set_title(f"gradient quality against the horizon ({device}): mean over frameworks, band = min..max", fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6, ncol=2)
    place_legends([ax], fontsize=6, ncol=2)
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return True
