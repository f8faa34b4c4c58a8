"""Generic figures for the run's plots and the report site: legible with a dozen frameworks and
their variants, and byte-for-byte the same PNG for the same input (fixed size and dpi, Agg, no
software/date metadata). Every figure is saved atomically (``compare.files.save_figure``) and,
unless ``data=False``, its numbers are written beside it as ``<name>.csv`` (``write_csv``).

    Bar(framework, variant, value, lo=None, hi=None, mark="")
        one bar; value None = not measured (failed, skipped): an empty slot labelled ``mark``;
        lo/hi = the spread, drawn as whiskers; a ``mark`` beside a value is printed after it
    Panel(title, bars)                    one axes of a multi-panel bar figure
    bars(path, title, xlabel, bars, *, log=False, better="lower", note="", fmt=None,
         reference=None, ratios=False, data=True)
        horizontal bars, best first, labelled at their ends (``fmt``; ``ratios``: and the ratio
        to the best), a dashed line at the best or at ``reference=(value, label)`` (the bars grow
        from it: a speed-up's baseline); log=None: a log axis where values span over 20x
    bar_panels(path, title, xlabel, panels, *, ...same keywords)    one panel per group
    (bar_panels and curves drawn once per process for equal arguments: chart_memo)
    Series(label, framework, xs, ys, lo=None, hi=None, dashed=False)
    curves(path, title, xlabel, ylabel, series, *, logx=True, logy=True, note="", data=True)
        lines with markers; lo/hi as a shaded band
    helpers: write_csv (floats to 6 digits, None as ""), colors, hatch, tidy_log (1-2-5 labels
    on log axes), pyplot (Agg), save (atomic, deterministic, layout checked), RC (rcParams)

Colours: a registered backend keeps ``compare.render.colors.backend_color``; any other framework a spare
colour chosen from its name, moved on only when taken. Variants are hatched or marked, never coloured.
"""
from __future__ import annotations

import csv
import io
import math
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterable, Sequence, cast

from compare.render import figure_check
from compare.render.chart_memo import memo
from compare.render.colors import backend_color
from compare.files import atomic_write, save_figure

if TYPE_CHECKING:
    from matplotlib.typing import RcKeyType

DPI = 110
WIDTH = 9.0                                  # inches; heights follow the number of bars
BAR_IN = 0.24                                # height per bar: 8-point labels never touch
LEGEND_INSIDE = 6                            # more entries than this: legend below the axes
# known variants first, so their hatches are the same in every figure whatever else ran
VARIANTS = ("default", "fastmath", "graph", "compile", "vector", "tile", "record_cmd", "checkpoint")
HATCHES = ("", "//", "..", "xx", "\\\\", "++", "--", "||", "**", "oo")
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">", "h")
# colours no registered backend uses (matplotlib's C0..C9 are tab10), for unknown frameworks
SPARE = ("#aec7e8", "#ffbb78", "#98df8a", "#ff9896", "#c5b0d5", "#c49c94", "#f7b6d2", "#dbdb8d",
         "#9edae5", "#393b79", "#637939", "#8c6d31", "#843c39", "#7b4173", "#000000")
RC: dict[RcKeyType, Any] = {
    "font.size": 9, "axes.titlesize": 9, "axes.labelsize": 9, "xtick.labelsize": 8,
    "ytick.labelsize": 8, "legend.fontsize": 8, "hatch.linewidth": 0.8, "svg.hashsalt": "charts"}


@dataclass(frozen=True)
class Bar:
    framework: str
    variant: str
    value: float | None
    lo: float | None = None
    hi: float | None = None
    mark: str = ""


@dataclass(frozen=True)
class Panel:
    title: str
    bars: list[Bar] = field(default_factory=list)


@dataclass(frozen=True)
class Series:
    label: str
    framework: str
    xs: list[float]
    ys: list[float]
    lo: list[float] | None = None
    hi: list[float] | None = None
    dashed: bool = False


def pyplot() -> Any:
    """matplotlib.pyplot on the Agg backend (no display, the same pixels everywhere)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _order(framework: str) -> tuple[int, str]:
    import backends
    b = backends.BACKENDS.get(framework)
    return (b.display_order if b is not None else 1000, framework)


def colors(frameworks: Iterable[str]) -> dict[str, str]:
    """framework -> colour, in display order (registry order, then by name); distinct within
    the call, stable across calls for registered backends and for unknown names alike."""
    import backends
    names = sorted(set(frameworks), key=_order)
    out = {n: backend_color(n) for n in names if n in backends.BACKENDS}
    used = set(out.values())
    for n in sorted(n for n in names if n not in out):
        i = zlib.crc32(n.encode()) % len(SPARE)
        while SPARE[i] in used and len(used) < len(SPARE) + 10:
            i = (i + 1) % len(SPARE)
        out[n] = SPARE[i]
        used.add(SPARE[i])
    return {n: out[n] for n in names}


def hatch(variant: str) -> str:
    """The variant's hatch ('' for the default), the same in every figure."""
    if variant in VARIANTS:
        return HATCHES[VARIANTS.index(variant) % len(HATCHES)]
    return HATCHES[1 + zlib.crc32(variant.encode()) % (len(HATCHES) - 1)]


