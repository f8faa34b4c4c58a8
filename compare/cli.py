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
import os
import sys

import compare.site
import scenarios
from compare import options
from compare.options import EXIT_FAIL, EXIT_INTERRUPTED, EXIT_USAGE, Parser, UsageError
from compare.results.store import StoreError
from compare.site import agree
from compare.spec import SpecError
from compare.suites import formats as suite_formats
from compare.suites import stress, sweep
from compare.suites.driver import Command, module_command
from compare.suites.listing import Listing
from compare.suites.publish import Publish
from compare.suites.report import Report
from compare.suites.run import RunSuite
from scenarios.base import ParamError

# The subcommands after the run suite's and report, in --help's order.
OWN: dict[str, type[Command]] = {"sweep": module_command(sweep), "stress": module_command(stress),
                                 "site": module_command(compare.site), "publish": Publish,
                                 "agree": module_command(agree)}


def commands() -> dict[str, type[Command]]:
    """Every subcommand's Command class by name, in --help's order: the run suite's under all,
    run and each scenario's name."""
    return {"list": Listing, "all": RunSuite, "run": RunSuite, **{name: RunSuite for name in scenarios.SCENARIOS},
            "report": Report, **OWN}


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog="python -m compare", description=__doc__,
               formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=Parser)
    for name, command in commands().items():
        if name == "all":
            sp = sub.add_parser("all", help="every scenario in 'all'")
        elif name == "run":
            sp = sub.add_parser("run", help="the named scenarios")
            sp.add_argument("scenarios", nargs="+", metavar="SCENARIO", help=", ".join(scenarios.SCENARIOS))
        elif name in scenarios.SCENARIOS:
            sc = scenarios.SCENARIOS[name]
            rules = "\n".join(f"  {n} (default {default!r}): {rule}" for n, default, rule in sc.param_rules())
            sp = sub.add_parser(sc.name, help=sc.title, formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog=f"{sc.title}. Parameters (--set NAME=VALUE):\n{rules}")
        else:
            sp = sub.add_parser(name, help=command.summary())
        command.add_arguments(sp)
    return p


def known_commands() -> list[str]:
    return list(commands())


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
        return commands()[args.command]().run(args, argv)
    except (UsageError, ParamError, StoreError, SpecError) as exc:
        print(f"error: {options.shown(str(exc))}", file=sys.stderr)   # a path's newline stays escaped
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        # the reader of the output went away (`| head`): not a full disk; stop without a traceback
        # from the interpreter's last flush, saying only what a measuring command keeps
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            if _records(argv):
                print("stopped: the reader of its output closed the pipe; every record saved before it is "
                      "kept: rerun with --resume", file=sys.stderr)
        except OSError:
            pass
        return EXIT_FAIL
    except OSError as exc:
        if exc.errno == errno.ENAMETOOLONG:     # a name the file system cannot hold: bad usage
            print(f"error: {options.shown(str(exc.filename or 'a path'))}: name too long for the file "
                  "system (give a shorter path)", file=sys.stderr)
            return EXIT_USAGE
        # the disk filled up (or went away) mid-run: what was saved stays
        print(f"error: {options.shown(write_failure(exc, argv))}", file=sys.stderr)
        return EXIT_FAIL


READ_ONLY = ("report", "list", "agree", "site")     # commands that measure nothing: no records to keep


def _records(argv: list[str]) -> bool:
    """Whether the command measures (saves records as it goes): a failure then keeps them."""
    return bool(argv) and argv[0] not in READ_ONLY and argv[1:2] != ["report"]


def write_failure(exc: OSError, argv: list[str]) -> str:
    """One line for a failed write: which file, why, and that the saved records are kept."""
    what = f"cannot write {exc.filename}" if exc.filename else "a write failed"
    why = exc.strerror or str(exc)
    hint = "" if not _records(argv) else "; every record saved before it is kept" + (
        "" if argv[0] == "stress" else ": free some space and rerun with --resume")
    return f"{what}: {why}{hint}"

