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

from compare import engine, environment, options, outdir, preflight
from compare.options import EXIT_FAIL, EXIT_INTERRUPTED, EXIT_OK, UsageError
from compare.store import Store
from compare.stress import page
from compare.stress.context import Ctx
from compare.stress.numerics import Experiment
from compare.stress.registry import experiments

# disk preflight: the cell records and findings of a full suite, generously (the CPU suite's
# stress.json is ~1 MB), and the page and plots
RESERVE_BYTES = 256 * 2**20
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


def failure(r: dict[str, Any]) -> bool:
    """A row that makes the exit status 1: a cell that failed, or a racy control not flagged."""
    return r["verdict"] in ("error", "CRASHED") or r["verdict"].startswith("MISSED")


def run(args: argparse.Namespace, argv: list[str]) -> int:
    """Run the chosen experiments (or merge saved parts); raises UsageError/ParamError for bad usage."""
    registry = experiments()
    if getattr(args, "precision", None) is not None:
        raise UsageError("--precision does not apply: each stress experiment states its precisions")
    chosen = options.selection(args)
    only = options.names(args.only, registry, "only") if args.only is not None else list(registry)
    if args.merge:
        options.refuse_inapplicable(args, add_arguments, ("--merge", "--out", "--no-plots"), "with --merge")
        options.no_duplicates(args.merge, "--merge")
        for f in args.merge:                # every part validated before anything is written
            Store.read(f, "stress")
        outdir.check_output(args.out)
        Store.open(args.out, "stress")
        out, lock = outdir.claim_output(args.out, 2 * sum(Path(f).stat().st_size for f in args.merge)
                                         + preflight.PAGE_BYTES)
        with lock:
            return page.merge(args.merge, out, registry, plots_=not args.no_plots)
    outdir.check_output(args.out)
    Store.open(args.out, "stress")                 # a bad stress.json refused (read only)
    probes = engine.availability(chosen["backends"])
    usable = [(b, d) for b in chosen["backends"] for d in chosen["devices"] if probes[b]["available"].get(d) is None]
    if not usable:      # every experiment would record only skips: refused before anything is written
        b, d = chosen["backends"][0], chosen["devices"][0]
        raise UsageError(f"nothing to run: no chosen backend can use a chosen device "
                         f"(first: {b} on {d}: {probes[b]['available'].get(d)})")
    out, lock = outdir.claim_output(args.out, RESERVE_BYTES)
    with lock:
        return run_claimed(args, argv, registry, chosen, only, Store.open(out, "stress"), probes)


def run_claimed(args: argparse.Namespace, argv: list[str], registry: dict[str, Experiment],
                chosen: dict[str, list[str]], only: list[str], store: Store,
                probes: dict[str, dict[str, Any]]) -> int:
    """The suite, once its output directory is checked and locked by this driver."""
    ctx = Ctx(chosen["backends"], chosen["devices"], args.quick, args.jobs, args.timeout, probes, store)
    env = environment.collect(argv)
    rows: list[dict[str, Any]] = []
    series: dict[str, Any] = {}
    try:
        for name in only:
            t0 = time.perf_counter()
            print(f"stress: {name} ...", file=sys.stderr, flush=True)
            try:
                r, s = registry[name].run(ctx)
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
            print(f"stress: {name} done in {time.perf_counter() - t0:.0f} s ({len(r)} rows)", file=sys.stderr, flush=True)
            page.write_outputs(store, env, rows, series, only[:only.index(name) + 1], registry, plots_=False)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    data = page.write_outputs(store, env, rows, series, only, registry, plots_=not args.no_plots)
    failed = [r for r in data["rows"] if r["experiment"] in only and failure(r)]
    print(f"wrote {store.path}, stress.md" + ("" if args.no_plots else ", *.png")
          + f": {len(rows)} rows, {len(failed)} failures", file=sys.stderr)
    for r in failed:
        print(f"  {r['experiment']} {r['backend']}/{r['device']} {r['setting']}: {r['verdict']} {r['detail'][:160]}",
              file=sys.stderr)
    return EXIT_FAIL if failed else EXIT_OK
