"""The cases of the ``ulps`` experiment (compare/stress/generic.py), by scenario: (parameter
overrides, the output whose elements are measured in ulps, setting label). Each scenario's cases
are the function named after it here (its cases give the label's detail, the scenario's name is
put in front); a scenario without one has none."""
from __future__ import annotations

from typing import Callable

from compare.stress.numerics import Overrides

Case = tuple[Overrides, str, str]


def saxpy(quick: bool) -> list[Case]:
    """Both input kinds (cancellation in random ones), at the quick or the full size."""
    n = 100_003 if quick else 1_000_000
    return [({"n": n, "inputs": "linspace"}, "out", "linspace"),
            ({"n": n, "inputs": "random", "seed": 3}, "out", "random")]


def sdf(quick: bool) -> list[Case]:
    """The default-size image (its per-pixel distribution is plotted)."""
    return [({"width": 512, "height": 512}, "image", "")]


ULP_CASES: dict[str, Callable[[bool], list[Case]]] = {f.__name__: f for f in (saxpy, sdf)}


def ulp_cases(scenario: str, quick: bool) -> list[Case]:
    cases = ULP_CASES.get(scenario)
    return [(over, out, f"{scenario} ({how})" if how else scenario)
            for over, out, how in (cases(quick) if cases is not None else [])]
