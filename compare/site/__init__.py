"""A static report site generated from stored results (``python -m compare site``).

    compare site RESULTS... --out DIR [--title T] [--against REFERENCE...]

RESULTS are results folders (holding any of results.json, sweep.json, stress.json: one
machine's store) or those files themselves. DIR receives ``index.html`` (the recommendation
matrix), one page per question, a machine-and-method page, ``figures/`` with each figure's data
as CSV beside its PNG, a Markdown twin of every page (``*.md``, for GitHub) and ``matrix.md`` (the
matrix alone, as README embeds it). Pages are self-contained: relative links, no server, nothing
fetched from the network. ``--against`` adds ``against.html``: this run's cells against a
reference machine's, per cell the ratio and whether it lies within both runs' spread.

Nothing here is written by hand: every number, verdict and colour is derived from the records by
the rules printed on the pages (compare/site/matrix.py).
"""
from __future__ import annotations

import argparse
from pathlib import Path

from compare import options
from compare.options import EXIT_OK, UsageError


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("files", nargs="+", metavar="RESULTS",
                   help="results folders (results.json, sweep.json, stress.json) or those files")
    p.add_argument("--out", required=True, help="the site's directory")
    p.add_argument("--title", default=None, help="the site's title (default: the machine's name)")
    p.add_argument("--against", action="append", default=[], metavar="REFERENCE",
                   help="a reference machine's results folder or files: adds against.html")


def build(inputs: list[Path], out: Path, title: str | None = None,
          against: list[Path] | None = None) -> list[Path]:
    """Write the site for the stores ``inputs`` into ``out``; the files written."""
    from compare.site import assemble
    return assemble.write_site([Path(p) for p in inputs], Path(out), title,
                            [Path(p) for p in against or []])


def run(args: argparse.Namespace, argv: list[str]) -> int:
    options.no_duplicates(args.files, "site")
    from compare.site import data
    data.load([Path(f) for f in args.files])          # a bad file refused before anything is written
    if args.against:
        data.load([Path(f) for f in args.against])
        if same := sorted({f.resolve() for p in args.files for f in data._suite_files(Path(p))}
                          & {f.resolve() for p in args.against for f in data._suite_files(Path(p))}):
            raise UsageError(f"--against {same[0]} is also one of the RESULTS: compare against another machine's")
    out, lock = options.claim_output(args.out, 64 * 2**20, "the site")
    with lock:
        written = build([Path(f) for f in args.files], out, args.title, [Path(f) for f in args.against])
    print(f"wrote {len(written)} files in {out}; open {out / 'index.html'}")
    return EXIT_OK
