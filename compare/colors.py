"""A backend's colour, the same in every plot of every suite (charts, sweep plots, stress plots)."""
from __future__ import annotations


def backend_color(name: str) -> str:
    """A backend's own colour (``Backend.color``) in every plot, whatever else ran; a backend
    without one gets the colour of its place in the registry."""
    import backends  # the registry discovers its packages: loaded only when a plot is drawn
    b = backends.BACKENDS.get(name)
    if b is not None and b.color:
        return b.color
    names = list(backends.BACKENDS)
    return f"C{names.index(name) % 10}" if name in names else "0.4"
