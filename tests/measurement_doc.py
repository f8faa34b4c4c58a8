"""What the tests of the docs' store figures share (tests/site/test_measurement_claims.py,
test_measurement_launch.py, test_doc_claims.py): the published stores, each machine's loaded once
per process, a doc on one line, and how the doc writes a range and names frameworks."""
from __future__ import annotations

import functools
import re
from pathlib import Path
from typing import Iterable

from compare.site import data, questions

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"
RULES = {r.key: r for r in questions.RULES}
NAMES = {"CuPy": "cupy", "Warp": "warp", "Numba": "numba", "Triton": "triton", "PyTorch": "torch",
         "JAX": "jax", "Taichi": "taichi", "quadrants": "quadrants", "Dr.Jit": "drjit", "MLX": "mlx",
         "NumPy": "numpy"}


@functools.cache
def machine(key: str) -> data.Machine:
    """docs/results/KEY's stores, loaded once (a second or less each)."""
    from compare.suites import formats
    formats.register()
    return data.load([RESULTS / key])


def doc_text(name: str = "docs/measurement.md") -> str:
    """A doc (measurement.md unless named: README.md, docs/findings.md) on one line, its en dashes as hyphens."""
    return " ".join((ROOT / name).read_text(encoding="utf-8").replace("\u2013", "-").split())


def said(doc: str, pattern: str) -> tuple[str, ...]:
    """The figures of the doc's sentence that ``pattern`` matches (fails where it no longer says so)."""
    m = re.search(pattern, doc)
    assert m, f"the doc no longer says: {pattern}"
    return m.groups()


def span(xs: Iterable[float], form: str = "{:.0f}") -> str:
    """'lo-hi' as the doc writes a range (one figure where both ends read the same)."""
    xs = list(xs)
    assert xs
    lo, hi = form.format(min(xs)), form.format(max(xs))
    return lo if lo == hi else f"{lo}-{hi}"


def names(words: str) -> set[str]:
    """'Warp, Numba and CuPy' as backend keys."""
    return {NAMES[w] for w in re.split(r", | and ", words)}
