"""``python -m compare report FILES``: tables, plots or a published page rebuilt from saved
results.json files (merged), without running anything."""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from compare import options
from compare.options import UsageError
from compare.planning import outdir
from compare.planning.preflight import PAGE_BYTES, RECORD_BYTES
from compare.render import report, run_plots
from compare.results.environment import RunEnvironment
from compare.results.record import Record
from compare.results.store import Store
from compare.suites.driver import Command
from compare.suites.run import render, saved_outputs


class Report(Command):
    """report: the saved files, --out and the page's options; runs no cell."""
    help = "rebuild tables/plots (or a page) from saved results.json files"

    @staticmethod
    def add_arguments(p: argparse.ArgumentParser) -> None:
        p.add_argument("files", nargs="+", metavar="RESULTS_JSON")
        options.add_output(p, "results")
        options.add_page(p)

    def run(self, args: argparse.Namespace, argv: list[str]) -> int:
        return report_command(args)


def report_command(args: argparse.Namespace) -> int:
    """Rebuild tables and plots from saved results.json files (merged), without running anything.
    Records from different machines are told apart by a 'machine' field (GPU model or host)."""
    records: list[Record] = []
    envs: list[RunEnvironment] = []     # stored runs
    outputs: dict[int, dict[str, np.ndarray]] = {}
    options.no_duplicates(args.files, "report")
    for opt in ("title", "notes"):
        if getattr(args, opt) is not None and not args.page:
            raise UsageError(f"--{opt} applies only with --page")
    for f in args.files:
        store = Store.read(f, "run")
        for env in store.runs:
            envs.append(env)
        machine = next((next((g["name"] for g in e.get("gpus") or []), "") or e.get("hostname") for e in store.runs), "?")
        recs = [r if r.machine is not None else r.replace(machine=machine) for r in store.records]
        mine: dict[int, dict[str, np.ndarray]] = {}
        saved_outputs(Path(f).parent, recs, mine)     # --save-arrays outputs redraw the pictures
        outputs.update({len(records) + i: o for i, o in mine.items()})
        records += recs
    notes = outdir.read_notes(args.notes)
    outdir.check_page(args.page, args.title)
    written = Path(args.out) / "results.json"
    if not args.page and any(Path(f).resolve() == written.resolve() for f in args.files):
        raise UsageError(f"report would rewrite its input {written}: give another --out (or --page FILE)")
    out, lock = outdir.claim_output(args.out, PAGE_BYTES + 2 * RECORD_BYTES * len(records))
    with lock:
        return report_claimed(args, out, envs, records, outputs, notes)


def report_claimed(args: argparse.Namespace, out: Path, envs: list[RunEnvironment],  # stored runs
                   records: list[Record], outputs: dict[int, dict[str, np.ndarray]], notes: str) -> int:
    if args.page:
        page = Path(args.page)
        if not args.no_plots:
            run_plots.write_plots(records, outputs, out / "plots")
        rebuild = " ".join(["python -m compare report", *args.files, "--out", args.out, "--page", args.page]
                           + ([f"--title '{args.title}'"] if args.title else [])
                           + (["--notes", args.notes] if args.notes else [])
                           + (["--no-plots"] if args.no_plots else []))
        report.atomic_write(page, report.page(args.title or "Results", envs, records,
                                              report.images_in(out / "plots", page.parent), notes, rebuild))
        print(f"wrote {page}")
        return options.EXIT_OK
    merged = Store(out / "results.json", "run", [{"merged_from": list(args.files), "environments": envs}], records)
    merged.save()
    render(out, merged.runs[0], records, outputs, plots=not args.no_plots)
    print(report.tables(records, wide=False))
    print("\n".join(report.noise_lines(records) + [""]), end="")
    return options.EXIT_OK
