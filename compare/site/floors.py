"""Which launch floor a compared figure was divided by, in words (``--against``: the page and the command line).

A per-call figure in floors (``data.floors``) is divided by its cell's own floor where its record
has one (``cell_floor``, probed in the cell's worker beside its timed window), else by its run's
yardstick. A ratio in floors compares two sides that may differ in that: these words mark a pair
where either side used its cell's own floor, and say nothing where both used their run's yardstick
(every record before ``cell_floor`` existed), so those pages read as before.
"""
from __future__ import annotations

from typing import Iterable, Protocol

from compare.results.record import Record
from compare.site import data

OWN = "cell floors"
NOTE = (f"; a ratio marked ({OWN}: here, there or both) divides that side by its cell's own floor "
        "(the same empty launch probed in the cell's worker beside its timed window) instead of its "
        "run's yardstick")


class Pair(Protocol):
    """One regime of a cell compared on two sides (``against.Compared``)."""
    @property
    def rec(self) -> Record: ...
    @property
    def there(self) -> Record | None: ...
    @property
    def regime(self) -> str: ...
    @property
    def floor_ratio(self) -> float | None: ...


def sides(x: Pair) -> str:
    """Which side's figure is in its cell's own floors: 'here', 'there', 'both' or ''."""
    here, there = data.own_floor(x.rec, x.regime), data.own_floor(x.there, x.regime)
    return "both" if here and there else "here" if here else "there" if there else ""


def mark(x: Pair) -> str:
    """The mark after a ratio in floors: '' where both sides are in their runs' yardsticks."""
    return f" ({OWN}: {s})" if (s := sides(x)) else ""


def note(xs: Iterable[Pair]) -> str:
    """The page's words on the marks ('' where no pair in floors has one)."""
    return NOTE if any(sides(x) for x in xs if x.floor_ratio is not None) else ""


def count(xs: Iterable[Pair]) -> str:
    """How many of the pairs in floors use a cell's own floor, in words ('' where none does)."""
    k = sum(bool(sides(x)) for x in xs if x.floor_ratio is not None)
    return f" ({k} with a cell's own floor on one side or both)" if k else ""
