"""compare/site/assemble.py: the machine-and-method page and writing the whole site twice (HTML and
Markdown), from the site's test store (fast tier: figures drawn but not rasterised; the built
site's links and layout: tests/site/test_site.py)."""
from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import pytest

from compare.render import charts, figure_check
from compare.site import assemble, data, fmt, pages, questions, reproducibility
from compare.site import questions_pages as qp
from compare.site.render import P, Table

STORE = Path(__file__).resolve().parents[2] / "tests" / "data" / "site"


@pytest.fixture(autouse=True)
def unrendered(monkeypatch):
    def save(fig, path):
        Path(path).write_bytes(b"png")
        charts.pyplot().close(fig)

    def checked(draw, png):              # the plots that save themselves: not drawn here
        Path(png).write_bytes(b"png")
        return True
    monkeypatch.setattr(charts, "save", save)
    monkeypatch.setattr(figure_check, "checked", checked)


@pytest.fixture(scope="module")
def loaded():
    m = data.load([STORE])
    return (m, *pages.evaluate(m))


def ctx(m, rows, tmp_path):
    return qp.Ctx(m, rows, tmp_path / "site", "STORE")


def test_write_site_writes_every_page_twice_the_matrix_and_the_manifest(tmp_path, monkeypatch, loaded):
    m = loaded[0]
    for key in assemble.BUILDERS:              # the pages' own contents: their own tests
        monkeypatch.setitem(assemble.BUILDERS, key, lambda c, key=key: [P(f"page {key}")])
    monkeypatch.setattr(pages, "evaluate", lambda _m: (loaded[1], loaded[2]))      # the module's rows
    monkeypatch.setattr(pages, "matrix_png", lambda path, *a: Path(path).write_bytes(b"png"))
    into = tmp_path / "into"
    into.mkdir()
    written = assemble.write_site([STORE], tmp_path / "site", into, None, [], m, None)
    stems = ["index", *questions.PAGES]
    for stem in stems:
        assert into / f"{stem}.html" in written and into / f"{stem}.md" in written
        assert (into / f"{stem}.md").read_text().startswith("# ")
        assert f"<p>page {stem}</p>" in (into / f"{stem}.html").read_text() or stem == "index"
    assert "against.html" not in {p.name for p in written}
    assert (into / "matrix.md").read_text().startswith("| question | ")
    assert (into / assemble.OVERVIEW).is_file()
    manifest = json.loads((into / assemble.MANIFEST).read_text())
    assert manifest == {"inputs": ["tests/data/site"], "title": f"Framework comparison: {m.name()}", "against": []}
    assert all(p.exists() for p in written)
    html = (into / "index.html").read_text()
    assert all(f'href="{k}.html"' in html for k in questions.PAGES)          # the navigation


def test_the_machine_page_without_a_publish_log_or_a_rerun(tmp_path, loaded):
    blocks = assemble.machine(ctx(*loaded[:2], tmp_path))
    texts = [getattr(b, "text", "") for b in blocks]
    assert "No publish log (publish.json)" in " ".join(texts)
    assert "the rankings have not been rerun" in " ".join(texts)
    packages = next(b for b in blocks if isinstance(b, Table) and b.headers == ("package", "version(s)"))
    assert ("warp-lang", "1.19.0") in packages.rows


