"""compare/site/agree.py: ``compare agree FIRST SECOND`` on two copies of the site's test store
(fast tier): a store agrees with itself; swapping two frameworks' records reverses orderings."""
from __future__ import annotations

import argparse
import shutil
from pathlib import Path

from compare.options import EXIT_FAIL, EXIT_OK
from compare.site import agree

STORE = Path(__file__).resolve().parents[2] / "tests" / "data" / "site"


def agree_main(first: Path, second: Path) -> int:
    p = argparse.ArgumentParser()
    agree.add_arguments(p)
    argv = [str(first), str(second)]
    return agree.run(p.parse_args(argv), argv)


def test_a_store_agrees_with_itself(capsys):
    assert agree_main(STORE / "results.json", STORE / "results.json") == EXIT_OK
    out = capsys.readouterr().out
    assert "significant" in out and "reversed" in out


def test_swapped_frameworks_reverse_an_ordering(tmp_path, capsys):
    text = (STORE / "results.json").read_text()
    swapped = (text.replace('"backend":"warp"', '"backend":"@@"').replace('"backend":"cupy"', '"backend":"warp"')
               .replace('"backend":"@@"', '"backend":"cupy"'))
    (tmp_path / "results.json").write_text(swapped)
    assert agree_main(STORE / "results.json", tmp_path / "results.json") == EXIT_FAIL
    out = capsys.readouterr().out
    assert "cupy" in out and "warp" in out
