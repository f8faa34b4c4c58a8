"""The particles picture: trajectories and each run's final-state error against its bound."""
from __future__ import annotations

import dataclasses
from typing import Any, cast

import numpy as np

import scenarios
from compare.render.figures.runs import Runs, pick_runs, run_label
from scenarios.base import Precision
from scenarios.particles import Particles

# this module draws the scenario it is named after (the registry's entry of that name is a Particles)
SC = cast(Particles, scenarios.get(__name__.rpartition(".")[2]))


def figure(runs: Runs) -> Any:
    """Left: trajectories (the run's own if it recorded them, else the float64 oracle's from the
    same rounded inputs) ending at each backend's final positions. Right: each backend's
    per-particle final-state error against the oracle and the derived bound."""
    import matplotlib.pyplot as plt
    runs = pick_runs(runs, 6)
    rec0, out0 = runs[0]
    p = SC.params(rec0.params)
    if p.n * (p.steps + 1) > 5e7:              # the oracle would be too big for a picture
        return None
    # one float64 oracle per precision (with every frame), for the trajectories and the errors
    refs = {prec: SC.oracle(dataclasses.replace(p, record_every=1), SC.inputs(p, prec), Precision(prec))
            for prec in {r.precision for r, _ in runs}}
    ref = refs[rec0.precision]
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(11, 4.6))
    shown = np.unique(np.linspace(0, p.n - 1, min(p.n, 48)).astype(int))
    own = "traj_x" in out0
    tx, ty = (np.asarray(out0[k]) for k in ("traj_x", "traj_y")) if own else (ref["traj_x"], ref["traj_y"])
    ax.plot(tx[:, shown], ty[:, shown], lw=0.5, alpha=0.7)
    markers = "osd^v<"
    for (r, o), m in zip(runs, markers):
        ax.scatter(o["x"], o["y"], s=9, marker=m, facecolors="none", edgecolors="k", lw=0.5,
                   label=f"{run_label(r)} final")
    ax.set_xlim(-1, 1); ax.set_ylim(bottom=0)
    ax.set_xlabel("x [m]"); ax.set_ylabel("y [m]")
    ax.set_title(f"{len(shown)} of {p.n} trajectories over {p.steps} steps "
                 f"({run_label(rec0) if own else 'float64 oracle, same rounded inputs'})", fontsize=8)
    ax.legend(fontsize=6, loc="upper right")
    idx = np.arange(p.n)
    for (r, o), m in zip(runs, markers):
        err = SC.state_error(o, refs[r.precision])
        ax2.scatter(idx, np.maximum(err, 1e-18), s=6, marker=m, label=run_label(r), alpha=0.7)
    ax2.plot(idx, ref["error_bound"], "r-", lw=1, label=f"derived bound ({rec0.precision})")
    ill = ref["ill_conditioned"]
    if ill.any():
        ax2.scatter(idx[ill], ref["error_bound"][ill], marker="x", color="r", s=14,
                    label=f"ill-conditioned ({int(ill.sum())}, not checked)")
    ax2.set_yscale("log"); ax2.set_xlabel("particle index")
    ax2.set_ylabel("max |state - float64 oracle| (0 drawn at 1e-18)")
    ax2.set_title("final-state error per particle", fontsize=8)
    ax2.legend(fontsize=6)
    fig.tight_layout()
    return fig