def test_the_machine_page_reads_the_publish_log_and_a_rerun(tmp_path, loaded):
    store = tmp_path / "store"
    shutil.copytree(STORE, store)
    (store / reproducibility.RERUN).mkdir()
    shutil.copy(STORE / "results.json", store / reproducibility.RERUN)
    (store / reproducibility.RERUN / data.PUBLISH_LOG).write_text(json.dumps({"parts": [
        {"name": "all", "argv": ["all"], "started": "t", "seconds": 90, "exit_code": 0}]}))
    (store / data.PUBLISH_LOG).write_text(json.dumps({"parts": [
        {"name": "cuda-matrix", "argv": ["all", "--backends", "warp,jax"], "started": "t", "seconds": 60,
         "exit_code": 0},
        {"name": "cuda-matrix", "argv": [], "started": "t2", "seconds": 30, "exit_code": None}]}))
    blocks = assemble.machine(ctx(data.load([store]), loaded[1], tmp_path))
    text = " ".join(getattr(b, "text", "") for b in blocks)
    assert "ran 1 part on this machine in 90 s of wall time" in text
    assert "significant orderings agree between the two runs; 0 became a tie in one of them (allowed), 0 reversed." in text
    # the second run named from its own files: when, which commit, how busy its host was, its time
    run = data.load([store / reproducibility.RERUN]).runs[0]
    assert f"(rerun/: run {run['created'][:16].replace('T', ' ')} UTC, commit {run['git_commit'][:7]}" in text
    assert "other processes used a median of" in text and "independent" not in text
    # both runs' hosts as their yardsticks saw them: one model name can stand for hosts far apart
    hw = next(iter(run["hardware"].values()))
    assert f"Its host's yardstick: copy {fmt.rate(hw['copy_bytes_per_s'], 'B/s')}" in text, text
    assert "The part took 1.5 minutes in 1 attempt (rerun/publish.json)." in text
    pub = next(b for b in blocks if isinstance(b, Table) and b.headers[0] == "part")
    assert pub.rows == (("cuda-matrix", "warp,jax", "t", "60", "0"), ("cuda-matrix", "all", "t2", "30", "cut off"))


def test_tree_and_argv_value():
    assert assemble._tree({"git_dirty": False}) == "clean"
    assert assemble._tree({"git_dirty": True, "git_dirty_paths": ["a.py"]}) == "uncommitted changes: a.py"
    assert assemble._tree({"git_note": "no git"}) == "not known (no git)"
    assert assemble._argv_value(["x", "--backends", "numpy"], "--backends") == "numpy"
    assert assemble._argv_value(["x", "--backends"], "--backends") == "all" and assemble._argv_value(None, "-b") == "all"


def test_a_run_says_how_it_timed_its_cells():
    assert assemble._timed({}) == "1 process"
    assert assemble._timed({"processes": "auto", "sitting_s": 1500.0, "overlap": 7, "overlap_beside": True}) == \
        "auto processes; sitting 1500 s; 7 set up ahead, beside GPU windows"
    assert assemble._timed({"processes": 6, "overlap": 1, "overlap_beside": False}) == "6 processes; 1 set up ahead"
    # a run cut short after its second round says so: its records kept 2 processes, not the 3 asked
    assert assemble._timed({"processes": 3}, ran=2) == "3 processes asked, 2 ran (cut short after round 2)"
    assert assemble._timed({"processes": 3}, ran=3) == "3 processes"


def test_store_label_names_a_store_in_the_repository_by_its_path(tmp_path):
    assert assemble.store_label([STORE]) == "tests/data/site"
    assert assemble.store_label([tmp_path]) == "STORE"


def test_every_page_has_a_builder():
    assert set(questions.PAGES) == set(assemble.BUILDERS)