def _fmt(v: float) -> str:
    return format(v, ".3g")


def _cell(v: Any) -> str:
    return "" if v is None else format(v, ".6g") if isinstance(v, float) else str(v)


def write_csv(path: Path, headers: Sequence[str], rows: Iterable[Sequence[Any]]) -> None:
    """A figure's numbers beside it, atomically; floats to 6 significant digits, None as ''."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(headers)
    w.writerows([_cell(v) for v in r] for r in rows)
    atomic_write(Path(path), buf.getvalue())


def tidy_log(ax: Any, fmt: Callable[[float], str] | None = None) -> None:
    """Readable base-10 log axes: over two or more decades label the powers of ten only, over
    less the 1-2-5 ticks, and every tick where fewer than two of those are in range
    (matplotlib's default overprints minor labels); labels in ``fmt``, else all plain or all
    powers of ten on one axis."""
    from matplotlib.ticker import FuncFormatter, NullFormatter

    def power(v: float) -> str:
        e = math.floor(math.log10(v) + 1e-9)
        m = round(v / 10**e, 6)
        return f"${m:g}\\times10^{{{e}}}$" if m != 1 else f"$10^{{{e}}}$"

    def mantissa(v: float) -> float:
        return round(v / 10**math.floor(math.log10(v) + 1e-9), 6) if v > 0 else 0.0
    for axis, (lo, hi) in ((ax.xaxis, ax.get_xlim()), (ax.yaxis, ax.get_ylim())):
        lo, hi = min(lo, hi), max(lo, hi)
        if axis.get_scale() != "log" or lo <= 0:
            continue
        short = fmt or ((lambda v: f"{v:g}") if 1e-3 <= lo and hi <= 1e4 else power)
        powers = math.floor(math.log10(hi)) - math.ceil(math.log10(lo)) + 1
        e0 = math.floor(math.log10(lo))
        in_range = [m * 10.0**e for e in (e0, e0 + 1) for m in (1, 2, 5) if lo <= m * 10.0**e <= hi]
        keep = (1.0, 2.0, 5.0) if len(in_range) >= 2 else tuple(float(m) for m in range(1, 10))
        axis.set_major_formatter(FuncFormatter(lambda v, _p, f=short: f(v) if v > 0 else ""))
        axis.set_minor_formatter(NullFormatter() if powers >= 2 else FuncFormatter(
            lambda v, _p, f=short, k=keep: f(v) if mantissa(v) in k else ""))


def save(fig: Any, path: Path) -> None:
    """Atomically, fixed dpi, no metadata that makes bytes differ, layout checked; closed."""
    figure_check.checked(lambda: save_figure(fig, path, dpi=DPI, metadata={"Software": None}), path)
    pyplot().close(fig)


def _legend(fig: Any, ax: Any, handles: list[Any]) -> None:
    """Inside the axes (best corner) for a few entries; below the axes, in columns, for more."""
    if not handles:
        return
    if len(handles) <= LEGEND_INSIDE:
        ax.legend(handles=handles, loc="best", framealpha=0.85)
    else:
        fig.legend(handles=handles, loc="outside lower center", ncol=min(5, len(handles)),
                   frameon=False)


def _fw_handles(cmap: dict[str, str], patch: bool) -> list[Any]:
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    if patch:
        return [Patch(facecolor=c, edgecolor="k", lw=0.5, label=f) for f, c in cmap.items()]
    return [Line2D([], [], color=c, marker="o", ls="", label=f) for f, c in cmap.items()]


def _sorted_bars(bars: list[Bar], better: str) -> list[Bar]:
    sign = -1.0 if better == "higher" else 1.0
    ok = [b for b in bars if b.value is not None and math.isfinite(b.value)]
    rest = [b for b in bars if b not in ok]
    ok.sort(key=lambda b: (sign * cast(float, b.value), _order(b.framework), b.variant))  # ok: value set
    rest.sort(key=lambda b: (_order(b.framework), b.variant))
    return ok + rest


def _ratio(r: float) -> str:
    return f"{r:.2f}" if r < 10 else (f"{r:.3g}" if r < 1000 else f"{r:.0f}")


def _draw_bars(ax: Any, panel: Panel, cmap: dict[str, str], log: bool | None, better: str,
               fmt: Callable[[float], str], reference: tuple[float, str] | None, ratios: bool) -> list[Bar]:
    bs = _sorted_bars(panel.bars, better)
    ok = [b for b in bs if b.value is not None and math.isfinite(b.value)]
    ends = [v for b in ok for v in (b.value, b.lo, b.hi) if v is not None and math.isfinite(v)]
    ends += [reference[0]] if reference else []
    pos = [v for v in ends if v > 0]
    if log is None:                     # per panel: a log axis only where values span decades
        log = bool(pos) and max(pos) / min(pos) > 20
    log = log and bool(pos)             # no positive value: a log axis has nothing to show
    if log and pos:                     # right of the largest end: about a third for the labels
        left = min(pos) / 2
        right = max(pos) * max(2.0, (max(pos) / left) ** 0.45)
    else:
        left = min(0.0, *ends) if ends else 0.0
        right = max(ends) + 0.45 * (max(ends) - left) if ends else 1.0
    right = right if right > left else left + 1.0
    start = reference[0] if reference else left      # bars grow from the reference line
    best = ok[0].value if ok else None
    ys = list(range(len(bs)))
    for y, b in zip(ys, bs):
        if b.value is None or not math.isfinite(b.value):
            ax.text(left * 1.1 if log else left, y, f" {b.mark or 'not measured'}", va="center",
                    ha="left", fontsize=8, style="italic", color="0.35")
            continue
        ax.barh(y, b.value - start, left=start, height=0.72, color=cmap[b.framework],
                hatch=hatch(b.variant), edgecolor="0.15", linewidth=0.5)
        if b.lo is not None or b.hi is not None:
            lo, hi = b.lo if b.lo is not None else b.value, b.hi if b.hi is not None else b.value
            ax.errorbar(b.value, y, xerr=[[max(b.value - lo, 0)], [max(hi - b.value, 0)]], fmt="none",
                        ecolor="k", elinewidth=0.9, capsize=2.5)
        end = max(v for v in (b.value, b.hi, reference[0] if reference else None) if v is not None)
        text = fmt(b.value)
        if ratios and best and b.value != best:
            text += (f"  ({_ratio(b.value / best)}× best)" if better == "lower"
                     else f"  (best {_ratio(best / b.value)}×)")
        text += f"  [{b.mark}]" if b.mark else ""
        ax.text(end * 1.08 if log else end + (right - left) * 0.01, y, text, va="center", fontsize=7.5)
    ax.set_yticks(ys, [b.framework + ("" if b.variant in ("", "default") else f" {b.variant}") for b in bs])
    ax.set_ylim(len(bs) - 0.4, -0.6)                       # best at the top
    if log:
        ax.set_xscale("log")
    ax.set_xlim(left, right)
    line = reference or ((best, "best in panel") if best is not None and len(ok) > 1 else None)
    if line:
        ax.axvline(line[0], color="0.25", ls="--", lw=1, zorder=0.5)
    ax.grid(True, axis="x", which="major", alpha=0.3)
    ax.set_axisbelow(True)
    if panel.title:
        ax.set_title(panel.title, loc="left")
    tidy_log(ax, fmt if fmt is not _fmt else None)
    if not log and fmt is not _fmt:
        from matplotlib.ticker import FuncFormatter
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _p: fmt(v) if v else "0"))
    return bs


def bars(path: Path, title: str, xlabel: str, bars: list[Bar], *, log: bool | None = False,
         better: str = "lower", note: str = "", fmt: Callable[[float], str] | None = None,
         reference: tuple[float, str] | None = None, ratios: bool = False, data: bool = True) -> None:
    """One horizontal bar chart (see the module docstring)."""
    bar_panels(path, title, xlabel, [Panel("", list(bars))], log=log, better=better, note=note,
               fmt=fmt, reference=reference, ratios=ratios, data=data)


@memo
def bar_panels(path: Path, title: str, xlabel: str, panels: list[Panel], *, log: bool | None = False,
               better: str = "lower", note: str = "", fmt: Callable[[float], str] | None = None,
               reference: tuple[float, str] | None = None, ratios: bool = False,
               data: bool = True) -> None:
    """Bar charts stacked one panel per group (each sorted best first, its own x range), one
    shared legend of frameworks and variants."""
    plt = pyplot()
    panels = [p for p in panels if p.bars] or [Panel("nothing measured", [])]
    allb = [b for p in panels for b in p.bars]
    cmap = colors(b.framework for b in allb)
    heights = [max(len(p.bars), 1) * BAR_IN + 0.7 for p in panels]
    legend_rows = -(-(len(cmap) + len({b.variant for b in allb}) + 1) // 5)
    size = (WIDTH, sum(heights) + 0.9 + 0.25 * legend_rows + (0.2 if note else 0))
    import matplotlib
    with matplotlib.rc_context(RC):
        fig = plt.figure(figsize=size, layout="constrained")
        axes = fig.subplots(len(panels), 1, squeeze=False, gridspec_kw={"height_ratios": heights})[:, 0]
        drawn = [_draw_bars(ax, p, cmap, log, better, fmt or _fmt, reference, ratios)
                 for ax, p in zip(axes, panels)]
        axes[-1].set_xlabel(xlabel + (f"\n{note}" if note else ""))
        fig.suptitle(title + f"  ({better} is better)", fontsize=10)
        from matplotlib.lines import Line2D
        from matplotlib.patches import Patch
        handles = _fw_handles(cmap, True)
        handles += [Patch(facecolor="white", edgecolor="k", hatch=hatch(v), lw=0.5, label=f"variant {v}")
                    for v in sorted({b.variant for b in allb} - {"", "default"}, key=_variant_key)]
        handles.append(Line2D([], [], color="0.25", ls="--", lw=1,
                              label=reference[1] if reference else "best in panel"))
        if len(handles) > LEGEND_INSIDE:
            _legend(fig, axes[-1], handles)
        else:
            fig.legend(handles=handles, loc="outside right upper", frameon=False)
        save(fig, Path(path))
    if data:
        write_csv(Path(path).with_suffix(".csv"), ("panel", "framework", "variant", "value", "lo", "hi", "mark"),
                  [(p.title, b.framework, b.variant, b.value, b.lo, b.hi, b.mark)
                   for p, bs in zip(panels, drawn) for b in bs])


def _variant_key(v: str) -> tuple[int, str]:
    return (VARIANTS.index(v) if v in VARIANTS else len(VARIANTS), v)


def _one_axes(n_legend: int, height: float) -> tuple[Any, Any]:
    """A figure of one axes, taller by the rows of a legend that goes below it."""
    rows = -(-n_legend // 5) if n_legend > LEGEND_INSIDE else 0
    return pyplot().subplots(figsize=(WIDTH, height + 0.25 * rows), layout="constrained")


def _finish(fig: Any, ax: Any, path: Path, title: str, xlabel: str, ylabel: str, note: str,
            logx: bool, logy: bool, handles: list[Any]) -> None:
    ax.set_xscale("log" if logx else "linear")
    ax.set_yscale("log" if logy else "linear")
    ax.set_xlabel(xlabel + (f"\n{note}" if note else ""))
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="major", alpha=0.3)
    tidy_log(ax)
    _legend(fig, ax, handles)
    save(fig, Path(path))


@memo
def curves(path: Path, title: str, xlabel: str, ylabel: str, series: list[Series], *,
           logx: bool = True, logy: bool = True, note: str = "", data: bool = True) -> None:
    """Lines against x, one colour per framework, a marker per series of the same framework,
    the spread (lo/hi) as a shaded band."""
    import matplotlib
    cmap = colors(s.framework for s in series)
    with matplotlib.rc_context(RC):
        fig, ax = _one_axes(len(series), 5.2)
        seen: dict[str, int] = {}
        handles = []
        for s in sorted(series, key=lambda s: (_order(s.framework), s.label)):
            m = MARKERS[seen.setdefault(s.framework, 0) % len(MARKERS)]
            seen[s.framework] += 1
            handles += ax.plot(s.xs, s.ys, ls="--" if s.dashed else "-", marker=m, ms=4,
                               color=cmap[s.framework], lw=1.3, label=s.label)
            if s.lo is not None and s.hi is not None:
                ax.fill_between(s.xs, s.lo, s.hi, color=cmap[s.framework], alpha=0.18, lw=0)
        _finish(fig, ax, path, title, xlabel, ylabel, note, logx, logy, handles)
    if data:
        write_csv(Path(path).with_suffix(".csv"), ("series", "framework", "x", "y", "lo", "hi"),
                  [(s.label, s.framework, x, y, s.lo[i] if s.lo else None, s.hi[i] if s.hi else None)
                   for s in series for i, (x, y) in enumerate(zip(s.xs, s.ys))])
