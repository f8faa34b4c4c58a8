"""The report site in a real browser: pages of the site built from tests/data/site (a sample; every
page in the long tier) loaded in headless Chromium (tests/browser.py, one browser for all pages):
no console error or uncaught exception, no failed load, no request to the network, no broken
image or link, no figure whose layout check (compare/render/figure_check.py, stamped in the PNG
where it was saved) found a text outside the canvas, two texts overlapping or a legend over data,
and the overview's matrix has one column per framework of the store. The harness's own tests load
hand-written pages, one per fault, and show each fault is caught and a good page passes.

Chromium missing is a skip whose reason is the install command (CI installs it: .ci/run).
"""
from __future__ import annotations

import struct
import time
from pathlib import Path

import pytest

import browser
from test_site import PNG, built_site, store_frameworks

MATRIX_JS = "[...document.querySelectorAll('#matrix th[data-framework]')].map(t => t.dataset.framework)"


@pytest.fixture(scope="module")
def chromium():
    """One browser for the module's tests."""
    if browser.find_chromium() is None:
        pytest.skip(browser.SKIP_REASON)
    with browser.Browser(timeout=30) as b:
        yield b


def assert_loads_clean(chromium: browser.Browser, site: Path, pages: list[Path]) -> None:
    problems = []
    for page in pages:               # about 0.3 s a page on a 2-core machine; each bounded by 30 s
        result = chromium.check(page)
        problems += [f"{page.relative_to(site)}: {p}" for p in result.problems()]
    assert not problems, "\n".join(problems)


# the overview (its matrix and the glossary every page carries), a row's page with its figure, the
# page with the most figures, and the machine page; every page is the long tier's
SAMPLE = ("index.html", "per-call.html", "gradients.html", "machine.html")


@pytest.mark.xdist_group("site")
def test_representative_pages_load_clean_in_chromium(chromium: browser.Browser, tmp_path_factory):
    site = built_site(tmp_path_factory)
    assert_loads_clean(chromium, site, [site / name for name in SAMPLE])


@pytest.mark.slow
def test_every_page_loads_clean_in_chromium(chromium: browser.Browser, tmp_path_factory):
    site = built_site(tmp_path_factory)
    pages = sorted(site.rglob("*.html"))
    assert len(pages) > 1 and {site / name for name in SAMPLE} <= set(pages)
    assert_loads_clean(chromium, site, pages)


@pytest.mark.xdist_group("site")
def test_matrix_has_one_column_per_framework_in_chromium(chromium: browser.Browser, tmp_path_factory):
    site = built_site(tmp_path_factory)
    result = chromium.check(site / "index.html", evaluate={"frameworks": MATRIX_JS})
    columns = result.values["frameworks"]
    assert columns, 'no <table id="matrix"> with <th data-framework=...> in the rendered overview'
    assert len(columns) == len(set(columns)), f"a framework twice: {columns}"
    assert sorted(columns) == store_frameworks()


# ---- the harness catches each fault (hand-written pages) --------------------------------------
def html(body: str, title: str = "fixture") -> str:
    return f"<!doctype html><html><head><title>{title}</title></head><body>{body}</body></html>"


@pytest.fixture
def fixtures(tmp_path: Path) -> Path:
    from compare.render import figure_check
    (tmp_path / "fig.png").write_bytes(figure_check.stamp(PNG, '{"problems": []}'))
    (tmp_path / "plain.png").write_bytes(PNG)
    (tmp_path / "crowded.png").write_bytes(figure_check.stamp(PNG, '{"problems": ["text \'a\' overlaps text \'b\'"]}'))
    (tmp_path / "other.html").write_text(html("<p>other</p>"))
    pages = {
        "ok": '<img src="fig.png"><a href="other.html#top">other</a><a href="#here">here</a>'
              '<a href="https://docs.python.org/3/">docs</a><script>document.body.dataset.ran = "1";</script>',
        "broken-image": '<img src="missing.png">',
        "console-error": '<script>console.error("boom");</script>',
        "exception": "<script>undefinedFunction();</script>",
        "broken-link": '<a href="nowhere.html">nowhere</a>',
        "network": '<img src="https://example.invalid/a.png"><script src="http://example.invalid/a.js"></script>',
        "hang": "<script>while (true) {}</script>",
        "figure-overlap": '<img src="crowded.png">',
        "figure-unchecked": '<img src="plain.png">',
    }
    for name, body in pages.items():
        (tmp_path / f"{name}.html").write_text(html(body, name))
    return tmp_path


def test_harness_passes_a_good_page(chromium: browser.Browser, fixtures: Path):
    r = chromium.check(fixtures / "ok.html", evaluate={"ran": "document.body.dataset.ran"})
    assert r.ok, r.problems()
    assert r.title == "ok" and r.values == {"ran": "1"}
    assert r.external_links == ["https://docs.python.org/3/"]       # listed, not a fault


@pytest.mark.parametrize("page, field, expect", [
    ("broken-image", "broken_images", "missing.png"),
    ("broken-image", "failed_loads", "missing.png: net::ERR_FILE_NOT_FOUND"),
    ("console-error", "console_errors", "boom"),
    ("exception", "console_errors", "ReferenceError: undefinedFunction is not defined"),
    ("broken-link", "broken_links", "nowhere.html"),
    ("network", "network_requests", "https://example.invalid/a.png"),
    ("network", "network_requests", "http://example.invalid/a.js"),
    ("missing-page", "failed_loads", "net::ERR_FILE_NOT_FOUND"),
    ("figure-overlap", "figure_problems", "crowded.png: text 'a' overlaps text 'b'"),
    ("figure-unchecked", "figure_problems", "plain.png: layout never checked"),
])
def test_harness_catches_each_fault(chromium: browser.Browser, fixtures: Path, page: str, field: str, expect: str):
    r = chromium.check(fixtures / f"{page}.html")
    assert not r.ok
    assert any(expect in x for x in getattr(r, field)), f"{field} = {getattr(r, field)}"


def test_harness_never_hangs(chromium: browser.Browser, fixtures: Path):
    """A page that never finishes loading is reported as timed out; the browser is killed and the
    next page gets a fresh one (the module's browser: the tests after this one use that one)."""
    chromium.check(fixtures / "ok.html")                # started: the timeout below is the page's
    start = time.monotonic()
    r = chromium.check(fixtures / "hang.html", timeout=2)
    assert r.timed_out and not r.ok and time.monotonic() - start < 10
    assert chromium.check(fixtures / "ok.html").ok


def test_screenshot(chromium: browser.Browser, fixtures: Path, tmp_path: Path):
    def size(png: Path) -> tuple[int, int]:
        data = png.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n"
        return struct.unpack(">II", data[16:24])

    tall = fixtures / "tall.html"
    tall.write_text(html('<div style="height:2500px;background:linear-gradient(red,blue)">tall</div>'))
    assert size(chromium.screenshot(tall, tmp_path / "view.png", 800, 600)) == (800, 600)
    w, h = size(chromium.screenshot(tall, tmp_path / "full.png", 800, 600, full_page=True))
    assert w == 800 and h >= 2500
