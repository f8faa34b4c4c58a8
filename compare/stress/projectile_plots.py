"""The projectile stress experiments on the page: the lr matrix above projectile-lr's table, the
rows that table keeps, and the three plots, drawn from the series kept in stress.json (so merged
parts redraw)."""
from __future__ import annotations

from pathlib import Path
from typing import BinaryIO

from compare.render.figure_check import place_legends
from compare.stress.numerics import ORACLE, Finding, Series, Style, log_floor
from compare.stress.projectile_rules import CONTACTS, FD_AGREE
from compare.stress.projectile_tasks import OPTIMISERS

LOOK = {
    "projectile-lr": "The loss after the descent over the loss before it, against the learning rate, per "
                     "contact and optimiser: above 1 the descent diverged. Gradient descent should turn at "
                     "the predicted boundary lr* = 2/lambda_max; frameworks whose curves lie on one another "
                     "diverge at the same learning rate.",
    "projectile-gradient": "The gradient against float64 finite differences as the step h shrinks, hard and "
                           "soft contact, and d loss / d vy0 along a scan: finite differences agree only "
                           "below a small h, and hard contact makes the loss jump where no gradient predicts it.",
    "projectile-horizon": "|grad| and the float32 gradient's error relative to float64 against the number "
                          "of steps, per contact: the gradient grows as a power of the horizon and the float32 "
                          "error with it; an error that large can still be within the bound derived for a "
                          "gradient that ill-conditioned (the row says which).",
}


def lr_matrix(rows: list[Finding]) -> str:
    """projectile-lr as one line per (backend, device, optimiser, contact): C/S/D per lr, under
    its legend (goes above the row table on the page). Reads the findings as stored (the file)."""
    from tabulate import tabulate
    cells_: dict[tuple, dict[float, str]] = {}
    lrs: set[float] = set()
    for r in rows:
        if r["experiment"] != "projectile-lr" or not r["setting"].count("lr="):
            continue
        parts = dict(p.split("=", 1) for p in r["setting"].split(", ")[1:])
        m = r["setting"].split(",", 1)[0]
        lr = float(parts["lr"]); lrs.add(lr)
        cells_.setdefault((r["backend"], r["device"], r["precision"], m, parts["contact"]), {})[lr] = \
            {"converged": "C", "stalled": "S", "diverged": "**D**"}.get(r["verdict"], "E")
    table = "" if not cells_ else tabulate(
        [[*k, *(v.get(lr, "") for lr in sorted(lrs))] for k, v in cells_.items()],
        headers=["backend", "device", "precision", "optimiser", "contact", *[f"lr {lr:g}" for lr in sorted(lrs)]],
        tablefmt="github", disable_numparse=True)
    return ("C converged, S stalled, **D** diverged (GD: the backend's own device loop; "
            f"clip, adam: host loop with the backend's gradient; {ORACLE}: float64 Python).\n\n" + table)


def lr_table_rows(rows: list[Finding]) -> list[Finding]:
    """The rows the page tables below the matrix: predictions and boundaries (not per-lr rows)."""
    return [r for r in rows if "lr=" not in r["setting"]]


def plot_projectile_lr(series: Series, path: Path | BinaryIO, style: Style) -> None:
    import matplotlib.pyplot as plt
    hist = series.get("histories", {})
    methods = OPTIMISERS
    fig, axes = plt.subplots(3, 3, figsize=(12, 9), sharex=True)
    for key, h in sorted(hist.items()):
        b, d, m, c, lr = key.split("/")
        ax = axes[methods.index(m)][CONTACTS.index(c)]
        ax.plot(range(len(h)), log_floor(h, 1e-30), ls="-" if b != ORACLE else ":", lw=1, label=f"{b} lr={lr}")
    for i, m in enumerate(methods):
        for j, c in enumerate(CONTACTS):
            ax = axes[i][j]
            ax.set_yscale("log"); ax.set_title(f"{m}, contact={c}", fontsize=9); ax.grid(True, alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("iteration")
    place_legends([ax for row in axes for ax in row if ax.lines], fontsize=5)    # clear of the curves
    fig.savefig(path, dpi=100); plt.close(fig)


def plot_projectile_gradient(series: Series, path: Path | BinaryIO, style: Style) -> None:
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(2, 3, figsize=(13, 7.5))
    for j, c in enumerate(CONTACTS):
        ax = axes[0][j]
        for lbl, rel in sorted(series["lines"].items()):
            if lbl.endswith("/" + c):
                ax.plot(series["h"], log_floor(rel), lw=1, ls="-" if "float32" in lbl else ":",
                        label=lbl.rsplit("/", 1)[0], **style(lbl))
        ax.axhline(FD_AGREE, color="k", ls="--", lw=0.8)
        if c in series.get("gd_step", {}):
            ax.axvline(series["gd_step"][c], color="r", lw=0.8, label="one GD step at lr 0.01")
        ax.set_xscale("log"); ax.set_yscale("log"); ax.set_title(f"contact={c}: |g - g_FD(h)|/|g|", fontsize=9)
        ax.set_xlabel("FD step h"); ax.grid(True, which="both", alpha=0.3)
    for j, c in enumerate(("hard", "soft")):
        ax = axes[1][j]
        for lbl, s in sorted(series["scans"].items()):
            if lbl.endswith("/" + c):
                ax.plot(s["vy"], s["loss"], lw=1, label=lbl.rsplit("/", 1)[0])
        ax.set_title(f"contact={c}: loss along vy0 (vx0 = 2)", fontsize=9); ax.set_xlabel("vy0"); ax.legend(fontsize=6)
        ax2 = axes[1][2]
        for lbl, s in sorted(series["scans"].items()):
            if lbl.endswith("/" + c):
                ax2.plot(s["vy"], s["dvy"], lw=1, ls="-" if c == "soft" else "--", label=f"{c} {lbl.rsplit('/', 1)[0]}")
        ax2.set_title("d loss / d vy0 along the scan (AD)", fontsize=9); ax2.set_xlabel("vy0"); ax2.legend(fontsize=6)
    place_legends(list(axes[0]), fontsize=5)          # the FD panels' legends clear of the curves
    fig.savefig(path, dpi=100); plt.close(fig)


def plot_projectile_horizon(series: Series, path: Path | BinaryIO, style: Style) -> None:
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for lbl, s in sorted(series.items()):
        ls = {"none": "-", "hard": "--", "soft": ":"}[lbl.rsplit("/", 1)[1]]
        axes[0].plot(s["steps"], log_floor(s["grad"]), ls=ls, lw=1, label=lbl, **style(lbl))
        axes[1].plot(s["steps"], log_floor(s["rel"]), ls=ls, lw=1, label=lbl, **style(lbl))
    axes[0].set_ylabel("|grad| (float32)"); axes[1].set_ylabel("float32 gradient rel. error vs float64")
    for ax in axes:
        ax.set_xscale("log"); ax.set_yscale("log"); ax.set_xlabel("steps (dt = 0.025)")
        ax.grid(True, which="both", alpha=0.3)
    place_legends(list(axes), fontsize=5)             # clear of the curves
    fig.savefig(path, dpi=110); plt.close(fig)
