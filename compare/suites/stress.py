"""``python -m compare stress``: the numerical stability stress suite (docs/stress.md).

Measures, per backend and device, what the seeds only warn about: float32 in long rollouts, hard
contacts and noisy gradients, gradient explosion at large learning rates, fast-math, races. Every
finding is a row (experiment, backend, device, precision, setting, figure, value, verdict, detail)
whose verdict is decided from the value beside it by a rule stated in docs/stress.md; nothing is
tuned per backend. The experiments are registered in ``compare.stress.registry``: each scenario's
own, then the generic ones (``compare.stress.generic``); this module only selects, runs and saves
them.

Writes DIR/stress.json, DIR/stress.md and DIR/*.png. With --only, rows of the experiments not run
this time are kept from an existing DIR/stress.json, so a long suite can be run in parts.
Exit status: 0 when the suite ran (unstable settings are findings, not failures), 1 when a cell
failed unexpectedly or a racy control kernel went unflagged on a GPU, 2 for bad usage.
"""
from __future__ import annotations

import argparse
import errno
import os
import sys
import time
import traceback
from pathlib import Path
from typing import Any

from compare.measuring import environment
from compare.running import sitting_run
from compare import options
from compare.planning import outdir, preflight
from compare.suites.driver import Planned, Run, Suite, claim, drive
from compare.options import EXIT_FAIL, EXIT_INTERRUPTED, EXIT_OK, UsageError
from compare.results.record import Record
from compare.results.store import Store
from compare.stress import page
from compare.stress.numerics import Finding, Outputs, Row, Series
from compare.suites.stress_context import Ctx
from compare.stress.registry import experiments

DISK_FULL = (errno.ENOSPC, errno.EDQUOT)


def add_arguments(p: argparse.ArgumentParser, common: bool = True) -> None:
    """The suite's options; with ``common`` also the shared selection and output ones."""
    if common:
        options.add_selection(p, precision=None, variants=False)
        options.add_output(p, "results/stress")
        p.add_argument("--quick", action="store_true", help="smaller sweeps (a few minutes on 2 cores)")
        p.add_argument("--timeout", type=options.seconds, default=900.0, help="seconds before a cell is killed")
    p.add_argument("--only", default=None, help="comma-separated: " + ",".join(experiments()))
    p.add_argument("--jobs", type=options.positive_int, default=min(8, os.cpu_count() or 1),
                   help="cells run at once (stress figures are not timings)")
    p.add_argument("--merge", nargs="+", metavar="STRESS_JSON", default=None,
                   help="run nothing: merge saved stress.json files (later ones win per experiment) into --out")


def failure(r: Finding) -> bool:
    """A row that makes the exit status 1: a cell that failed, or a racy control not flagged."""
    return r["verdict"] in ("error", "CRASHED") or r["verdict"].startswith("MISSED")


def run(args: argparse.Namespace, argv: list[str]) -> int:
    """Run the chosen experiments (or merge saved parts); raises UsageError/ParamError for bad usage."""
    if args.merge:
        return merge(args)
    return drive(StressSuite(), args, argv)


def merge(args: argparse.Namespace) -> int:
    """--merge: saved parts into --out, every part validated before anything is written."""
    registry = experiments()
    if getattr(args, "precision", None) is not None:
        raise UsageError("--precision does not apply: each stress experiment states its precisions")
    options.selection(args)
    if args.only is not None:
        options.names(args.only, registry, "only")
    options.refuse_inapplicable(args, add_arguments, ("--merge", "--out", "--no-plots"), "with --merge")
    options.no_duplicates(args.merge, "--merge")
    for f in args.merge:
        Store.read(f, "stress")
    outdir.check_output(args.out)
    Store.open(args.out, "stress")
    out, lock = claim(args, 2 * sum(Path(f).stat().st_size for f in args.merge) + preflight.PAGE_BYTES)
    with lock:
        return page.merge(args.merge, out, registry, plots_=not args.no_plots)


