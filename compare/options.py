"""The options every subcommand shares, their validation, and the one error path.

Every option is checked where it is parsed (finite, positive, known names, no duplicates), so bad
input is a one-line ``UsageError`` (exit 2) before any cell runs or any file is written.
"""
from __future__ import annotations

import argparse
import dataclasses
import math
from typing import Any, Callable, Iterable, NoReturn

import backends
import scenarios
from scenarios.base import PRECISIONS, ParamError, dtype_of

EXIT_OK, EXIT_FAIL, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


class UsageError(Exception):
    """Bad command-line usage; its message is one line."""


class Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:   # one line, exit 2, no usage dump
        raise UsageError(message)

    def parse_known_args(self, args: Any = None, namespace: Any = None) -> Any:
        if args is not None:
            self._refuse_repeats(list(args))
        return super().parse_known_args(args, namespace)

    def _refuse_repeats(self, args: list[str]) -> None:
        """A single-valued option given twice is refused (argparse would keep the last silently)."""
        repeatable = (argparse._AppendAction, argparse._CountAction, argparse._HelpAction,
                      argparse._SubParsersAction)
        sub = next((a for a in self._actions if isinstance(a, argparse._SubParsersAction)), None)
        words = []
        for w in args:
            if w == "--" or (sub is not None and w in sub.choices):
                break                  # the rest is a positional list or the subcommand's own
            words.append(w)
        for action in self._actions:
            if not action.option_strings or isinstance(action, repeatable):
                continue
            n = sum(1 for w in words for o in action.option_strings
                    if w == o or (o.startswith("--") and w.startswith(o + "=")))
            if n > 1:
                raise UsageError(f"argument {'/'.join(action.option_strings)}: given {n} times (give it once)")

    def _get_values(self, action: argparse.Action, arg_strings: list[str]) -> Any:
        # argparse drops a lone '--' value (``--repeat=--``) and stores [] unchecked
        if action.option_strings and action.nargs is None and list(arg_strings) == ["--"]:
            raise UsageError(f"argument {'/'.join(action.option_strings)}: expected a value, got '--'")
        return super()._get_values(action, arg_strings)


def names(value: str, allowed: Iterable[str], what: str) -> list[str]:
    """A comma-separated list of known names, without duplicates; 'all' means every allowed one."""
    allowed = list(allowed)
    if value.strip() == "all":
        return allowed
    items = [v.strip() for v in value.split(",") if v.strip()]
    if not items:
        raise UsageError(f"--{what} is empty (allowed: {', '.join(allowed)})")
    for v in items:
        if v not in allowed:
            raise UsageError(f"unknown {what.rstrip('s')} {v!r} (allowed: {', '.join(allowed)})")
    dup = next((v for i, v in enumerate(items) if v in items[:i]), None)
    if dup:
        raise UsageError(f"--{what} names {dup!r} twice")
    return items


def whole_number(text: str, minimum: int = 1) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < minimum:
        raise argparse.ArgumentTypeError(f"must be >= {minimum}, got {value}")
    return value


def positive_int(text: str) -> int:
    return whole_number(text, 1)


def nonnegative_int(text: str) -> int:
    return whole_number(text, 0)


def count_or_auto(minimum: int) -> Callable[[str], int | str]:
    """An argparse type: a whole number >= ``minimum``, or 'auto'."""
    def parse(text: str) -> int | str:
        if text == "auto":
            return text
        try:
            return whole_number(text, minimum)
        except argparse.ArgumentTypeError:
            raise argparse.ArgumentTypeError(f"expected a whole number >= {minimum} or auto, got {text!r}") from None
    return parse


overlap_count = count_or_auto(0)
processes_count = count_or_auto(1)


def seconds(text: str, allow_zero: bool = False) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of seconds, got {text!r}") from None
    if not math.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        raise argparse.ArgumentTypeError(f"must be finite and {'>=' if allow_zero else '>'} 0, got {text}")
    return value


def nonnegative_seconds(text: str) -> float:
    return seconds(text, allow_zero=True)


def add_selection(p: argparse.ArgumentParser, precision: str | None = ",".join(PRECISIONS),
                  variants: bool = True) -> None:
    """Which cells: --backends --devices --precision (--variants)."""
    p.add_argument("--backends", default="all", help="comma-separated backend names, or all "
                   f"(known: {', '.join(backends.BACKENDS)})")
    p.add_argument("--devices", default="all", help="comma-separated: " + ",".join(backends.DEVICES))
    p.add_argument("--precision", default=precision, help="comma-separated: " + ",".join(PRECISIONS))
    if variants:
        p.add_argument("--variants", default="default",
                       help="comma-separated variants (e.g. default,fastmath) or all")


