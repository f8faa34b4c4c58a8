"""Plot helpers shared by every stress experiment's plot (drawn from the series in stress.json).

An experiment's ``plot(series, path, style)`` gets ``style`` from here, so a backend keeps its
colour (``Backend.color``) and a device its marker in every plot, whatever else ran. The log-axis
floor every plot uses is ``compare.stress.numerics.log_floor``.
"""
from __future__ import annotations

import io
import sys
from pathlib import Path
import backends
from compare.render.colors import backend_color
from compare.results.store import atomic_write
from compare.stress.numerics import ORACLE, Experiment, PlotStyle, Series


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _colour(name: str) -> str:
    """The backend's own colour (``colors.backend_color``); the float64 oracle comes after every
    backend; anything else (a prediction) is black."""
    if name in backends.BACKENDS:
        return backend_color(name)
    return f"C{len(backends.BACKENDS) % 10}" if name == ORACLE else "k"


def _style(lbl: str) -> PlotStyle:
    """One colour per backend and one marker per device, in every plot."""
    return {"color": _colour(lbl.split("/", 1)[0]), "marker": "^" if "/cuda" in lbl else "o", "markersize": 4}


def draw(experiment: Experiment, series: Series, path: Path) -> None:
    """Draw one experiment's plot; a failing plot warns and must not lose the table."""
    if experiment.plot is None or not series:
        return
    plt = _plt()
    try:        # the experiment draws into memory; the file is written atomically
        buf = io.BytesIO()
        experiment.plot(series, buf, _style)
        atomic_write(path, buf.getvalue())
    except Exception as exc:
        print(f"warning: plot {experiment.name} failed: {type(exc).__name__}: {exc}", file=sys.stderr)
    finally:
        plt.close("all")
