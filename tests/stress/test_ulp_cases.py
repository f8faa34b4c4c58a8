"""compare/stress/ulp_cases.py: the ulps experiment's cases by scenario (fast tier)."""
from __future__ import annotations

import scenarios
from compare.stress.ulp_cases import ULP_CASES, ulp_cases


def test_saxpy_has_both_input_kinds_at_the_quick_or_full_size():
    quick = ulp_cases("saxpy", True)
    assert [(o["n"], o["inputs"], out, label) for o, out, label in quick] == [
        (100_003, "linspace", "out", "saxpy (linspace)"), (100_003, "random", "out", "saxpy (random)")]
    assert {o["n"] for o, _, _ in ulp_cases("saxpy", False)} == {1_000_000}


def test_sdf_is_the_default_image_labelled_by_its_scenario():
    assert ulp_cases("sdf", True) == [({"width": 512, "height": 512}, "image", "sdf")]


def test_a_scenario_without_cases_has_none_and_every_case_names_a_scenario():
    assert ulp_cases("particles", True) == [] and ulp_cases("nope", False) == []
    assert set(ULP_CASES) <= set(scenarios.SCENARIOS)
    for name in ULP_CASES:                       # the overrides are the scenario's parameters
        sc = scenarios.get(name)
        for over, _, _ in ulp_cases(name, True):
            sc.params(over)
