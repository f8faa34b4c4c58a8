"""Why the float32 error shares of one machine differ between frameworks, read from the records.

SAXPY decides most of the accuracy row. Its derived bound (scenarios/saxpy.py): ``a*x + y``
rounded twice, the product and then the sum, errs by up to 2u of ``|a x| + |y|``; rounded once,
as a fused multiply-add does, by at most u. A record's ``error.ulps`` (its largest error over
``|a x| + |y|``, in units of u = 2^-24) above 1 therefore shows two roundings; at most 1 is what
one rounding gives. Whether a compiler contracts ``a*x + y`` into one instruction is its own
choice (XLA's CPU backend does, its CUDA backend here did not; CUDA compilers do by default), so
one framework can lead on one machine and trail on another with the same arithmetic written.
The other scenarios' shares differ far less on the machines measured: their spread is stated
beside it.
"""
from __future__ import annotations

import math
from typing import Iterable

import scenarios
from compare.results.record import Record
from compare.site import data, matrix

ONE_ROUNDING = 1.0        # error.ulps at most this: what one rounding of a*x + y gives


def _ulps(r: Record) -> float | None:
    return data.num(r.error.get("ulps")) if r.status == "ok" and r.error else None


def _counts_roundings(scenario: str) -> bool:
    sc = scenarios.SCENARIOS.get(scenario)
    return bool(sc is not None and sc.ulps_count_roundings)


def roundings(recs: Iterable[Record]) -> dict[str, float]:
    """Each framework's error in units of u (float32 cells) in the scenario whose ulps count the
    roundings of one fusable operation (SAXPY's a*x + y; the site names no scenario)."""
    return {r.backend: u for r in recs if r.precision == "float32" and _counts_roundings(r.scenario)
            and (u := _ulps(r)) is not None}


def _geomean(xs: list[float]) -> float:
    return math.exp(sum(math.log(max(x, matrix.ERROR_FLOOR)) for x in xs) / len(xs))


def others_spread(recs: Iterable[Record]) -> float | None:
    """How far apart the frameworks' geometric-mean shares are over the scenarios other than
    SAXPY (max over min), among frameworks with a share in every one of them."""
    shares: dict[str, dict[str, float]] = {}
    for r in recs:
        s = matrix.error_share(r) if r.status == "ok" else None
        if not _counts_roundings(r.scenario) and s is not None:
            shares.setdefault(r.backend, {})[r.scenario] = s
    scen = {sc for per in shares.values() for sc in per}
    means = [_geomean(list(per.values())) for per in shares.values() if set(per) == scen and scen]
    return max(means) / min(means) if len(means) >= 2 else None


def paragraph(recs: list[Record]) -> str:
    """The page's sentences on why the shares differ; '' where SAXPY's records say nothing."""
    ulps = roundings(recs)
    if not ulps:
        return ""
    once = sorted(f for f, u in ulps.items() if u <= ONE_ROUNDING)
    twice = sorted(f for f, u in ulps.items() if u > ONE_ROUNDING)
    text = ("Why the shares differ: SAXPY's `a·x + y` rounded once, as a fused multiply-add does, "
            "errs by at most u = 2⁻²⁴ of |a·x| + |y|; the product rounded before the add errs by "
            "up to 2u (scenarios/saxpy.py). ")
    hi, lo = max(ulps.values()), min(ulps.values())
    n = len(matrix.IN_ALL)
    if once and twice:
        lo = max(max(ulps[f] for f in once), matrix.ERROR_FLOOR)
        text += (f"Here the errors of {', '.join(once)} fit one rounding (at most {lo:.3g} u); those of "
                 f"{', '.join(twice)} show two (up to {hi:.3g} u). That alone puts the second group's "
                 f"geometric mean over the {n} scenarios {(hi / lo) ** (1 / n):.3g}× above the first's. Whether a compiler "
                 "fuses the two operations is its own choice, so the same code can lead on one "
                 "machine and trail on another.")
    else:
        text += f"Here every framework rounded {'once' if once else 'twice'}, so SAXPY does not set them apart."
    spread = others_spread(recs)
    if spread is not None:
        text += (f" Over the other scenarios the frameworks' geometric means are within "
                 f"{100 * (spread - 1):.1f} % of each other"
                 + (", so SAXPY's rounding sets the row's order." if once and twice and spread < (hi / lo) ** (1 / n)
                    else "."))
    return text
