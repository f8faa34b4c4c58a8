"""The report site's static contract, checked with Python's html.parser only (fast tier).

The site is built by ``compare.site.build`` from the small committed store tests/data/site
(tests/data/site/make_store.py). Every page must parse; every <img src> and relative <a href>
must exist; nothing may be fetched from the network (no http(s) or protocol-relative resource,
no absolute path: the site opens from disk wherever it is copied); each .html has its Markdown
twin, each figure PNG its CSV, and the overview's matrix has one column per framework of the
store. tests/site/test_browser.py loads the same pages in headless Chromium.
"""
from __future__ import annotations

import re
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest

from compare.results.store import SUITES, Store

ROOT = Path(__file__).resolve().parents[2]
STORE = ROOT / "tests" / "data" / "site"
MAX_EXTERNAL_LINKS = 10          # plain <a href="https://..."> per page: allowed, but rare
# elements whose end tag HTML never omits: a stray or missing one is a broken page
STRICT = {"html", "body", "head", "div", "section", "article", "nav", "header", "footer", "main",
          "table", "thead", "tbody", "figure", "figcaption", "ul", "ol", "a", "span", "script",
          "style", "h1", "h2", "h3", "h4", "h5", "h6", "title", "details", "summary", "svg", "code", "pre"}
CSS_REMOTE = re.compile(r"""(?:url\(\s*['"]?|@import\s+['"])\s*(?:https?:)?//""", re.I)
MD_TARGET = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)|<img\s[^>]*src=[\"']([^\"']+)")

_BUILT: dict[str, Path] = {}


def store_frameworks(store: Path = STORE) -> list[str]:
    """The frameworks of a store: the distinct ``backend`` of its records (all three suites)."""
    names: set[str] = set()
    for file in SUITES.values():
        if (store / file).exists():
            names |= {r.backend for r in Store.read(store / file).records}
    return sorted(names)


def built_site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The site of the committed store, built once per test session (both test files share it)."""
    if "site" not in _BUILT:
        from compare import site
        out = tmp_path_factory.mktemp("site")
        site.build([STORE], out)
        _BUILT["site"] = out
    return _BUILT["site"]


# ---- the checks (also run on hand-written fixtures below) ------------------------------------
def _local(ref: str) -> bool:
    """A reference to a file beside the page (not a fragment, scheme or protocol-relative URL)."""
    r = ref.strip()
    return bool(r) and not r.startswith(("#", "//")) and ":" not in r.split("/", 1)[0]


def _remote(ref: str) -> bool:
    r = ref.strip().lower()
    return r.startswith(("http:", "https:", "//"))


def _target(page: Path, ref: str) -> Path:
    return page.parent / unquote(urlsplit(ref).path)


class Page(HTMLParser):
    """One page's references and tag structure."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.stack: list[str] = []
        self.problems: list[str] = []
        self.images: list[str] = []
        self.links: list[str] = []
        self.resources: list[tuple[str, str]] = []     # (tag, src/href) the browser would fetch
        self.matrix_frameworks: list[str] = []
        self.css: list[str] = []
        self.title = ""
        self._in: list[str] = []
        self._matrix_depth = 0

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = {k: v or "" for k, v in attrs}
        if tag in STRICT:
            self.stack.append(tag)
        self._in.append(tag)
        if tag == "img":
            self.images.append(a.get("src", ""))
        if tag == "a" and "href" in a:
            self.links.append(a["href"])
        for attr in ("src", "srcset", "data", "poster"):
            if attr in a:
                self.resources.append((tag, a[attr]))
        if tag == "link" and "href" in a:
            self.resources.append((tag, a["href"]))
        if "style" in a:
            self.css.append(a["style"])
        if tag == "table" and a.get("id") == "matrix":
            self._matrix_depth = len(self.stack)
        if tag == "th" and self._matrix_depth and "data-framework" in a:
            self.matrix_frameworks.append(a["data-framework"])

    def handle_endtag(self, tag: str) -> None:
        if self._in and tag in self._in:
            while self._in.pop() != tag:
                pass
        if tag not in STRICT:
            return
        if tag not in self.stack:
            self.problems.append(f"stray </{tag}>")
            return
        while self.stack:
            top = self.stack.pop()
            if top == tag:
                break
            self.problems.append(f"<{top}> closed by </{tag}>")
        if tag == "table" and len(self.stack) < self._matrix_depth:
            self._matrix_depth = 0

    def handle_data(self, data: str) -> None:
        if self._in and self._in[-1] == "style":
            self.css.append(data)
        if self._in and self._in[-1] == "title":
            self.title += data

    def close(self) -> None:
        super().close()
        self.problems += [f"<{t}> never closed" for t in self.stack]


