"""The topic pages' tests (tests/site/topics/) share one context: the site's test store, evaluated
once per module, and figures drawn but not rasterised (tests/render/test_charts.py checks the drawing)."""
from __future__ import annotations

from pathlib import Path

import pytest

from compare.render import charts
from compare.site import data, pages
from compare.site import questions_pages as qp

STORE = Path(__file__).resolve().parent / "data" / "site"


@pytest.fixture(scope="module")
def ctx(tmp_path_factory):
    m = data.load([STORE])
    return qp.Ctx(m, pages.evaluate(m)[0], tmp_path_factory.mktemp("site"), "STORE")


@pytest.fixture(autouse=True)
def unrendered(monkeypatch):
    def save(fig, path):
        Path(path).write_bytes(b"png")
        charts.pyplot().close(fig)
    monkeypatch.setattr(charts, "save", save)