class StressSuite(Suite):
    """The chosen experiments, one after another, into DIR/stress.json. A unit of its plan is an
    experiment (``Planned(None, name)``): it makes its cells as it runs, from what it found."""
    timed = False       # stress figures are not timings: no --overlap, no --processes
    add_arguments = staticmethod(add_arguments)

    def plan(self, args: argparse.Namespace) -> list[Planned[str]]:
        self.registry = experiments()
        if getattr(args, "precision", None) is not None:
            raise UsageError("--precision does not apply: each stress experiment states its precisions")
        self.chosen = options.selection(args)
        only = options.names(args.only, self.registry, "only") if args.only is not None else list(self.registry)
        return [Planned(None, name) for name in only]

    def check_output(self, args: argparse.Namespace) -> None:
        outdir.check_output(args.out)
        Store.open(args.out, "stress")                 # a bad stress.json refused (read only)

    def backends(self, run: Run) -> list[str]:
        return self.chosen["backends"]

    def check_runnable(self, run: Run, blocked: list[Any]) -> None:
        """Every experiment would record only skips: refused before anything is written."""
        b_, d_ = self.chosen["backends"], self.chosen["devices"]
        if not any(run.probes[b]["available"].get(d) is None for b in b_ for d in d_):
            b, d = b_[0], d_[0]
            raise UsageError(f"nothing to run: no chosen backend can use a chosen device "
                             f"(first: {b} on {d}: {run.probes[b]['available'].get(d)})")

    def disk_need(self, run: Run) -> float:
        return preflight.STRESS_BYTES

    def open(self, run: Run) -> None:
        args = run.args
        self.store_ = Store.open(run.out, "stress")
        self.ctx = Ctx(self.chosen["backends"], self.chosen["devices"], args.quick, args.jobs, args.timeout,
                       run.probes, self.store_, on_record=self.on_record)
        self.env = environment.collect(run.argv)
        sitting_run.start(self.env, measure=False)      # publish's check of this part, where it ran one
        # the run is in the store's runs before any record naming it is saved (as the run and
        # sweep suites do); write_outputs keeps this entry, the last one, as the run's
        self.store_.runs.append(self.env)
        self.rows: list[Row] = []
        self.series: dict[str, Series] = {}
        self.interrupted = False

    def on_record(self, i: int, rec: Record, outputs: Outputs | None) -> Record:
        """Every cell's record names the run that measured it, as a results record does."""
        return rec.replace(run=environment.run_stamp(self.env))

    def execute(self, run: Run) -> list[Any]:
        only = [str(p.extra) for p in run.planned]
        ctx, store, rows, series = self.ctx, self.store_, self.rows, self.series
        try:
            for name in only:
                t0 = time.perf_counter()
                print(f"stress: {name} ...", file=sys.stderr, flush=True)
                try:
                    r, s = self.registry[name].run(ctx)
                except OSError as exc:
                    if exc.errno in DISK_FULL:   # no experiment can save: stop (one line, exit 1)
                        raise
                    traceback.print_exc()
                    r, s = [ctx.row(name, "-", "-", "-", "-", "experiment", None, "error",
                                    f"{type(exc).__name__}: {exc}")], {}
                except Exception as exc:  # one broken experiment must not lose the others
                    traceback.print_exc()
                    r, s = [ctx.row(name, "-", "-", "-", "-", "experiment", None, "error",
                                    f"{type(exc).__name__}: {exc}")], {}
                rows += r
                series[name] = s
                print(f"stress: {name} done in {time.perf_counter() - t0:.0f} s ({len(r)} rows)",
                      file=sys.stderr, flush=True)
                page.write_outputs(store, self.env, rows, series, only[:only.index(name) + 1], self.registry,
                                   plots_=False)
        except KeyboardInterrupt:
            print("interrupted", file=sys.stderr)
            self.interrupted = True
        return []

    def render(self, run: Run, results: list[Any]) -> int:
        if self.interrupted:
            return EXIT_INTERRUPTED
        only, store, rows = [str(p.extra) for p in run.planned], self.store_, self.rows
        sitting_run.end(self.env)       # a publish part's end check
        stored = page.write_outputs(store, self.env, rows, self.series, only, self.registry,
                                    plots_=not run.args.no_plots)
        failed = [r for r in stored if r["experiment"] in only and failure(r)]
        print(f"wrote {store.path}, stress.md" + ("" if run.args.no_plots else ", *.png")
              + f": {len(rows)} rows, {len(failed)} failures", file=sys.stderr)
        for r in failed:
            print(f"  {r['experiment']} {r['backend']}/{r['device']} {r['setting']}: {r['verdict']} "
                  f"{r['detail'][:160]}", file=sys.stderr)
        return EXIT_FAIL if failed else EXIT_OK
