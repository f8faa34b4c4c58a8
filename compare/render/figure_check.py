"""A drawn figure's layout, checked where it is saved: every text inside the canvas, no two texts'
boxes overlapping, no legend over data points. Matplotlib knows where it put each text (its
window extent under the figure's renderer), so the check reads that, not pixels.

The verdict travels inside the PNG as a text chunk (``LAYOUT_KEY``: JSON ``{"problems": [...]}``),
so a test of a built site can hold every figure it shows to it (tests/browser.py) and a PNG
saved without the check is told apart. Reading needs the standard library only.
"""
from __future__ import annotations

import contextlib
import json
import struct
import zlib
from pathlib import Path
from typing import Any, Callable, TypedDict, TypeVar

T = TypeVar("T")

LAYOUT_KEY = "compare-layout"
SLACK_PX = 1.0          # overlaps and overhangs up to this many pixels are antialiasing, not a fault
_PNG = b"\x89PNG\r\n\x1a\n"


def _drawn_texts(fig: Any) -> list[Any]:
    """The texts a draw of ``fig`` actually renders (a tick label outside the view, or an empty
    string, is never drawn): the renderer is asked, not the artist tree."""
    renderer = fig.canvas.get_renderer()
    seen: list[Any] = []

    def record(gc: Any, x: float, y: float, s: str, prop: Any, angle: float, ismath: Any = False,
               mtext: Any = None) -> None:
        if mtext is not None and s.strip() and mtext not in seen:
            seen.append(mtext)

    # laid out and measured as a real draw, nothing rasterised (the saved PNG was drawn already):
    # every draw_* is a no-op for this draw but draw_text, which only records. The renderer's
    # no-op switch is matplotlib's own (what Figure.draw_without_rendering uses, not public); where
    # a matplotlib lacks it, the draw paints as well, with the same texts recorded.
    quiet = getattr(renderer, "_draw_disabled", None)
    with quiet() if quiet is not None else contextlib.nullcontext():
        renderer.draw_text = record
        try:
            fig.draw(renderer)
        finally:
            if quiet is None:                    # (the switch undoes its own on leaving)
                del renderer.draw_text           # the instance attribute: the class's method again
    return seen


def _name(t: Any) -> str:
    s = " ".join(t.get_text().split())
    return repr(s if len(s) <= 40 else s[:37] + "...")


STEP_PX = 3.0         # a drawn line's segments are checked at points this far apart


