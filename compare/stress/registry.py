"""Every stress experiment by name: each scenario's own (a module of this package named after
the scenario, with ``EXPERIMENTS``, in the scenarios' registry order), then the generic ones that
name no scenario. Experiments import neither the driver nor the store, so the validating loader
(compare/results/records.py) reads their page hooks from here without loading the suite."""
from __future__ import annotations

import importlib
import importlib.util

import scenarios
from compare.stress import generic
from compare.stress.numerics import Experiment


def _own(name: str) -> dict[str, Experiment]:
    """The experiments of scenario ``name``: its module's, or none."""
    module = f"{__package__}.{name}"
    found = importlib.util.find_spec(module) is not None
    return getattr(importlib.import_module(module), "EXPERIMENTS", {}) if found else {}


BY_SCENARIO: dict[str, dict[str, Experiment]] = {n: e for n in scenarios.SCENARIOS if (e := _own(n))}


def experiments() -> dict[str, Experiment]:
    """The registry: every scenario's experiments (registry order), then the generic ones."""
    reg: dict[str, Experiment] = {}
    for name in scenarios.SCENARIOS:
        reg.update(BY_SCENARIO.get(name, {}))
    reg.update(generic.EXPERIMENTS)
    return reg
