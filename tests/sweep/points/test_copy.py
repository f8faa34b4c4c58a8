"""compare/sweep/points/copy.py: the copy yardstick's one bandwidth point per device (fast tier)."""
from __future__ import annotations

import pytest

from compare.sweep.points import CHECK_SAMPLE, sweeps
from compare.sweep.points.copy import COPY_N, SWEEPS


@pytest.mark.parametrize("device,quick", sorted(COPY_N))
def test_one_unchecked_point_far_beyond_the_caches(device, quick):
    (pt,) = SWEEPS.points("bandwidth", device, quick)
    assert pt.params == {"n": COPY_N[device, quick]} and pt.knob is None
    assert pt.check_sample == CHECK_SAMPLE and not pt.save_outputs
    assert pt.params["n"] * 4 >= 16 * 2**20                  # a float32 array of 16 MiB or more


def test_it_measures_the_roofline_and_nothing_else():
    assert sweeps("copy") is SWEEPS and SWEEPS.measures == "copy"
    assert SWEEPS.points("error", "cpu", False) == [] and SWEEPS.points("bandwidth", "tpu", False) == []
    assert COPY_N["cuda", False] > COPY_N["cpu", False] and COPY_N["cpu", True] < COPY_N["cpu", False]
