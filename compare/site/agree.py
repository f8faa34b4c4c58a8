"""Whether two stores of one machine kind agree on every significant ordering of the matrix.

    compare agree FIRST SECOND

FIRST and SECOND are results folders (or files) of two independent runs on machines of the same
kind. For every matrix row and every pair of frameworks one of them separates (intervals across
processes apart, or 1.6x for one-process figures), the other is asked: same order, a tie, or the
opposite order. Only the cells both measured are compared (the same framework, variant and
sizes: ``agreement.hold``), so a run that timed fewer variants is not set against another
variant. Prints which cells, one line per row and the total; exit 1 when an ordering reversed.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from tabulate import tabulate

from compare.options import EXIT_FAIL, EXIT_OK


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("first", metavar="FIRST", help="a results folder or file (one run)")
    p.add_argument("second", metavar="SECOND", help="another run's, of the same machine kind")


def run(args: argparse.Namespace, argv: list[str]) -> int:
    from compare.site import agreement, data
    held = agreement.hold(*(data.load([Path(p)]) for p in (args.first, args.second)))
    got = list(held.rows)
    print(f"Compared {held.words()}.")
    print(tabulate([(r.question, r.significant - r.missing, r.agree, r.tie, r.disagree, ", ".join(r.reversed_pairs))
                    for r in got if r.significant],
                   headers=("row", "significant", "agree", "tie in one", "reversed", "which")))
    print(agreement.summary(got))
    return EXIT_FAIL if held.reversed else EXIT_OK
