"""compare/stress/generic.py: the race verdict (moved here from tests/suites/test_stress.py)."""
from __future__ import annotations

import numpy as np
import pytest

from compare.stress import generic, numerics


def _outputs(seed=0):
    rng = np.random.default_rng(seed)
    return {k: rng.standard_normal(100).astype(np.float32) for k in ("x", "y", "vx", "vy")}


@pytest.mark.parametrize("device,differing,oracle_ok,flagged", [
    ("cuda", 37, (True, True), True),           # runs disagree
    ("cuda", 0, (False, False), True),          # deterministic, but wrong
    ("cuda", 0, (True, False), True),
    ("cuda", -1, (True, True), True),           # shapes differ
    ("cuda", 0, (True, True), False),           # clean on a GPU: the control was missed
    ("cpu", 0, (True, True), False),            # clean on the CPU: threads ran in order
    ("cpu", 5, (True, True), True),
])
def test_race_verdict(device, differing, oracle_ok, flagged):
    verdict = generic.race_verdict(device, differing, oracle_ok)
    assert verdict.startswith("RACE DETECTED") == flagged
    if not flagged:
        assert verdict == ("race not observable on CPU" if device == "cpu" else "MISSED: race not flagged")


def test_race_detector_flags_a_synthetic_read_before_write():
    """What the seed's one-launch kernel does when step s is read before step s-1 is written: the
    detector must flag the result through the oracle check and through run-to-run differences."""
    clean = _outputs()
    stale = {k: v.copy() for k, v in clean.items()}
    stale["y"][::3] = 0.0                       # some threads read the zeroed history
    differing = numerics.bitwise_differences(clean, stale)
    assert differing > 0
    assert generic.race_verdict("cuda", differing, (True, False)).startswith("RACE DETECTED")


def test_the_generic_experiments_name_no_scenario():
    import scenarios
    assert list(generic.EXPERIMENTS) == ["ulps", "races"]
    assert not set(generic.EXPERIMENTS) & set(scenarios.SCENARIOS)
    assert generic.EXPERIMENTS["ulps"].plot is generic.plot_ulps and generic.EXPERIMENTS["races"].plot is None


def test_without_backends_there_are_no_controls_and_no_race_rows():
    from compare.suites import stress_context as context
    ctx = context.Ctx([], ["cpu"], True, 1, 1.0, {})
    assert generic.controls(ctx) == []
    assert generic.exp_races(ctx) == ([], {})


def test_plot_ulps_draws_each_image_series():
    import io

    import matplotlib.pyplot as plt

    from compare.stress.plots import _style
    buf = io.BytesIO()
    generic.plot_ulps({"warp/cpu/float32": {"ulps": [0.0, 0.5, 1.0], "frac": [0.5, 0.9, 1.0]},
                       "warp/cpu/float32/fastmath": {"ulps": [0.0, 2.0], "frac": [0.4, 1.0]}}, buf, _style)
    plt.close("all")
    assert buf.getvalue().startswith(b"\x89PNG")


def test_the_race_verdict_says_which_evidence_caught_it():
    """0 differing elements beside 'RACE DETECTED' must say the runs agreed and were wrong alike."""
    alike = generic.race_verdict("cuda", 0, (False, False))
    assert "agree bitwise" in alike and "outside the oracle's bound" in alike and "differ in" not in alike
    assert generic.race_verdict("cuda", 96, (True, True)) == "RACE DETECTED (runs differ in 96 values)"
    both = generic.race_verdict("cuda", 7, (False, True))
    assert "differ in 7 values" in both and "agree bitwise" not in both
