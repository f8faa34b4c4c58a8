"""``python -m compare``: one command line with real subcommands, each with its own ``--help``.

    list                      scenarios, backends, devices, and what is missing or broken
    all | run S... | <S>      every / the named scenarios on every available backend and device
    report FILES              tables, plots or a published page from saved results.json files
    sweep KIND                measurement sweeps (docs/measurement.md)
    stress                    numerical stability stress suite (docs/stress.md)
    site RESULTS... --out DIR the static report site (recommendation matrix, one page per question)
    publish --out DIR         run what a machine's report needs (resumable, in parts), then its site
    agree FIRST SECOND        whether two runs of one machine kind agree on every significant ordering

Every subcommand shares the options of compare/options.py and one error path: bad usage or a bad
parameter is one line on stderr and exit 2, before any cell runs or any file is written.
"""
from __future__ import annotations

import argparse
import errno
import sys
from typing import Any

import backends
import scenarios
from compare.running import engine
from compare import options
from compare.suites import formats as suite_formats
from compare.suites import run as run_suite
from compare.options import EXIT_FAIL, EXIT_INTERRUPTED, EXIT_OK, EXIT_USAGE, Parser, UsageError
from compare.spec import SpecError
from compare.results.store import StoreError
from scenarios.base import ParamError


# The subcommands with a module of their own: each has add_arguments, run and a docstring.
SUITE_MODULES = {"sweep": "compare.suites.sweep", "stress": "compare.suites.stress", "site": "compare.site",
                 "publish": "compare.suites.publish", "agree": "compare.site.agree"}


def suite_modules() -> dict[str, Any]:
    import importlib
    return {name: importlib.import_module(module) for name, module in SUITE_MODULES.items()}


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog="python -m compare", description=__doc__,
               formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=Parser)
    sub.add_parser("list", help="scenarios, backends, devices (and why one is unavailable)")
    run_suite.add_arguments(sub.add_parser("all", help="every scenario in 'all'"))
    r = sub.add_parser("run", help="the named scenarios")
    r.add_argument("scenarios", nargs="+", metavar="SCENARIO", help=", ".join(scenarios.SCENARIOS))
    run_suite.add_arguments(r)
    for sc in scenarios.SCENARIOS.values():
        rules = "\n".join(f"  {name} (default {default!r}): {rule}" for name, default, rule in sc.param_rules())
        run_suite.add_arguments(sub.add_parser(
            sc.name, help=sc.title, formatter_class=argparse.RawDescriptionHelpFormatter,
            epilog=f"{sc.title}. Parameters (--set NAME=VALUE):\n{rules}"))
    rep = sub.add_parser("report", help="rebuild tables/plots (or a page) from saved results.json files")
    rep.add_argument("files", nargs="+", metavar="RESULTS_JSON")
    options.add_output(rep, "results")
    options.add_page(rep)
    for name, mod in suite_modules().items():
        sp = sub.add_parser(name, help=(mod.__doc__ or "").strip().splitlines()[0])
        mod.add_arguments(sp)
    return p


def known_commands() -> list[str]:
    return ["list", "all", "run", *scenarios.SCENARIOS, "report", *suite_modules()]


def scenario_problems() -> list[str]:
    """Kernel files a backend lacks: required (every scenario in 'all') or optional."""
    out = []
    for name, b in backends.BACKENDS.items():
        if isinstance(b, backends.Broken):
            continue
        where = type(b).__module__.replace(".", "/")
        missing = [sc for sc in scenarios.SCENARIOS.values() if not b.has_kernel(sc.name)]
        req = [sc.name for sc in missing if sc.in_all]
        opt = [sc.name for sc in missing if not sc.in_all]
        if req:
            out.append(f"{name}: missing required {', '.join(f'{where}/{s}.py' for s in req)} (its cells are errors)")
        if opt:
            out.append(f"{name}: no optional {', '.join(f'{where}/{s}.py' for s in opt)} (skipped in the sweeps)")
    return out


def cmd_list() -> int:
    probes = engine.availability(backends.BACKENDS)
    print("scenarios:")
    for sc in scenarios.SCENARIOS.values():
        tag = "" if sc.in_all else " [measurement-only, not in 'all']"
        print(f"  {sc.name:11s} {sc.title}{tag}; defaults: {sc.describe_params()}")
    print("backends (device: available, or why not):")
    width = max(map(len, backends.BACKENDS), default=7)
    for name, b in backends.BACKENDS.items():
        avail = probes[name]["available"]
        devs = "; ".join(f"{d}: {'yes' if avail.get(d) is None else avail.get(d)}" for d in backends.DEVICES)
        ref = " (reference)" if b.is_reference else ""
        print(f"  {name:{width}s}{ref} gradient={b.gradient_method} variants={','.join(b.variants)}"
              + "".join(f" (+{sc}: {','.join(vs)})" for sc, vs in b.scenario_variants.items()) + f"; {devs}")
    problems = backends.PROBLEMS + scenario_problems()
    if problems:
        print("problems:")
        for line in problems:
            print(f"  {line}")
    return EXIT_OK


def parse(argv: list[str]) -> argparse.Namespace:
    """The parsed command line. Words after the options join the command's list of files or
    scenarios (argparse takes a positional list in one block: ``sweep report --out D a.json``);
    any other leftover is refused."""
    args, extra = build_parser().parse_known_args(argv)
    words = [w for w in extra if not w.startswith("-")]
    listed = next((k for k in ("files", "scenarios") if isinstance(getattr(args, k, None), list)), None)
    if not extra:
        return args
    if listed is None or len(words) != len(extra):
        raise UsageError(f"unrecognized arguments: {' '.join(extra)}")
    setattr(args, listed, getattr(args, listed) + words)
    return args


def main(argv: list[str]) -> int:
    suite_formats.register()        # every suite's results-file format, before any file is read
    try:
        options.check_utf8(argv)
        if argv and not argv[0].startswith("-") and argv[0] not in known_commands():
            raise UsageError(f"unknown scenario or command {argv[0]!r} (known: {', '.join(known_commands())})")
        args = parse(argv)
        if args.command == "list":
            return cmd_list()
        if args.command == "report":
            return run_suite.report_command(args)
        if args.command in suite_modules():
            return suite_modules()[args.command].run(args, argv)
        return run_suite.run(args, argv)      # all, run S..., <S>
    except (UsageError, ParamError, StoreError, SpecError) as exc:
        print(f"error: {options.shown(str(exc))}", file=sys.stderr)   # a path's newline stays escaped
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except OSError as exc:
        if exc.errno == errno.ENAMETOOLONG:     # a name the file system cannot hold: bad usage
            print(f"error: {options.shown(str(exc.filename or 'a path'))}: name too long for the file "
                  "system (give a shorter path)", file=sys.stderr)
            return EXIT_USAGE
        # the disk filled up (or went away) mid-run: what was saved stays
        print(f"error: {options.shown(write_failure(exc, argv))}", file=sys.stderr)
        return EXIT_FAIL


def write_failure(exc: OSError, argv: list[str]) -> str:
    """One line for a failed write: which file, why, and that the saved records are kept."""
    what = f"cannot write {exc.filename}" if exc.filename else "a write failed"
    why = exc.strerror or str(exc)
    suite = bool(argv) and argv[0] not in ("report", "list") and argv[1:2] != ["report"]
    hint = "" if not suite else "; every record saved before it is kept" + (
        "" if argv[0] == "stress" else ": free some space and rerun with --resume")
    return f"{what}: {why}{hint}"

