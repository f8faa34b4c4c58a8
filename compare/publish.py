"""Run what a machine's report needs, then build its site (``python -m compare publish``).

(Being written: see issue 28, item 3.)
"""
from __future__ import annotations

import argparse

from compare.options import UsageError


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help="the machine's results folder")


def run(args: argparse.Namespace, argv: list[str]) -> int:
    raise UsageError("compare publish is not written yet")
