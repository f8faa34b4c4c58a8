"""The projectile picture: each run's descent against the oracle's, and its distance to it."""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

import scenarios
from compare.render.figures.runs import Runs, run_label
from scenarios.base import Precision

SC = scenarios.get(__name__.rpartition(".")[2])    # this module draws the scenario it is named after


def figure(runs: Runs) -> Any:
    """Left: loss against descent iteration for every run over the float64 oracle's descent.
    Right: each run's relative distance to the oracle's history (the oracle run from the same
    rounded inputs) and the derived bound for its precision."""
    import matplotlib.pyplot as plt
    rec0 = runs[0][0]
    p = SC.params(rec0.params)
    if p.batch > 1:        # draw row 0 of every batch: the seed case
        p = dataclasses.replace(p, batch=1)
        runs = [(r, {k: np.asarray(v)[:, 0] if k == "loss_history" else np.asarray(v)[0]
                     for k, v in o.items()}) for r, o in runs]
    refs = {prec: SC.oracle(p, SC.inputs(p, prec), Precision(prec)) for prec in {r.precision for r, _ in runs}}
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    ref = refs.get(Precision.FLOAT64, next(iter(refs.values())))["loss_history"]
    ax.plot(np.arange(ref.size), np.maximum(ref, 1e-30), "k--", lw=2, alpha=0.5, label="float64 oracle")
    for prec, o in refs.items():
        scale = np.maximum(np.abs(o["loss_history"]), 1e-300)
        ax2.plot(np.arange(scale.size), np.maximum(o["tol_history"] / scale, 1e-18), "k",
                 ls=":" if prec == "float32" else "-.", lw=1.5,
                 label=f"derived bound, {prec}")
    for r, o in runs:
        h = np.asarray(o["loss_history"], np.float64)
        line, = ax.plot(np.arange(h.size), np.maximum(h, 1e-30), lw=1, label=run_label(r))
        ho = refs[r.precision]["loss_history"]
        if h.shape == ho.shape:
            with np.errstate(invalid="ignore", divide="ignore"):
                rel = np.abs(h - ho) / np.maximum(np.abs(ho), 1e-300)
            ax2.plot(np.arange(h.size), np.maximum(rel, 1e-18), lw=1, color=line.get_color(),
                     label=run_label(r))
    ax.set_yscale("log"); ax.set_xlabel("gradient-descent iteration"); ax.set_ylabel("loss [m²]")
    ax.set_title(f"projectile: contact={p.contact}, lr={p.lr:g}, {p.steps} steps", fontsize=9)
    ax.legend(fontsize=6, ncol=2)
    ax2.set_yscale("log"); ax2.set_xlabel("gradient-descent iteration")
    ax2.set_ylabel("|loss - oracle| / oracle (0 drawn at 1e-18)")
    ax2.set_title("distance to the oracle's descent, same rounded inputs", fontsize=9)
    ax2.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    return fig
