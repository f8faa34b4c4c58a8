"""The sdf picture: the oracle image and each run's difference to it."""
from __future__ import annotations

from typing import Any

import numpy as np

import scenarios
from compare.render.figures.runs import Runs, pick_runs, run_label
from scenarios.base import UNIT_ROUNDOFF, Precision
from scenarios.sdf import TOLERANCE_ULPS

SC = scenarios.get(__name__.rpartition(".")[2])    # this module draws the scenario it is named after


def figure(runs: Runs) -> Any:
    """The float64 oracle image, then |image - oracle| per backend (log colour, one scale for
    all panels, the maximum also as a fraction of the derived tolerance)."""
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm
    runs = [(r, o) for r, o in pick_runs(runs, 8) if "image" in o and np.ndim(o["image"]) == 2]
    if not runs:
        return None
    p = SC.params(runs[0][0].params)
    ref = SC.oracle(p, {}, Precision(runs[0][0].precision))["image"]
    diffs = []
    for r, o in runs:
        img = np.asarray(o["image"], np.float64)
        diffs.append(np.abs(img - ref) if img.shape == ref.shape else None)
    tiny = 1e-12
    top = max([float(d.max()) for d in diffs if d is not None] + [tiny * 10])
    cols = min(3, len(runs) + 1)
    rows = -(-(len(runs) + 1) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.6 * cols, 3.3 * rows), squeeze=False)
    ax = axes.flat[0]
    im = ax.imshow(ref, origin="lower", cmap="magma")
    fig.colorbar(im, ax=ax, label="exp(-18|d|)", shrink=0.85)
    ax.set_title(f"float64 oracle, {p.width}x{p.height}", fontsize=8)
    vmin = max(tiny, top * 1e-6)
    norm = LogNorm(vmin=vmin, vmax=top)
    for ax, (r, _), d in zip(axes.flat[1:], runs, diffs):
        if d is None:
            ax.set_title(f"{run_label(r)}: shape differs", fontsize=8); continue
        im = ax.imshow(np.maximum(d, vmin), origin="lower", cmap="viridis", norm=norm)
        fig.colorbar(im, ax=ax, label="|image - oracle|", shrink=0.85)
        tol = TOLERANCE_ULPS * (UNIT_ROUNDOFF[Precision(r.precision)] + UNIT_ROUNDOFF[Precision.FLOAT64])
        ax.set_title(f"{run_label(r)}\nmax {d.max():.2g} = {d.max() / tol:.2g} x derived tolerance",
                     fontsize=8)
    for ax in axes.flat:
        ax.set_xlabel("pixel column i", fontsize=7); ax.set_ylabel("pixel row j", fontsize=7)
        ax.tick_params(labelsize=6)
    for ax in axes.flat[len(runs) + 1:]:
        ax.set_visible(False)
    fig.suptitle("sdf: oracle image and each backend's difference to it", fontsize=10)
    fig.tight_layout()
    return fig