def parse(page: Path) -> Page:
    p = Page()
    p.feed(page.read_text(encoding="utf-8"))
    p.close()
    return p


def page_problems(page: Path) -> list[str]:
    """What is wrong with one HTML page, read from disk only."""
    name = page.name
    p = parse(page)
    out = [f"{name}: {x}" for x in p.problems]
    if not p.title.strip():
        out.append(f"{name}: no <title>")
    for tag, ref in p.resources:
        if _remote(ref):
            out.append(f"{name}: <{tag}> fetches {ref} from the network")
        elif ref.startswith(("/", "file:")):
            out.append(f"{name}: <{tag}> refers to {ref} by an absolute path")
    for css in p.css:
        if CSS_REMOTE.search(css):
            out.append(f"{name}: CSS fetches from the network: {CSS_REMOTE.search(css).group(0)}")
    for src in p.images:
        if src.startswith("data:"):
            continue
        if not _local(src) or src.startswith("/"):
            out.append(f"{name}: image {src!r} is not a file beside the page")
        elif not _target(page, src).is_file():
            out.append(f"{name}: broken image {src}")
    for href in p.links:
        if href.startswith(("/", "file:")):
            out.append(f"{name}: link {href} by an absolute path")
        elif _local(href) and not _target(page, href).exists():
            out.append(f"{name}: broken link {href}")
    external = [h for h in p.links if _remote(h)]
    if len(external) > MAX_EXTERNAL_LINKS:
        out.append(f"{name}: {len(external)} external links (at most {MAX_EXTERNAL_LINKS}: the site stands alone)")
    return out


def markdown_problems(md: Path) -> list[str]:
    out = []
    for m in MD_TARGET.finditer(md.read_text(encoding="utf-8")):
        ref = m.group(1) or m.group(2)
        if ref.startswith(("/", "file:")):
            out.append(f"{md.name}: {ref} by an absolute path")
        elif _local(ref) and not _target(md, ref).exists():
            out.append(f"{md.name}: broken link or image {ref}")
    return out


def site_problems(out: Path) -> list[str]:
    """Every static problem of a built site (pages, twins, figures' data)."""
    problems = []
    pages = sorted(out.rglob("*.html"))
    if not (out / "index.html").is_file():
        problems.append("no index.html")
    for page in pages:
        problems += page_problems(page)
        if not page.with_suffix(".md").is_file():
            problems.append(f"{page.name}: no Markdown twin {page.with_suffix('.md').name}")
    for md in sorted(out.rglob("*.md")):
        problems += markdown_problems(md)
    for png in sorted((out / "figures").glob("*.png")):
        if not png.with_suffix(".csv").is_file():
            problems.append(f"figures/{png.name}: no {png.with_suffix('.csv').name} beside it")
    return problems


# ---- the built site ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return built_site(tmp_path_factory)


def test_store_loads_with_every_framework():
    for file in SUITES.values():
        Store.read(STORE / file)
    assert len(store_frameworks()) == 8
    assert sum((STORE / f).stat().st_size for f in SUITES.values()) <= 400_000


@pytest.mark.xdist_group("site")
def test_site_layout(site: Path):
    assert (site / "index.html").is_file() and (site / "matrix.md").is_file()
    assert len(list(site.rglob("*.html"))) > 1, "the overview and at least one question page"
    figures = list((site / "figures").glob("*.png"))
    assert figures, "no figures/*.png"


@pytest.mark.xdist_group("site")
def test_site_static(site: Path):
    problems = site_problems(site)
    assert not problems, "\n".join(problems)


