"""``python -m compare report`` (compare/suites/report.py): a Command that runs no cell; its
refusals come before anything is read or written."""
from __future__ import annotations

from pathlib import Path

import pytest

from compare import cli
from compare.options import UsageError
from compare.suites.report import Report

CPU = Path(__file__).resolve().parents[2] / "docs" / "results" / "cpu" / "results.json"


def test_page_options_without_a_page_are_refused(tmp_path: Path) -> None:
    args = cli.parse(["report", str(CPU), "--out", str(tmp_path / "out"), "--title", "t"])
    with pytest.raises(UsageError, match="--title applies only with --page"):
        Report().run(args, [])
    assert not (tmp_path / "out").exists()


def test_report_never_rewrites_its_input(tmp_path: Path) -> None:
    src = tmp_path / "results.json"
    src.write_bytes(CPU.read_bytes())
    args = cli.parse(["report", str(src), "--out", str(tmp_path)])
    with pytest.raises(UsageError, match="would rewrite its input"):
        Report().run(args, [])
    assert src.read_bytes() == CPU.read_bytes()
