"""Colours shared by every format: a backend's colour in every plot, and the matrix's bands (the
same band, emoji and swatch in the Markdown matrix, the HTML matrix and its picture)."""
from __future__ import annotations

import dataclasses


def backend_color(name: str) -> str:
    """A backend's own colour (``Backend.color``) in every plot, whatever else ran; a backend
    without one gets the colour of its place in the registry."""
    import backends  # the registry discovers its packages: loaded only when a plot is drawn
    b = backends.BACKENDS.get(name)
    if b is not None and b.color:
        return b.color
    names = list(backends.BACKENDS)
    return f"C{names.index(name) % 10}" if name in names else "0.4"


@dataclasses.dataclass(frozen=True)
class Band:
    name: str                     # the CSS class and compare.site.matrix.Cell.band
    emoji: str                    # the Markdown matrix's mark: the swatch's colour
    background: str               # the HTML cell's and the picture's colour
    text: str                     # the text colour on it
    words: str                    # what the band means, in the legend
    bound: float | None = None    # ranked bands by ratio: the upper bound of the ratio


# The one definition of the matrix's bands: Markdown, HTML, the picture and the legend read it.
BANDS: tuple[Band, ...] = (
    Band("best", "🟩", "#1a7f37", "#ffffff", "**bold**: the best, or tied with it"),
    Band("near", "🟨", "#f7e07a", "#1b1f24", "within {bound}× of the leader", 2.0),
    Band("far", "🟧", "#f5a55a", "#1b1f24", "within {bound}×", 5.0),
    Band("poor", "🟥", "#f2a09a", "#1b1f24", "beyond {bound}×"),
    Band("ref", "🟦", "#b6d4f2", "#1b1f24", "`✎` a hand-written adjoint on a gradient row: its ratio to "
         "the best automatic differentiation, shown as a reference and never ranked"),
    Band("none", "⬜", "#eceff1", "#57606a", "not measured, skipped or failed"),
)
BAND = {b.name: b for b in BANDS}


def band_words(b: Band) -> str:
    """What a band means, its bound read from the bands (beyond the last bound: ``poor``)."""
    last = max(x.bound for x in BANDS if x.bound is not None)
    return b.words.replace("{bound}", f"{b.bound if b.bound is not None else last:g}")


def band_css() -> str:
    """The bands as CSS classes (the best in bold, as the Markdown matrix bolds it)."""
    return "".join(f".{b.name}{{background:{b.background};color:{b.text}"
                   + (";font-weight:600" if b.name == "best" else "") + "}" for b in BANDS)
