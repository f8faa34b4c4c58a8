"""Each scenario's picture of its results for the report (DIR/<scenario>.png): a module of this
package named after the scenario, with ``figure(runs)``, drawn from the runs that kept their
outputs with the scenario's own oracle, so it shows what the results mean; the driver only saves
it. A scenario without a module has none."""
from __future__ import annotations

import importlib
import pkgutil
from typing import Any, Callable

import scenarios

from .runs import Runs

FIGURES: dict[str, Callable[[Runs], Any]] = {
    m.name: importlib.import_module(f"{__name__}.{m.name}").figure
    for m in pkgutil.iter_modules(__path__) if m.name in scenarios.SCENARIOS}


def figure(scenario: str, runs: Runs) -> Any:
    """A matplotlib Figure of ``scenario``'s results, or None. ``runs``: (record, outputs) of
    every cell that kept its outputs, reference backend first."""
    draw = FIGURES.get(scenario)
    return draw(runs) if draw is not None and runs else None
