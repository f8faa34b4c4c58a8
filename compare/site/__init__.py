"""A static report site generated from stored results (``python -m compare site``).

    compare site RESULTS... --out DIR [--title T] [--against REFERENCE...]

RESULTS are results folders (holding any of results.json, sweep.json, stress.json: one
machine's store) or those files themselves. DIR receives ``index.html`` (the recommendation
matrix), one page per question, a machine-and-method page, ``figures/`` with each figure's data
as CSV beside its PNG, a Markdown twin of every page (``*.md``, for GitHub) and ``matrix.md`` (the
matrix alone, as README embeds it). Pages are self-contained: relative links, no server, nothing
fetched from the network. ``--against`` adds ``against.html``: this run's cells against a
reference machine's, per cell the ratio and whether it lies within both runs' spread. DIR is
written whole: a rebuild over an earlier site swaps the new one in (compare/site/whole.py).

Nothing here is written by hand: every number, verdict and colour is derived from the records by
the rules printed on the pages (compare/site/matrix.py).
"""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from compare import options
from compare.planning import outdir
from compare.options import EXIT_OK, UsageError

if TYPE_CHECKING:
    from compare.site.data import Machine


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("files", nargs="+", metavar="RESULTS",
                   help="results folders (results.json, sweep.json, stress.json) or those files")
    p.add_argument("--out", required=True, help="the site's directory")
    p.add_argument("--title", default=None, help="the site's title (default: the machine's name)")
    p.add_argument("--against", action="append", default=[], metavar="REFERENCE",
                   help="a reference machine's results folder or files: adds against.html")


def build(inputs: list[Path], out: Path, title: str | None = None, against: list[Path] | None = None,
          machine: Machine | None = None, reference: Machine | None = None) -> list[Path]:
    """Write the site for the stores ``inputs`` at ``out``, whole (built beside it, then swapped
    in: compare/site/whole.py); the files written. ``machine`` and ``reference``: the stores of
    ``inputs`` and ``against`` where the caller has loaded them already (each file is read once)."""
    from compare.site import assemble, data, whole
    inputs, against = [Path(p) for p in inputs], [Path(p) for p in against or []]
    m = machine if machine is not None else data.load(inputs)
    ref = reference if reference is not None or not against else data.load(against)
    return whole.write_whole(out, lambda into: assemble.write_site(inputs, Path(out), into, title, against, m, ref))


def run(args: argparse.Namespace, argv: list[str]) -> int:
    from compare.site import data, whole
    options.no_duplicates(args.files, "site")
    files, against = [Path(f) for f in args.files], [Path(f) for f in args.against]
    m = data.load(files)          # a bad file refused before anything is written; loaded once
    ref = data.load(against) if against else None
    if against:
        if same := sorted({f.resolve() for p in files for f in data._suite_files(p)}
                          & {f.resolve() for p in against for f in data._suite_files(p)}):
            raise UsageError(f"--against {same[0]} is also one of the RESULTS: compare against another machine's")
    outdir.check_output(args.out)
    whole.check_replaceable(args.out)         # before the claim creates or locks anything
    out, lock = outdir.claim_output(args.out, 64 * 2**20, "the site")
    with lock:
        written = build(files, out, args.title, against, m, ref)
    print(f"wrote {len(written)} files in {out}; open {out / 'index.html'}")
    return EXIT_OK