def add_scheduler(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run cells as tasks on a Dask cluster ('local': one worker per GPU of this "
                        "host, each pinned to its GPU and a core set; compare/running/scaleout.py)")


def check_scheduler(args: argparse.Namespace) -> None:
    if args.scheduler is not None and not args.scheduler.strip():
        raise UsageError("--scheduler is empty (give ADDRESS, or 'local')")


def add_timing(p: argparse.ArgumentParser, repeat: int | None = 10, min_time: float | None = 0.2,
               timeout: float = 900.0) -> None:
    p.add_argument("--repeat", type=positive_int, default=repeat, help="minimum timed calls per cell")
    p.add_argument("--min-time", type=nonnegative_seconds, default=min_time,
                   help="minimum timed seconds per cell")
    p.add_argument("--timeout", type=seconds, default=timeout, help="seconds before a cell is killed")
    p.add_argument("--overlap", type=overlap_count, default=None, metavar="N",
                   help="N more workers set up side by side with the next cell's, each timed alone (beside a GPU "
                   "cell's window on 8 or more cores), in every round of --processes too (auto: half the cores less "
                   "one; default: auto on fewer than 8 cores, where every window is alone, without --busy; else 0, "
                   "one cell at a time: docs/measurement.md, 'Overlapped set-ups')")


def add_processes(p: argparse.ArgumentParser) -> None:
    """--processes: the repeats across worker processes (``compare.running.repeats``), which the driver
    runs for every timed suite."""
    p.add_argument("--processes", type=processes_count, default=1, metavar="N",
                   help="time every cell in N independent worker processes (auto: until each "
                        "figure's 95 %% interval is within 5 %% of its median, 6 to 10), in seeded "
                        "interleaved rounds; the record keeps every process's figure, the median "
                        "and its interval (time.processes; docs/measurement.md); processes 4 on "
                        "start from the kernel caches the 3rd kept, so time to first result is the "
                        "3 cold ones' (a non-default variant: processes 2 on start from the 1st's, "
                        "its first result is the 1st's alone); a cell whose timings no row ranks "
                        "stops there: a fast-math variant after 1 process, its scenario at its "
                        "defaults on a device not in Scenario.timings_ranked_on after 3, a "
                        "non-default variant 1. Default 1: one "
                        "process per cell, a figure no ranking relies on")
    p.add_argument("--sitting", type=seconds, default=None, metavar="S",
                   help="with --processes auto: a round past the fewest processes (6) starts only "
                        "if, at the last round's pace, it ends within S seconds of the run's start "
                        "(one sitting on a lent machine); the fewest always run")


def add_output(p: argparse.ArgumentParser, out: str) -> None:
    p.add_argument("--out", default=out, help=f"output directory (default {out})")
    p.add_argument("--no-plots", action="store_true", help="write no PNG files")


def add_page(p: argparse.ArgumentParser) -> None:
    p.add_argument("--page", default=None, metavar="FILE", help="write one Markdown page")
    p.add_argument("--title", default=None, help="the page's title")
    p.add_argument("--notes", default=None, metavar="FILE",
                   help="hand-written Markdown put under the title (never numbers)")


def given(args: argparse.Namespace, add_arguments: Callable[[argparse.ArgumentParser], None],
          *positional: str) -> list[str]:
    """The options of ``args`` that differ from their defaults (as ``--name``), where
    ``add_arguments`` builds the subcommand's parser and ``positional`` satisfies it."""
    p = Parser(add_help=False)
    add_arguments(p)
    defaults = vars(p.parse_args(list(positional)))
    dests = {a.dest: a for a in p._actions}
    return [a.option_strings[0] if a.option_strings else a.dest
            for k, a in dests.items() if k in defaults and getattr(args, k, defaults[k]) != defaults[k]]


def refuse_inapplicable(args: argparse.Namespace, add_arguments: Callable[[argparse.ArgumentParser], None],
                        allowed: Iterable[str],
                        where: str, *positional: str) -> None:
    """A one-line UsageError for the first option given that does not apply ``where``."""
    allowed = set(allowed)
    for opt in given(args, add_arguments, *positional):
        if opt not in allowed:
            raise UsageError(f"{opt} does not apply {where}")


def no_duplicates(items: Iterable[str], what: str) -> list[str]:
    items = list(items)
    dup = next((v for i, v in enumerate(items) if v in items[:i]), None)
    if dup is not None:
        raise UsageError(f"{what} names {dup!r} twice")
    return items


def selection(args: argparse.Namespace) -> dict[str, list[str]]:
    """Validated backend, device, precision and variant lists (reference backend first)."""
    chosen = names(args.backends, backends.BACKENDS, "backends")
    ref = backends.reference()
    out: dict[str, list[str]] = {
        "backends": sorted(chosen, key=lambda n: n != ref),
        "devices": names(args.devices, backends.DEVICES, "devices"),
    }
    if getattr(args, "precision", None) is not None:
        out["precisions"] = names(args.precision, PRECISIONS, "precision")
    if hasattr(args, "variants"):
        offered = sorted({v for n in chosen for v in backends.get(n).variants}
                         | {v for n in chosen for vs in backends.get(n).scenario_variants.values() for v in vs})
        out["variants"] = names(args.variants, offered, "variants")
    return out


def check_precision(sc: scenarios.Scenario, params: Any, precision: str) -> None:
    """Refuse a float parameter that is finite in float64 but not in the cell's precision (it
    would overflow to inf, or a nonzero value round to 0, when the inputs are rounded to it)."""
    import dataclasses

    import numpy as np
    dt = np.dtype(dtype_of(precision)).type
    for f in dataclasses.fields(params):
        v = getattr(params, f.name)
        if not isinstance(v, float):
            continue
        with np.errstate(over="ignore", under="ignore"):
            r = dt(v)
        if not np.isfinite(r) or (v != 0 and r == 0):
            raise ParamError(f"{sc.name}: {f.name}={v!r} is not representable in {precision} "
                             f"(rounds to {float(r)!r}); give --precision without {precision}")


def parse_sets(pairs: list[str]) -> dict[str, str]:
    """--set KEY=VALUE pairs (repeatable) as a dict; a key given twice is refused."""
    raw: dict[str, str] = {}
    for pair in pairs:
        if "=" not in pair:
            raise UsageError(f"--set expects KEY=VALUE, got {pair!r}")
        k, v = (s.strip() for s in pair.split("=", 1))
        if not k:
            raise UsageError(f"--set expects KEY=VALUE, got {pair!r}")
        if k in raw:
            raise UsageError(f"--set gives {k!r} twice")
        raw[k] = v
    return raw


def scenario_sets(raw: dict[str, str], chosen: list[scenarios.Scenario]) -> dict[str, dict[str, str]]:
    """Split --set values among the chosen scenarios (a key applies to every scenario that has
    it); a key no chosen scenario knows is refused. The values stay the strings given: each
    scenario coerces them into its ``Params`` (``Scenario.params``)."""
    known = {sc.name: {f.name for f in dataclasses.fields(sc.Params)} for sc in chosen}
    unknown = [k for k in raw if not any(k in fields for fields in known.values())]
    if unknown:
        allk = sorted(set().union(*known.values())) if known else []
        raise ParamError(f"unknown parameter {unknown[0]!r} (known: {', '.join(allk)})")
    return {sc.name: {k: v for k, v in raw.items() if k in known[sc.name]} for sc in chosen}


def shown(text: str) -> str:
    """``text`` with what a terminal cannot show on one line escaped as ``repr`` does (a newline
    as \\n, a byte that is not UTF-8 as \\xff): an error naming a hostile path stays one line."""
    return "".join(f"\\x{ord(c) - 0xDC00:02x}" if 0xDC80 <= ord(c) <= 0xDCFF      # undecodable byte
                   else c if c.isprintable() else repr(c)[1:-1] for c in text)


def check_utf8(argv: list[str]) -> None:
    """Refuse a word that is not UTF-8 (a path with such a byte) up front: results and pages are
    UTF-8 text naming their command and paths, so it would fail only after every cell ran."""
    for i, word in enumerate(argv):
        try:
            word.encode("utf-8")
        except UnicodeEncodeError:
            opt = argv[i - 1] + " " if i and argv[i - 1].startswith("-") and "=" not in word else ""
            raise UsageError(f"{opt}{shown(word)}: not valid UTF-8 (results and pages are UTF-8 text); "
                             "give a UTF-8 name") from None
