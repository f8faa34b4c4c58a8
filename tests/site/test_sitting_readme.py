"""Each later sitting's README states its figures from the stores (compare/site/sitting_readme.py):
its generated block is current, and the order table names exactly the pairs that swap."""
from __future__ import annotations

from pathlib import Path

from compare.site import readme, sitting_readme
from compare.site.render import block_md
from compare.site.sittings import Between

ROOT = Path(__file__).resolve().parents[2]


def test_every_sitting_readme_has_its_block_and_it_is_current() -> None:
    found = sitting_readme.readmes(ROOT / "docs" / "results")
    assert {p.parent.parent.parent.name for p in found} >= {"h100", "cpu"}
    for path in found:
        assert readme.blocks(path) == [readme.SITTING], path
        assert readme.expected(path) == path.read_text(encoding="utf-8"), \
            f"{path}'s figures differ from its stores: run python -m compare.site.readme"


def _b(fw: str, first: float, other: float, exact: bool = False) -> Between:
    return Between("k", "Row", fw, "default", "s", first, None, "later", other, 3, exact)


def test_the_order_table_names_the_pairs_that_swap_and_skips_exact_rows() -> None:
    same = sitting_readme._orders([_b("a", 1, 2), _b("b", 2, 3), _b("c", 3, 9)])
    assert "the same" in block_md(same[0])
    swapped = block_md(sitting_readme._orders([_b("a", 1, 5), _b("b", 2, 3), _b("c", 3, 4)])[0])
    assert "2 pairs swap: a and b; a and c" in swapped
    assert sitting_readme._orders([_b("a", 1, 1, True), _b("b", 2, 2, True)]) == []
    assert sitting_readme._orders([_b("a", 1, 5)]) == []