@pytest.mark.xdist_group("site")
def test_matrix_has_one_column_per_framework(site: Path):
    columns = parse(site / "index.html").matrix_frameworks
    assert columns, 'no <table id="matrix"> with <th data-framework=...> cells in index.html'
    assert len(columns) == len(set(columns)), f"a framework twice: {columns}"
    assert sorted(columns) == store_frameworks()


# ---- the checks catch what they should (hand-written fixtures) --------------------------------
PNG = bytes.fromhex("89504e470d0a1a0a0000000d4948445200000001000000010802000000907753de0000000c4944"
                    "4154789c63f8cfc0000003010100c9fe92ef0000000049454e44ae426082")    # 1x1, red


def page(title: str, body: str) -> str:
    return f"<!doctype html><html><head><title>{title}</title></head><body>{body}</body></html>"


def make_fixture_site(root: Path) -> Path:
    """A tiny site that passes, with its figure, CSV and twins."""
    (root / "figures").mkdir(parents=True)
    (root / "figures" / "speed.png").write_bytes(PNG)
    (root / "figures" / "speed.csv").write_text("framework,seconds\nwarp,1\n")
    (root / "index.html").write_text(page("overview", '<table id="matrix"><tr><th>q</th>'
                                          '<th data-framework="warp">warp</th></tr></table>'
                                          '<img src="figures/speed.png"><a href="speed.html#top">speed</a>'
                                          '<a href="https://docs.python.org/">docs</a>'))
    (root / "index.md").write_text("# overview\n\n![speed](figures/speed.png)\n[speed](speed.md)\n")
    (root / "speed.html").write_text(page("speed", '<a href="index.html">back</a>'))
    (root / "speed.md").write_text("[back](index.md \"overview\")\n")
    (root / "matrix.md").write_text("| q | warp |\n")
    return root


def test_static_checks_pass_a_good_site(tmp_path: Path):
    site_dir = make_fixture_site(tmp_path)
    assert site_problems(site_dir) == []
    assert parse(site_dir / "index.html").matrix_frameworks == ["warp"]


@pytest.mark.parametrize("fault, expect", [
    (lambda d: (d / "figures" / "speed.png").unlink(), "broken image figures/speed.png"),
    (lambda d: (d / "speed.html").unlink(), "broken link speed.html#top"),
    (lambda d: (d / "speed.md").unlink(), "no Markdown twin speed.md"),
    (lambda d: (d / "figures" / "speed.csv").unlink(), "no speed.csv beside it"),
    (lambda d: (d / "index.md").write_text("![x](figures/gone.png)\n"), "broken link or image figures/gone.png"),
    (lambda d: (d / "speed.html").write_text(page("s", '<script src="https://cdn.example/x.js"></script>')),
     "fetches https://cdn.example/x.js from the network"),
    (lambda d: (d / "speed.html").write_text(page("s", '<link rel="stylesheet" href="//cdn.example/a.css">')),
     "fetches //cdn.example/a.css from the network"),
    (lambda d: (d / "speed.html").write_text(page("s", "<style>body{background:url(https://x.example/b.png)}</style>")),
     "CSS fetches from the network"),
    (lambda d: (d / "speed.html").write_text(page("s", f'<img src="{d / "figures" / "speed.png"}">')),
     "is not a file beside the page"),
    (lambda d: (d / "speed.html").write_text(page("s", "<div><table></div>")), "<table> closed by </div>"),
    (lambda d: (d / "speed.html").write_text("<!doctype html><p>no title"), "speed.html: no <title>"),
])
def test_static_checks_catch_each_fault(tmp_path: Path, fault, expect: str):
    site_dir = make_fixture_site(tmp_path)
    fault(site_dir)
    problems = site_problems(site_dir)
    assert any(expect in p for p in problems), problems


