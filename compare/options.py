"""The options every subcommand shares, their validation, and the one error path.

Every option is checked where it is parsed (finite, positive, known names, no duplicates), so bad
input is a one-line ``UsageError`` (exit 2) before any cell runs or any file is written.
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any, Iterable

import backends
import scenarios
from scenarios.base import PRECISIONS, ParamError

EXIT_OK, EXIT_FAIL, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


class UsageError(Exception):
    """Bad command-line usage; its message is one line."""


class Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:   # one line, exit 2, no usage dump
        raise UsageError(message)


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


def positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {value}")
    return value


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


def add_timing(p: argparse.ArgumentParser, repeat: int | None = 10, min_time: float | None = 0.2,
               timeout: float = 900.0) -> None:
    p.add_argument("--repeat", type=positive_int, default=repeat, help="minimum timed calls per cell")
    p.add_argument("--min-time", type=nonnegative_seconds, default=min_time,
                   help="minimum timed seconds per cell")
    p.add_argument("--timeout", type=seconds, default=timeout, help="seconds before a cell is killed")


def add_output(p: argparse.ArgumentParser, out: str) -> None:
    p.add_argument("--out", default=out, help=f"output directory (default {out})")
    p.add_argument("--no-plots", action="store_true", help="write no PNG files")


def add_page(p: argparse.ArgumentParser) -> None:
    p.add_argument("--page", default=None, metavar="FILE", help="write one Markdown page")
    p.add_argument("--title", default=None, help="the page's title")
    p.add_argument("--notes", default=None, metavar="FILE",
                   help="hand-written Markdown put under the title (never numbers)")


def selection(args: argparse.Namespace) -> dict[str, list[str]]:
    """Validated backend, device, precision and variant lists (reference backend first)."""
    chosen = names(args.backends, backends.BACKENDS, "backends")
    ref = backends.reference()
    out: dict[str, list[str]] = {
        "backends": sorted(chosen, key=lambda n: n != ref),
        "devices": names(args.devices, backends.DEVICES, "devices"),
    }
    if getattr(args, "precision", None):
        out["precisions"] = names(args.precision, PRECISIONS, "precision")
    if hasattr(args, "variants"):
        offered = sorted({v for n in chosen for v in backends.get(n).variants})
        out["variants"] = names(args.variants, offered, "variants")
    return out


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


def scenario_sets(raw: dict[str, str], chosen: list[scenarios.Scenario]) -> dict[str, dict[str, Any]]:
    """Split --set values among the chosen scenarios (a key applies to every scenario that has
    it); a key no chosen scenario knows is refused."""
    known = {sc.name: set(sc.Params.__dataclass_fields__) for sc in chosen}
    unknown = [k for k in raw if not any(k in fields for fields in known.values())]
    if unknown:
        allk = sorted(set().union(*known.values())) if known else []
        raise ParamError(f"unknown parameter {unknown[0]!r} (known: {', '.join(allk)})")
    return {sc.name: {k: v for k, v in raw.items() if k in known[sc.name]} for sc in chosen}


def output_directory(path: str) -> Path:
    """The output directory, created if needed and checked writable before any cell runs."""
    import os
    import tempfile
    if not path or not path.strip():
        raise UsageError("--out is empty (give a directory)")
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {path}: is a file, not a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out):
            pass
    except OSError as exc:
        raise UsageError(f"--out {path}: cannot write there ({exc.strerror or exc})") from None
    if not os.access(out, os.W_OK):
        raise UsageError(f"--out {path}: not writable")
    return out


def read_notes(path: str | None) -> str:
    """--notes FILE's text ('' without one)."""
    if not path:
        return ""
    try:
        with open(path, encoding="utf-8") as f:
            return f.read()
    except (OSError, UnicodeDecodeError) as exc:
        raise UsageError(f"cannot read --notes {path}: {getattr(exc, 'strerror', None) or exc}") from None
