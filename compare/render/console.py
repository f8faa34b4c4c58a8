"""What ``compare all | run`` prints when it ends: a screen, not a log.

In order: the table of the cells that ran (a skipped cell is no row: results.md has every one);
the skipped cells grouped by cause, one line each with the command that fixes it where the
backend's own reason names one; the summary (which never ranks a noisy cell); the noisy cells
counted by cause; where the time went; what was written; this run against the closest stored
report (``compare.site.versus``). ``--verbose`` prints today's full listing instead: every skipped
cell in the table, every noisy cell's reasons, one progress line per cell.
"""
from __future__ import annotations

import argparse
import re
import textwrap
from collections import Counter
from typing import Iterable

from backends.base import DEFAULT_VARIANT
from compare.measuring import noise
from compare.render import report
from compare.results.environment import RunEnvironment
from compare.results.record import Record

WIDTH = 118
MAX_CAUSES = 12         # more distinct causes than this: the rest counted in one line
# a backend's reason for a package it cannot import (backends.base.not_installed), and the
# install command a reason may end with ("... (install: CMD)" or "...; install: CMD")
NOT_INSTALLED = re.compile(r"\bnot importable\b")
INSTALL = re.compile(r"(\()?\binstall: (.+)$")
EXTRA = re.compile(r"^pip install -e '\.\[([\w,-]+)\]'$")


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The console's options of ``all | run | <scenario>``."""
    p.add_argument("--verbose", action="store_true",
                   help="the full listing: every skipped cell in the table, every noisy cell's "
                        "reasons, one progress line per cell (default: a screen)")
    p.add_argument("--against", default=None, metavar="DIR",
                   help="hold this run against the stored report in DIR (default: the closest "
                        "machine kind's under docs/results; 'none': no comparison)")


def install_hint(reason: str) -> tuple[str, str]:
    """(cause, command): a reason split at the install command it ends with ('' if none)."""
    m = INSTALL.search(reason)
    if not m:
        return reason, ""
    cmd = m[2][:-1] if m[1] and m[2].endswith(")") else m[2]
    return reason[:m.start()].rstrip(" ;:,("), cmd.strip()


def merge_commands(cmds: Iterable[str]) -> str:
    """The distinct install commands in one: the project's extras as one ``pip install -e '.[a,b]'``."""
    extras: list[str] = []
    other: list[str] = []
    for c in cmds:
        m = EXTRA.match(c)
        target = extras if m else other
        for item in (m[1].split(",") if m else [c]):
            if item not in target:
                target.append(item)
    head = [f"pip install -e '.[{','.join(extras)}]'"] if extras else []
    return "; ".join(head + other)


def _names(items: Iterable[str]) -> str:
    return ", ".join(dict.fromkeys(items))


def _fit(text: str, keep: str = "") -> str:
    """``text`` cut to one line of WIDTH with ``keep`` (a command) whole after it."""
    room = max(WIDTH - len(keep), 60)      # a long command makes the line longer, never the cause shorter
    if len(text) > room:
        text = text[:room - 1].rstrip() + "…"
    return text + keep


def skip_lines(records: list[Record], gpu_here: bool) -> list[str]:
    """The skipped cells grouped by cause, one line each: packages not installed (with the one
    command that installs them), a device this machine does not have, then every other reason
    by device and its first clause (the full text: results.md)."""
    skipped = [r for r in records if r.status == "skipped"]
    if not skipped:
        return []
    missing: dict[str, str] = {}               # backend -> its install command
    no_device: dict[str, list[Record]] = {}
    other: dict[tuple[str, str, str], list[Record]] = {}
    for r in skipped:
        if r.device != "cpu" and not gpu_here:
            no_device.setdefault(r.device, []).append(r)
        elif NOT_INSTALLED.search(r.reason):
            cmd = install_hint(r.reason)[1]
            if cmd or r.backend not in missing:
                missing[r.backend] = cmd
        else:
            cause, cmd = install_hint(r.reason)
            other.setdefault((r.device, cause.split("; ")[0], cmd), []).append(r)
    lines = []
    if missing:
        cmd = merge_commands(c for c in missing.values() if c)
        lines.append(_fit(f"  {_names(missing)} not installed", f": {cmd}" if cmd else ""))
    for dev, recs in no_device.items():
        lines.append(f"  {dev}: no GPU on this machine ({len(recs)} cells of {len({r.backend for r in recs})} "
                     "frameworks)")
    for (dev, cause, cmd), recs in sorted(other.items(), key=lambda kv: -len(kv[1])):
        who = _names(r.backend if r.variant == DEFAULT_VARIANT else f"{r.backend}/{r.variant}" for r in recs)
        lines.append(_fit(f"  {who} on {dev} ({len(recs)} cell{'' if len(recs) == 1 else 's'}): {cause}",
                          f": {cmd}" if cmd else ""))
    if len(lines) > MAX_CAUSES:
        rest = len(lines) - MAX_CAUSES + 1
        lines = lines[:MAX_CAUSES - 1] + [f"  ... and {rest} more causes (results.md gives every cell's reason)"]
    return [f"{len(skipped)} cells skipped (each with its reason in results.md):"] + lines


# a noise reason's kind, from the wording of compare/measuring/noise.py (a figure left out)
KINDS = ((re.compile(r"^host busy"), "host busy"), (re.compile(r"^spread "), "wide spread"),
         (re.compile(r"^\d+ repeats?$"), "few repeats"), (re.compile(r"taken between calls"), "host taken between calls"))


def _kind(why: str) -> str:
    return next((kind for pattern, kind in KINDS if pattern.search(why)), " ".join(why.split()[:3]))


def noise_brief(records: list[Record]) -> list[str]:
    """The noisy cells counted by cause and what to do (their reasons: results.md, --verbose)."""
    full = report.noise_lines(records)
    if not full:
        return []
    noisy = [r for r in records if r.status == "ok" and noise.reasons_for(r)]
    kinds = Counter(k for r in noisy for k in {_kind(x.why) for x in
                                               (r.time.noise.reasons if r.time and r.time.noise else None) or ()})
    why = ", ".join(f"{k} {n}" for k, n in kinds.most_common())
    head = (f"{noise.MARK} {len(noisy)} of {sum(r.status == 'ok' for r in records)} timed cells are noisy: "
            f"{why} (why: results.md)")
    return textwrap.wrap(head, WIDTH, subsequent_indent="    ") + [full[-1]]


def closing(records: list[Record], env: RunEnvironment, verbose: bool, wide: bool) -> list[str]:
    """The end of a run up to the summary and noise lines (the driver adds the time, the files
    written and the reference block)."""
    if verbose:
        return [report.tables(records, wide=wide).rstrip("\n"), "",
                *report.summary_lines(records), *report.noise_lines(records)]
    shown = [r for r in records if r.status != "skipped"]
    out = [report.tables(shown, wide=wide, brief=True).rstrip("\n"), ""] if shown else []
    return out + skip_lines(records, bool(env.get("gpus"))) + report.summary_lines(records) + noise_brief(records)


__all__ = ["add_arguments", "closing", "skip_lines", "noise_brief", "install_hint", "merge_commands"]