def test_the_machine_page_says_noisy_sitting(tmp_path, loaded):
    """A run publish let through a noisy sitting: the machine page names it with its reasons, the
    runs table says so; a run from before the check is judged by its yardstick against the quiet
    sittings the stores give (a slow floor noisy, a quiet one quiet); so is a run whose check had no
    reference when it ran (null) or did not record one; a run with neither is not listed."""
    from compare.measuring.sitting import SittingCheck
    m = data.load([STORE])
    check = SittingCheck.of(device="cuda", launch_latency_s=12.65e-6, launch_pipelined_s=7.6e-6).to_json()
    noisy, quiet = dict(m.runs[0]), dict(m.runs[0])
    noisy.update(sitting={"start": check, "end": check}, noisy_sitting=True,
                 noisy_sitting_reasons=["pipelined launch 7.6 us, 1.49x the quiet 5.09 us (limit 1.25x)"])
    # judged quiet at the time against a lenient reference it recorded: the page keeps its verdict
    quiet.update(sitting={"start": check, "quiet": {"kind": "NVIDIA H100 80GB HBM3", "runs": 4,
                                                    "launch_latency_s": 12e-6, "launch_pipelined_s": 7e-6}})
    h100 = SittingCheck.of(device="cuda", gpu="NVIDIA H100 80GB HBM3", launch_latency_s=12.65e-6,
                           launch_pipelined_s=7.6e-6).to_json()
    unjudged, unrecorded = dict(m.runs[0], sitting={"start": h100, "quiet": None}), dict(m.runs[0], sitting={"start": h100})

    def yardstick(sync_us: float, pipelined_us: float) -> dict:
        return dict(m.runs[0], sitting=None, hardware={"cuda": {
            "gpu": "NVIDIA H100 80GB HBM3", "copy_bytes_per_s": 3e12, "launch_latency_s": sync_us * 1e-6,
            "launch_pipelined_s": pipelined_us * 1e-6}})
    m = dataclasses.replace(m, runs=(noisy, quiet, yardstick(14.4, 11.0), yardstick(9.5, 4.6)))
    blocks = assemble.machine(ctx(m, loaded[1], tmp_path))
    text = " ".join(getattr(b, "text", "") for b in blocks)
    assert "**2 of 4 runs sat in a noisy sitting**" in text
    table = next(b for b in blocks if isinstance(b, Table) and b.headers == ("run", "figures", "judged by", "verdict"))
    assert [r[3].split(":")[0] for r in table.rows] == ["**noisy sitting**", "quiet", "**noisy sitting**", "quiet"]
    # a check judged with no reference is judged now against the stores' quiet sittings (the
    # published H100 runs: pipelined about 5 us): the same 7.6 us floor, quiet by the run's stamp,
    # is noisy after the fact
    late = {r[2]: r[3] for r in assemble.sittings([unjudged, unrecorded], tmp_path)[-1].rows}
    assert late["its check, against the stores' quiet sittings after the fact (it had none when it ran)"].startswith(
        "**noisy sitting**: pipelined launch 7.6 us")
    assert "(judged after the fact)" in late["its check, against the stores' quiet sittings after the fact "
                                              "(its reference was not recorded)"]
    assert table.rows[0][3].endswith("1.49x the quiet 5.09 us (limit 1.25x)") and "at its end" in table.rows[0][2]
    assert table.rows[1][2] == "its check" and table.rows[2][2] == table.rows[3][2] == "its yardstick, after the fact"
    assert table.rows[0][1].startswith("launch + sync 12.6 us, pipelined 7.6 us")
    assert "pipelined launch 11 us" in table.rows[2][3]
    runs = next(b for b in blocks if isinstance(b, Table) and b.headers[0] == "created")
    assert runs.rows[0][3].endswith("noisy sitting") and not runs.rows[1][3].endswith("noisy sitting")
    assert assemble.sittings([dict(m.runs[1], sitting=None, hardware={})], tmp_path) == []    # neither: no block
    # a kind the stores hold too few other runs of (a made-up GPU): the absolute limits alone, said so
    lone = SittingCheck.of(device="cuda", gpu="NVIDIA Z900", launch_latency_s=12.65e-6, launch_pipelined_s=7.6e-6)
    (row,) = assemble.sittings([dict(m.runs[1], sitting={"start": lone.to_json(), "quiet": None})], tmp_path)[-1].rows
    assert row[2].endswith("absolute limits only: the stores hold under 4 other runs of its kind, no quiet "
                           "sitting to compare with") and row[3] == "quiet"


def test_a_page_names_its_rows_without_a_figure():
    """The H200's store has no large parts yet: its Large arrays page names the row and what it
    reads instead of ending after its introduction; a row another device answers (CPU-only use) is
    not listed on a GPU page, and a row with a figure never is."""
    from pathlib import Path
    m = data.load([Path(__file__).resolve().parents[2] / "docs" / "results" / "h200"])
    rows, empty = pages.evaluate(m)
    (large,) = assemble._without(empty, "bandwidth")
    assert large.text.startswith("**Large bandwidth-bound arrays**: no figure on this machine; what it reads: SAXPY")
    assert assemble._without(empty, "cpu") == [] and assemble._without(empty, "per-call") == []
    assert {r.rule.page for r in rows} >= {"per-call"}
