"""The particles experiments' plots (compare/stress/particles.py), drawn from the series kept in
stress.json, and the sentence under each that says what to see in it (``LOOK``)."""
from __future__ import annotations

import math
from pathlib import Path
from typing import BinaryIO

import numpy as np

from compare.render.figure_check import place_legends
from compare.stress.numerics import Series, Style, log_floor

LOOK = {
    "particles-dt": "One panel per framework and device: its float32 (solid) and float64 (dotted) median "
                    "state error against dt, under the black float64 discretisation error. A float32 curve "
                    "far below the black line at every dt means the time step, not float32 rounding, limits "
                    "the accuracy; a curve reaching it would mean a smaller dt no longer helps in float32.",
    "particles-long": "Total energy E(T)/E(0) against the number of steps, one line per framework and "
                      "precision: with bounce below 1 no line may rise above 1 (energy gained); with bounce "
                      "above 1 the energy grows until the state is non-finite (gaps).",
    "particles-divergence": "The distance between the float32 and the float64 port over time: where the "
                            "median (solid) crosses the dashed particle radius, the two precisions have taken "
                            "different contact histories, which float32 rounding permits from different "
                            "inputs; the flips table says whether any happened where the bound forbids it.",
}


def _panels(n: int, plt, width: float = 2.6, height: float = 2.3):   # type: ignore[no-untyped-def]
    """A grid of ``n`` panels sharing both axes, at most five a row; unused panels hidden."""
    cols = min(5, max(1, n))
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(width * cols + 0.6, height * rows + 0.8),
                             sharex=True, sharey=True, squeeze=False)
    flat = list(axes.ravel())
    for ax in flat[n:]:
        ax.set_visible(False)
    return fig, flat[:n]


def plot_particles_dt(series: Series, path: Path | BinaryIO, style: Style) -> None:
    """Small multiples: one panel per framework and device, both precisions in it, the float64
    discretisation error drawn in every panel (20-30 lines in one axes hid each other and the
    discretisation line under the legend)."""
    import matplotlib.pyplot as plt
    groups: dict[str, list[str]] = {}
    for lbl in sorted(series["lines"]):
        backend, device = lbl.split("/")[:2]
        groups.setdefault(f"{backend} {device}", []).append(lbl)
    fig, axes = _panels(len(groups), plt)
    for ax, (name, labels) in zip(axes, groups.items()):
        ax.plot(series["dt"], log_floor(series["discretisation"]), "k-", lw=2, label="discretisation (float64)")
        for lbl in labels:
            line = series["lines"][lbl]
            prec = lbl.rsplit("/", 1)[-1]
            ax.plot(line["dt"], log_floor(line["median"]), ls="-" if prec == "float32" else ":", lw=1.2,
                    label=prec, **style(lbl))
        ax.set_title(name, fontsize=9)
        ax.set_xscale("log"); ax.set_yscale("log"); ax.grid(True, which="both", alpha=0.3)
        ax.tick_params(labelsize=7)
    axes[0].invert_xaxis()          # shared: every panel runs from the largest dt to the smallest
    for ax in axes:
        if ax.get_subplotspec().is_last_row() or ax is axes[-1]:
            ax.set_xlabel("dt [s] (T = 3 s)", fontsize=8)
        if ax.get_subplotspec().is_first_col():
            ax.set_ylabel("median |state error|", fontsize=8)
    fig.suptitle("float32 rounding against time discretisation (float64 error 0 drawn at 1e-18)", fontsize=9)
    axes[0].legend(fontsize=6)
    place_legends(axes[:1], fontsize=6)     # the first panel's legend, clear of its curves
    fig.savefig(path, dpi=110); plt.close(fig)


def plot_particles_long(series: Series, path: Path | BinaryIO, style: Style) -> None:
    import matplotlib.pyplot as plt
    bounces = sorted({float(k.rsplit("bounce=", 1)[1]) for k in series})
    fig, axes = plt.subplots(1, len(bounces), figsize=(5.2 * len(bounces), 4.2), squeeze=False)
    for key, s in sorted(series.items()):
        ax = axes[0][bounces.index(float(key.rsplit("bounce=", 1)[1]))]
        ax.plot(s["steps"], log_floor(s["ratio"]), ls="-" if "float32" in key else ":",
                label=key.rsplit("/bounce", 1)[0], lw=1, **style(key))
    for ax, b in zip(axes[0], bounces):
        ax.set_title(f"bounce {b:g}: " + ("must not gain energy" if b < 1 else "unstable (gaps: non-finite)"))
        finite = any(np.isfinite(y).any() for line in ax.lines for y in [np.asarray(line.get_ydata(), float)])
        if not finite:
            ax.text(0.5, 0.5, "non-finite energy at every length", ha="center", transform=ax.transAxes)
        ax.set_xscale("log"); ax.set_yscale("log" if finite else "linear"); ax.grid(True, which="both", alpha=0.3)
        ax.set_xlabel("steps (dt = 0.01)"); ax.set_ylabel("total E(T) / E(0)"); ax.legend(fontsize=6)
    place_legends(list(axes[0]), fontsize=6, ncol=2)       # clear of the curves, else below the axes
    fig.savefig(path, dpi=110); plt.close(fig)


def plot_particles_divergence(series: Series, path: Path | BinaryIO, style: Style) -> None:
    import matplotlib.pyplot as plt
    bounces = sorted({k.rsplit("bounce=", 1)[1] for k in series}, key=float)
    fig, axes = plt.subplots(1, len(bounces), figsize=(6 * len(bounces), 4.5), squeeze=False)
    for lbl, s in sorted(series.items()):
        ax = axes[0][bounces.index(lbl.rsplit("bounce=", 1)[1])]
        name = lbl.rsplit("/bounce", 1)[0]
        st = style(lbl)
        st["marker"] = None
        ax.plot(s["step"], log_floor(s["median"]), label=f"{name} median", **st)
        ax.plot(s["step"], log_floor(s["max"]), ls=":", label=f"{name} max", **st)
    for ax, b in zip(axes[0], bounces):
        ax.axhline(0.03, color="k", lw=0.8, ls="--", label="radius")
        ax.set_xscale("log"); ax.set_yscale("log"); ax.grid(True, which="both", alpha=0.3)
        ax.set_title(f"bounce {b}: float32 vs float64 port (0 drawn at 1e-18)", fontsize=9)
        ax.set_xlabel("step"); ax.set_ylabel("|pos float32 - pos float64| over particles [m]")
        ax.legend(fontsize=6)
    place_legends(list(axes[0]), fontsize=6, ncol=2)       # clear of the curves, else below the axes
    fig.savefig(path, dpi=110); plt.close(fig)