def _along(xy: Any, style: Any) -> Any:
    """A line's vertices (display coordinates) and, where it draws its segments, points along each
    at most ``STEP_PX`` apart: a legend over a segment between two vertices hides data too."""
    import numpy as np
    if style in ("None", "none", " ", "") or len(xy) < 2:
        return xy
    out = [xy]
    for a, b in zip(xy[:-1], xy[1:]):
        if np.all(np.isfinite(a)) and np.all(np.isfinite(b)):
            n = int(np.hypot(*(b - a)) // STEP_PX)
            if n > 1:
                t = np.linspace(0.0, 1.0, n + 1)[1:-1, None]
                out.append(a + t * (b - a))
    return np.concatenate(out)


def _data_points(ax: Any) -> Any:
    """Display coordinates of the axes' data: the vertices of its lines and points along their
    drawn segments, and the offsets of its scatters, drawn in data coordinates (a reference line
    across the axes is not data), those inside the axes."""
    import numpy as np
    pts = [_along(line.get_transform().transform(np.asarray(line.get_xydata(), float)), line.get_linestyle())
           for line in ax.get_lines()
           if line.get_visible() and len(line.get_xydata()) and line.get_transform().contains_branch(ax.transData)]
    pts += [c.get_offset_transform().transform(np.asarray(c.get_offsets(), float)) for c in ax.collections
            if c.get_visible() and len(c.get_offsets()) and c.get_offset_transform().contains_branch(ax.transData)]
    if not pts:
        return np.empty((0, 2))
    out = np.concatenate(pts)
    box = ax.bbox
    keep = np.all(np.isfinite(out), axis=1) & (out[:, 0] >= box.x0) & (out[:, 0] <= box.x1) \
        & (out[:, 1] >= box.y0) & (out[:, 1] <= box.y1)
    return out[keep]


def _covered(ax: Any, legend: Any, renderer: Any) -> int:
    """How many of the axes' data points lie under ``legend``."""
    box = legend.get_window_extent(renderer)
    pts = _data_points(ax)
    return int(((pts[:, 0] > box.x0) & (pts[:, 0] < box.x1) & (pts[:, 1] > box.y0)
                & (pts[:, 1] < box.y1)).sum()) if len(pts) else 0


# Where a legend may go inside the axes, in order; none clear of the data: below the axes.
INSIDE = ("best", "upper right", "upper left", "lower left", "lower right", "center right",
          "center left", "upper center", "lower center")
GAP_PT = 4.0          # between an axes' x label and a legend below it


class LegendStyle(TypedDict, total=False):
    """The legend keywords the figures set (matplotlib's ``legend`` takes them as they are; one
    not set is matplotlib's default)."""
    fontsize: float
    ncol: int


def _renderer(fig: Any) -> Any:
    if not hasattr(fig.canvas, "get_renderer"):       # closed by pyplot: draw it on Agg again
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        FigureCanvasAgg(fig)
    return fig.canvas.get_renderer()


def _inside(ax: Any, renderer: Any, style: LegendStyle) -> bool:
    """Put the legend at the first place inside the axes where it covers no data point."""
    for loc in INSIDE:
        if _covered(ax, ax.legend(loc=loc, **style), renderer) == 0:
            return True
    return False


def _below(ax: Any, renderer: Any, style: LegendStyle) -> float:
    """Put the legend under the axes' x label, in as many columns as the axes' width holds (a
    fixed distance in points, so a later layout keeps it there); its height in inches."""
    from matplotlib.transforms import ScaledTranslation
    fig = ax.figure
    ax.get_legend().remove()                  # the axes' own extent: tick labels and x label
    bottom = ax.get_tightbbox(renderer).y0
    drop = (ax.bbox.y0 - bottom) / fig.dpi + GAP_PT / 72
    one = ax.legend(**{**style, "ncol": 1}).get_window_extent(renderer).width
    ncol = max(1, int(ax.bbox.width // max(one, 1.0)))
    under = ax.transAxes + ScaledTranslation(0, -drop, fig.dpi_scale_trans)
    legend = ax.legend(**{**style, "ncol": ncol}, loc="upper center", bbox_to_anchor=(0.5, 0.0),
                       bbox_transform=under)
    return legend.get_window_extent(renderer).height / fig.dpi + drop


def place_legends(axes: list[Any], fontsize: float | None = None, ncol: int = 1) -> None:
    """Legends of ``axes`` (all of one figure) clear of their data: inside the axes where a
    place covers no point, else below the axes, the figure grown by what those take per row;
    then the figure is laid out (tight_layout). A layout that shrinks an axes may put data
    under a legend again, so the placing repeats (three rounds at most)."""
    if not axes:
        return
    style = LegendStyle(ncol=ncol)
    if fontsize is not None:
        style["fontsize"] = fontsize
    fig = axes[0].figure
    fig.tight_layout()
    renderer = _renderer(fig)
    below: set[int] = set()
    for _ in range(3):
        grow: dict[int, float] = {}
        for i, ax in enumerate(axes):
            legend = ax.get_legend()
            if legend is not None and (i in below or _covered(ax, legend, renderer) == 0):
                continue
            if not _inside(ax, renderer, style):
                row = ax.get_subplotspec().rowspan.start if ax.get_subplotspec() else 0
                grow[row] = max(grow.get(row, 0.0), _below(ax, renderer, style))
                below.add(i)
        if not grow:            # legends inside the axes leave the layout as it is
            return
        fig.set_figheight(fig.get_figheight() + sum(grow.values()))
        fig.tight_layout()


def keep_apart(texts: list[Any]) -> list[Any]:
    """Remove each of ``texts`` (labels placed at data points, in priority order) whose box
    overlaps an earlier one kept, or lies outside the canvas; the kept ones. Call it once the
    figure's layout is final."""
    if not texts:
        return []
    fig = texts[0].figure
    renderer = fig.canvas.get_renderer()
    fig.draw_without_rendering()        # laid out for the extents, nothing rasterised
    kept: list[tuple[Any, Any]] = []
    canvas = fig.bbox
    for t in texts:
        b = t.get_window_extent(renderer)
        outside = b.x0 < canvas.x0 or b.x1 > canvas.x1 or b.y0 < canvas.y0 or b.y1 > canvas.y1
        if outside or any(min(b.x1, c.x1) - max(b.x0, c.x0) > 0 and min(b.y1, c.y1) - max(b.y0, c.y0) > 0
                          for _, c in kept):
            t.remove()
        else:
            kept.append((t, b))
    return [t for t, _ in kept]


def problems(fig: Any) -> list[str]:
    """What is wrong with the layout of ``fig`` as it draws now (empty: nothing)."""
    if not hasattr(fig.canvas, "get_renderer"):     # closed by pyplot: draw it on Agg again
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        FigureCanvasAgg(fig)
    texts = _drawn_texts(fig)
    renderer = fig.canvas.get_renderer()
    canvas = fig.bbox
    boxes = [(t, t.get_window_extent(renderer)) for t in texts]
    out = []
    for t, b in boxes:
        over = max(canvas.x0 - b.x0, b.x1 - canvas.x1, canvas.y0 - b.y0, b.y1 - canvas.y1)
        if over > SLACK_PX:
            out.append(f"text {_name(t)} runs {over:.0f} px outside the canvas")
    for i, (t, b) in enumerate(boxes):
        for u, c in boxes[i + 1:]:
            w, h = min(b.x1, c.x1) - max(b.x0, c.x0), min(b.y1, c.y1) - max(b.y0, c.y0)
            if w > SLACK_PX and h > SLACK_PX:
                out.append(f"text {_name(t)} overlaps text {_name(u)} ({w:.0f} x {h:.0f} px)")
    for ax in fig.axes:
        legend = ax.get_legend()
        if legend is None or not legend.get_visible():
            continue
        inside = _covered(ax, legend, renderer)
        if inside:
            where = f"the axes {_name(ax.title)}" if ax.get_title() else "an axes"
            out.append(f"the legend of {where} covers {inside} data point{'s' if inside != 1 else ''}")
    return out


def report(fig: Any) -> str:
    """The verdict as the chunk's JSON (sorted keys: the same figure gives the same bytes)."""
    return json.dumps({"problems": problems(fig)}, sort_keys=True)


def _chunks(png: bytes) -> list[tuple[bytes, bytes]]:
    if not png.startswith(_PNG):
        raise ValueError("not a PNG")
    out, pos = [], len(_PNG)
    while pos + 8 <= len(png):
        n, kind = struct.unpack(">I4s", png[pos:pos + 8])
        out.append((kind, png[pos + 8:pos + 8 + n]))
        pos += 12 + n
    return out


def stamp(png: bytes, verdict: str) -> bytes:
    """``png`` with the verdict as a tEXt chunk right after its header."""
    body = LAYOUT_KEY.encode("latin-1") + b"\0" + verdict.encode("latin-1", "replace")
    chunk = struct.pack(">I", len(body)) + b"tEXt" + body + struct.pack(">I", zlib.crc32(b"tEXt" + body))
    head = len(_PNG) + 8 + struct.unpack(">I", png[len(_PNG):len(_PNG) + 4])[0] + 4    # after IHDR
    return png[:head] + chunk + png[head:]


def read(path: Path) -> list[str] | None:
    """The problems stamped in a PNG (empty: checked and clean), or None: never checked."""
    for kind, data in _chunks(Path(path).read_bytes()):
        if kind == b"tEXt":
            key, _, value = data.partition(b"\0")
            if key == LAYOUT_KEY.encode("latin-1"):
                return list(json.loads(value.decode("latin-1"))["problems"])
    return None


def save_checked(fig: Any, png: bytes) -> bytes:
    """The saved bytes of ``fig``, stamped with its layout's verdict (PNG only; others as they are)."""
    return stamp(png, report(fig)) if png.startswith(_PNG) else png


def checked(draw: Callable[[], T], png: Path, key: Any = None) -> T:
    """Run ``draw`` (a plot function that saves and closes its own figure into ``png``), catch
    the figure it saves on the way out, and stamp ``png`` with that figure's layout verdict: the
    sweep and stress plots save themselves, so their figures are checked here, not changed.
    ``key``: what the picture is drawn from (the function and its arguments but the path): an equal
    key drawn before in this process is written from memory, stamped (``chart_memo.remembered``)."""
    if key is not None:
        from compare.render import chart_memo
        return chart_memo.remembered(key, [Path(png)], lambda: checked(draw, png))
    from matplotlib.figure import Figure

    from compare.files import atomic_write
    saved: list[Any] = []
    original = Figure.savefig

    def spy(self: Any, *args: Any, **kwargs: Any) -> Any:
        saved.append(self)
        return original(self, *args, **kwargs)

    Figure.savefig = spy  # type: ignore[method-assign]   # for this draw only; restored below
    try:
        result = draw()
    finally:
        Figure.savefig = original  # type: ignore[method-assign]
    if saved and Path(png).exists():
        data = Path(png).read_bytes()
        if data.startswith(_PNG) and read(png) is None:
            atomic_write(Path(png), save_checked(saved[-1], data))
    return result
