"""compare/stress/registry.py: every stress experiment by name, each scenario's then the generic
ones (fast tier)."""
from __future__ import annotations

import scenarios
from compare.stress import generic, registry


def test_every_scenarios_experiments_in_registry_order_then_the_generic_ones():
    names = list(registry.experiments())
    own = [n for sc in scenarios.SCENARIOS for n in registry.BY_SCENARIO.get(sc, {})]
    assert names == own + list(generic.EXPERIMENTS)
    assert set(registry.BY_SCENARIO) <= set(scenarios.SCENARIOS)
    assert {"particles", "projectile"} <= set(registry.BY_SCENARIO)


def test_every_experiment_is_registered_under_its_own_name_and_runs():
    for name, e in registry.experiments().items():
        assert e.name == name and e.title and callable(e.run)


def test_a_scenario_without_a_stress_module_has_none():
    assert registry._own("no_such_scenario") == {}
