"""The saxpy picture: each float32 run's error distribution in ulps."""
from __future__ import annotations

from typing import Any

import numpy as np

import scenarios
from compare.render.figures.runs import Runs, run_label
from scenarios.base import Precision

SC = scenarios.get(__name__.rpartition(".")[2])    # this module draws the scenario it is named after


def figure(runs: Runs) -> Any:
    """Distribution of each float32 run's error in ulps of the exact result (float64 a*x + y
    of the float32 inputs: the product is exact, the sum far below a float32 ulp): <= 0.5 is
    correctly rounded (an FMA), up to ~1 for the two roundings of a*x then + y."""
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    edges = np.linspace(0.0, 1.5, 31)
    p = SC.params(runs[0][0].params)
    runs = [(r, o) for r, o in runs if r.precision == "float32"]
    if not runs:
        return None
    for r, o in runs:
        inputs = SC.inputs(p, r.precision)
        ref = SC.oracle(p, inputs, Precision(r.precision))["out"]
        out = np.asarray(o["out"], np.float64)
        if out.shape != ref.shape:
            continue
        ulp = np.spacing(np.abs(ref).astype(np.float32)).astype(np.float64)
        ulps = np.abs(out - ref) / np.maximum(ulp, np.finfo(np.float64).tiny)
        # (matplotlib's stubs type bins as a Sequence, which an ndarray is not)
        ax.hist(np.clip(ulps, 0, edges[-1]), bins=edges, histtype="step", lw=1.2,  # type: ignore[arg-type]
                weights=np.full(ulps.size, 100.0 / max(ulps.size, 1)),
                label=f"{run_label(r)} (max {ulps.max():.2f})")
    ax.axvline(0.5, color="0.4", ls=":", lw=1)
    ax.set_xlabel("|out - exact| in float32 ulps of the exact result")
    ax.set_ylabel("% of elements"); ax.set_yscale("log")
    ax.set_title(f"saxpy float32 error distribution (n={p.n}, inputs={p.inputs}); "
                 "identical runs overlap", fontsize=8)
    ax.legend(fontsize=6)
    fig.tight_layout()
    return fig
