"""``Scenario.timings_ranked_on`` against the site's rules: the driver caps the processes of a cell
at its scenario's defaults on a device that attribute leaves out (``compare.suites.driver.caps``:
its first result's alone), so no timed row may read such a cell, and every device it names must
have a row that does. Read from the published H100 and CPU stores with the rules' own picks."""
from __future__ import annotations

import pytest

import scenarios
from compare.results.record import Record
from compare.site import data, matrix, questions
from measurement_doc import machine

pytestmark = pytest.mark.xdist_group("measurement-claims")

# the rows that rank a timing regime: not the deterministic ones (error shares, bytes) and not
# the aggregates over scenarios (the accuracy's error, the compile row's cold first results, which
# the capped cells keep: ``repeats.COLD`` processes of the default variant)
TIMED = [r for r in questions.RULES if not r.exact and r.key not in matrix.AGGREGATES]


def _picked(key: str) -> list[tuple[str, str, Record]]:
    """(rule, device, record) of every timed row on every device of the store."""
    m = machine(key)
    return [(rule.key, device, r) for rule in TIMED for device in m.devices()
            if rule.device in ("", device) for r in rule.pick(m, device)]


def _unranked_here(r: Record) -> bool:
    on = scenarios.get(r.scenario).timings_ranked_on
    return on is not None and r.device not in on and data.at_defaults(r)


@pytest.mark.parametrize("key", ["h100", "cpu"])
def test_no_timed_row_reads_a_cell_whose_timings_are_said_unranked(key: str) -> None:
    picked = _picked(key)
    assert picked, f"{key}: no timed row picked anything"
    wrong = [(rule, device, r.scenario, r.backend, r.variant) for rule, device, r in picked if _unranked_here(r)]
    assert not wrong, f"rows read timings the driver caps (Scenario.timings_ranked_on): {wrong}"


def test_every_device_said_to_rank_a_scenario_has_a_row_that_does() -> None:
    """The other way round: a device in ``timings_ranked_on`` is one where a timed row reads the
    scenario at its defaults (the CPU-only and busy rows read the projectile's)."""
    picked = [(device, r) for key in ("h100", "cpu") for _, device, r in _picked(key)]
    for name, sc in scenarios.SCENARIOS.items():
        for device in sc.timings_ranked_on or ():
            assert any(r.scenario == name and d == device and data.at_defaults(r) for d, r in picked), (name, device)
    # and the cap is not idle: the H100 store has the projectile at its defaults on CUDA
    assert any(r.scenario == "projectile" and r.device == "cuda" and data.at_defaults(r) for r in machine("h100").run)
