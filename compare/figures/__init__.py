"""Each scenario's picture of its results for the report (DIR/<scenario>.png), registered by
scenario name: drawn from the runs that kept their outputs with the scenario's own oracle, so
it shows what the results mean; the driver only saves it. A scenario not listed has none."""
from __future__ import annotations

from typing import Any, Callable

from . import particles, projectile, saxpy, sdf
from .runs import Runs

FIGURES: dict[str, Callable[[Runs], Any]] = {
    "saxpy": saxpy.figure, "sdf": sdf.figure, "particles": particles.figure, "projectile": projectile.figure}


def figure(scenario: str, runs: Runs) -> Any:
    """A matplotlib Figure of ``scenario``'s results, or None. ``runs``: (record, outputs) of
    every cell that kept its outputs, reference backend first."""
    draw = FIGURES.get(scenario)
    return draw(runs) if draw is not None and runs else None
