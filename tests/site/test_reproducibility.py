"""compare/site/reproducibility.py: the machine page's second runs, each held against the report on
the cells both measured (fast tier; the rerun's paragraph: tests/site/test_assemble.py)."""
from __future__ import annotations

import shutil
from pathlib import Path

from compare.site import data, pages, reproducibility
from compare.site import questions_pages as qp
from compare.site.render import Table

STORE = Path(__file__).resolve().parents[2] / "tests" / "data" / "site"


def test_the_machine_page_holds_every_later_sitting_against_the_report(tmp_path):
    """A later sitting (sittings/<label>/) is a second run too: listed with its agreement on the
    cells both measured, without the rerun's paragraph where no rerun/ is stored."""
    from compare.site import sittings
    store = tmp_path / "store"
    shutil.copytree(STORE, store)
    (store / sittings.FOLDER / "later").mkdir(parents=True)
    shutil.copy(STORE / "results.json", store / sittings.FOLDER / "later")
    m = data.load([store])
    c = qp.Ctx(m, pages.evaluate(m)[0], tmp_path / "site", "STORE", later=sittings.load_all([store]))
    blocks = reproducibility.blocks(c)
    text = " ".join(getattr(b, "text", "") for b in blocks)
    assert "Every second run stored beside these records (1:" in text and "0 reversed" in text
    assert "The second run of the matrix part" not in text
    table = next(b for b in blocks if isinstance(b, Table))
    [line] = table.rows
    later = data.load([store / sittings.FOLDER / "later"])     # the report's results.json: its sweep is not in it
    n = len({r.key for r in (*later.records, *later.busy)})
    assert line[0] == "sittings/later" and line[3] == str(n) and line[7] == "0" and line[8] == "-"
    assert line[2].startswith("copy ")          # its host, as its yardstick saw it



def test_a_sitting_that_reverses_an_ordering_is_named_with_its_pairs(tmp_path):
    """The sum says how many orderings reversed, and the sitting's line which, by row."""
    from compare.site import sittings
    store = tmp_path / "store"
    shutil.copytree(STORE, store)
    swapped = ((STORE / "results.json").read_text().replace('"backend":"warp"', '"backend":"@@"')
               .replace('"backend":"cupy"', '"backend":"warp"').replace('"backend":"@@"', '"backend":"cupy"'))
    (store / sittings.FOLDER / "swapped").mkdir(parents=True)
    (store / sittings.FOLDER / "swapped" / "results.json").write_text(swapped)
    m = data.load([store])
    c = qp.Ctx(m, pages.evaluate(m)[0], tmp_path / "site", "STORE", later=sittings.load_all([store]))
    blocks = reproducibility.blocks(c)
    [line] = next(b for b in blocks if isinstance(b, Table)).rows
    assert int(line[7]) > 0 and "cupy vs warp" in line[8] and ": " in line[8]
    text = " ".join(getattr(b, "text", "") for b in blocks)
    assert f"{line[7]} reversed (a ranking that did not survive a rerun)" in text