# ---- figures' data say what their columns name ------------------------------------------------
@pytest.mark.xdist_group("site")
def test_time_vs_error_csv_has_each_points_error_and_wall_clock(site: Path):
    """Every point of the time-against-error figure has its error (``converged.error``) and its
    wall-clock median (``time.wall``), never a CUDA-event median under the wall column."""
    import csv
    from compare.sweep.rows import wall_s
    recs = {(r.backend, r.variant, r.precision): r for r in Store.read(STORE / "sweep.json").records
            if (r.tags or {}).get("sweep") == "error" and r.status == "ok"}
    assert any(r.time.get("timer") == "events" for r in recs.values()), "the store lost its event-timed points"
    with open(site / "figures" / "accuracy-time-vs-error.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(recs)
    for row in rows:
        r = recs[(row["framework"], row["variant"], row["precision"])]
        assert row["error"] == format(r.converged["error"], ".6g"), row
        assert row["wall median s"] == format(wall_s(r), ".6g"), row


def test_a_newer_record_replaces_an_older_one_that_lacks_params_added_since():
    """A record stored before a parameter existed (projectile before ``batch`` and ``seed``) ran
    at that parameter's default: the same cell as a newer record at the defaults, which wins."""
    import dataclasses
    import scenarios
    from compare.results.record import Record
    from compare.site import matrix
    full = dataclasses.asdict(scenarios.SCENARIOS["projectile"].params())
    old = {k: v for k, v in full.items() if k not in ("batch", "seed")}
    assert old != full, "projectile's defaults lost batch and seed: pick params added since"
    cell = dict(scenario="projectile", device="cpu", precision="float32", status="ok")
    older = Record(backend="jax", params=old, time={"median_s": 2.0}, **cell)
    newer = Record(backend="jax", params=full, time={"median_s": 1.0}, **cell)
    other = Record(backend="numba", params=old, time={"median_s": 3.0}, **cell)
    assert matrix.latest([older, other, newer]) == [newer, other]
    bigger = Record(backend="jax", params={**full, "batch": 4096}, time={"median_s": 5.0}, **cell)
    assert matrix.latest([older, bigger]) == [older, bigger]       # another size: another cell


def _particles_page(store: Path, out: Path):
    from compare.site import data, pages
    from compare.site import questions_pages as qp
    from compare.site.topics import particles
    m = data.load([store])
    rows, _ = pages.evaluate(m)
    c = qp.Ctx(m, rows, out, "STORE")
    return c, particles.page(c)


def test_the_particle_scaling_table_and_the_verdicts_read_one_record_per_cell(tmp_path: Path):
    """Where the run suite and the scaling sweep both measured a cell (the CPU's Numba at n = 256:
    10 µs per rollout in the run, 8 ms in a sweep run while the 2-core host was loaded), the
    scaling table shows the run suite's record, as the matrix rows do, so the page's table and
    its verdicts give one figure."""
    from compare.site import fmt
    from compare.site.render import Table
    c, blocks = _particles_page(ROOT / "docs" / "results" / "cpu", tmp_path)
    table = next(b for b in blocks if isinstance(b, Table) and "size" in b.headers)
    rate = {(r[0], r[1], r[2]): r[3] for r in table.rows}
    small = next(r for r in c.rows if r.rule.key == "particles-small")
    large = next(r for r in c.rows if r.rule.key == "particles-large")
    checked = 0
    for fw, cell in small.cells.items():
        if cell.value is not None and cell.variant == "default" and (fw, "default", "256") in rate:
            assert rate[fw, "default", "256"] == fmt.rate(256 * 300 / cell.value), fw
            checked += 1
    for fw, cell in large.cells.items():
        if cell.value is not None and cell.variant == "default" and (fw, "default", "1048576") in rate:
            assert rate[fw, "default", "1048576"] == fmt.rate(cell.value), fw
            checked += 1
    assert checked >= 8
    best = small.cells["numba"]          # the verdict names the figure the table was checked against
    assert best.value is not None and f"numba ({fmt.seconds(best.value)})" in small.verdict, small.verdict


@pytest.mark.xdist_group("site")
def test_overview_picture_is_drawn_from_the_matrix_and_reproducible(site: Path, tmp_path: Path):
    """overview.png (README's picture of the matrix) is written by the build, not screenshotted, and
    the same rows give the same bytes."""
    from compare.site import data, pages
    png = site / "overview.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    m = data.load([STORE])
    rows, _ = pages.evaluate(m)
    title = parse(site / "index.html").title
    again = tmp_path / "overview.png"
    pages.matrix_png(again, rows, m.frameworks, title)
    assert again.read_bytes() == png.read_bytes()
    from compare.render import figure_check  # no page shows it: its layout is checked here
    assert figure_check.read(png) == []

