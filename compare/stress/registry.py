"""Every stress experiment by name: each scenario's own (registered here by scenario name, in the
scenarios' registry order), then the generic ones that name no scenario. Experiments import
neither the driver nor the store, so the validating loader (compare/records.py) reads their page
hooks from here without loading the suite."""
from __future__ import annotations

import scenarios
from compare.stress import generic, particles, projectile
from compare.stress.numerics import Experiment

BY_SCENARIO: dict[str, dict[str, Experiment]] = {"particles": particles.EXPERIMENTS,
                                                 "projectile": projectile.EXPERIMENTS}


def experiments() -> dict[str, Experiment]:
    """The registry: every scenario's experiments (registry order), then the generic ones."""
    reg: dict[str, Experiment] = {}
    for name in scenarios.SCENARIOS:
        reg.update(BY_SCENARIO.get(name, {}))
    reg.update(generic.EXPERIMENTS)
    return reg
