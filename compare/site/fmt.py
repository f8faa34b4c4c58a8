"""Numbers in words for the site: times, rates, bytes, ratios, and the matrix's cell text."""
from __future__ import annotations

import math
from typing import Mapping

from compare.render.colors import BANDS
from compare.measuring.noise import MARK as NOISY_MARK
from compare.site.matrix import Cell
from compare.spec import ParamValue

BAND_EMOJI = {b.name: b.emoji for b in BANDS}
REFERENCE_MARK = "✎"           # a cell shown beside the ranking, never in it (a hand adjoint)
UNTIMED_MARK = "†"             # a variant of the framework not timed at the row's point (site/untimed.py)


def _g(x: float) -> str:
    """Three significant digits without an exponent (999.5 rounds to 1000, not 1e+03)."""
    return f"{x:.3g}" if abs(x) < 999.5 else f"{x:.0f}"


def seconds(v: float | None) -> str:
    if v is None or not math.isfinite(v):
        return "-"
    if v >= 120:
        return f"{v / 60:.3g} min"
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("µs", 1e-6), ("ns", 1e-9)):
        if abs(v) >= scale or unit == "ns":
            return f"{_g(v / scale)} {unit}"
    return f"{v:.3g} s"


def with_floors(v: float | None, n: float | None, own: bool = False) -> str:
    """A per-call figure and the same in its run's launch floors: ``37.9 µs = 2.77 floors``, or in
    its cell's own (``own``): ``37.9 µs = 2.77 cell floors``; the figure alone where there is no floor."""
    unit = "cell floors" if own else "floors"
    return seconds(v) + (f" = {_g(n)} {unit}" if v is not None and n is not None and math.isfinite(n) else "")


def rate(v: float | None, unit: str = "/s") -> str:
    if v is None or not math.isfinite(v):
        return "-"
    for suffix, scale in (("T", 1e12), ("G", 1e9), ("M", 1e6), ("k", 1e3)):
        if abs(v) >= scale:
            return f"{_g(v / scale)} {suffix}{unit}"
    return f"{_g(v)} {unit}"


def nbytes(v: float | None) -> str:
    if v is None or not math.isfinite(v):
        return "-"
    for unit, scale in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if abs(v) >= scale:
            return f"{_g(v / scale)} {unit}"
    return f"{v:.0f} B"


def value(v: float | None, unit: str) -> str:
    """A row's figure in its unit: 's' time, 'B' bytes, '1/s' a rate, 'x' a plain ratio."""
    if v is None:
        return "-"
    return {"s": seconds, "B": nbytes, "1/s": rate}.get(unit, lambda x: f"{x:.3g}")(v)


def pct(v: float | None) -> str:
    return "-" if v is None or not math.isfinite(v) else f"{100 * v:.0f} %"


def ratio(r: float) -> str:
    return f"{r:.2f}×" if r < 10 else f"{r:.3g}×" if r < 1000 else f"{r:.0f}×"


def fraction(v: float | None, label: str = "") -> str:
    """A hardware fraction as a percentage, labelled where it is not a plain fraction of the
    memory bandwidth (``cache (154 %)``, ``above copy (102 %)``: data.fraction_label)."""
    return pct(v) if not label or v is None else f"{label} ({pct(v)})"


def cell_text(c: Cell) -> str:
    """What the matrix shows: the ratio to the row's best, or why there is none; marked where a
    variant of the framework was not timed at the row's point."""
    untimed = UNTIMED_MARK if c.untimed else ""
    if c.ratio is not None:
        ref = f" {REFERENCE_MARK}" if c.reference else ""
        return ratio(c.ratio) + (NOISY_MARK if c.noisy else "") + untimed + ref
    if c.status in ("error", "mismatch"):
        return "✗ " + c.status + untimed
    return ("skipped" if c.status == "skipped" else "—") + untimed


def untimed_text(c: Cell) -> str:
    """The variants of the cell's framework not timed at the row's point, in words ('' if none)."""
    return f"not timed at this point: {', '.join(c.untimed)}" if c.untimed else ""


def variant_label(c: Cell) -> str:
    """The winning variant's name where it is not the default (the matrix's small label)."""
    return c.variant if c.winner_not_default else ""


def default_text(c: Cell, unit: str) -> str:
    """The default variant's figure beside a winning other variant: ``40 µs (4.80×)``."""
    if c.default_value is None:
        return "not measured for this row"
    return value(c.default_value, unit) + (f" ({ratio(c.default_ratio)})" if c.default_ratio else "")


def cell_title(c: Cell, unit: str, reference: str = "a reference") -> str:
    """The cell's tooltip: the figure itself, its variant and spread, or the reason;
    ``reference`` names what a reference cell is (the rule's words)."""
    if c.value is None:
        return "; ".join(x for x in (c.reason or c.status, untimed_text(c)) if x)
    parts = [value(c.value, unit)]
    if c.reference:
        parts.append(f"{reference}: beside the ranking, never ranked")
    elif c.tied:
        parts.append("shares the top of the row")
    if c.winner_not_default:
        parts.append(f"fastest variant {c.variant}; the default variant: {default_text(c, unit)}")
    if c.lo is not None and c.hi is not None and c.hi > c.lo:
        parts.append(f"quartiles {value(c.lo, unit)} – {value(c.hi, unit)}")
    if c.ci is not None:
        parts.append(f"95 % interval over {c.processes} processes {value(c.ci[0], unit)} – {value(c.ci[1], unit)}")
    if c.noisy:
        parts.append(f"noisy: {c.noisy}")
    if c.untimed:
        parts.append(f"{untimed_text(c)} (the fastest of the variants timed)")
    return "; ".join(parts)


def params_text(p: Mapping[str, ParamValue], defaults: Mapping[str, ParamValue]) -> str:
    """The parameters that differ from the scenario's defaults, as ``k=v`` (or 'defaults')."""
    diff = [f"{k}={v}" for k, v in (p or {}).items() if defaults.get(k, v) != v]
    return ", ".join(diff) if diff else "defaults"
