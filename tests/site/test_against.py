"""``compare site MINE --against REFERENCE`` (fast tier): the page comparing a run with a reference.

MINE is a copy of the small committed store tests/data/site; REFERENCE is another copy with a few
records perturbed by hand: one cell twice as slow with a narrow spread (ratio 0.50×, outside the
spread: "faster" here), one 5 % slower with the same spread (inside it), one failed, one
removed, and one package version changed. Everything runs in tmp_path with the working directory
there too, so a file written anywhere but --out is caught. test_against_page builds the whole
site; the tests that read only SAXPY rows (or whole-page wording) of against.md build it from
MINE's SAXPY records alone (``_saxpy_only``: the other pages' figures took most of a build's ~12 s).
"""
from __future__ import annotations

import json
import re
import shutil
from pathlib import Path
from typing import Any

import pytest

from compare import cli
from test_site import page_problems

ROOT = Path(__file__).resolve().parents[2]
STORE = ROOT / "tests" / "data" / "site"
if not STORE.is_dir() or not (ROOT / "compare" / "site" / "against.py").exists():
    pytest.skip("tests/data/site or compare/site/against.py not present", allow_module_level=True)

SAXPY = {"scenario": "saxpy", "device": "cuda", "precision": "float32", "variant": "default"}


def _find(records: list[dict[str, Any]], backend: str) -> dict[str, Any]:
    """The default-size float32 SAXPY record of ``backend`` on CUDA."""
    return next(r for r in records if r["backend"] == backend and r["status"] == "ok"
                and all(r[k] == v for k, v in SAXPY.items()) and r["params"]["n"] == 1000000)


def _set_latency(r: dict[str, Any], median: float, iqr: float) -> None:
    r["time"]["latency"].update(median_s=median, iqr_s=iqr)
    r["time"].update(median_s=median, iqr_s=iqr)


def _snapshot(root: Path, skip: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file() and skip not in p.parents}


@pytest.fixture()
def stores(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> dict[str, Any]:
    mine, ref = tmp_path / "mine", tmp_path / "ref"
    shutil.copytree(STORE, mine)
    shutil.copytree(STORE, ref)
    doc = json.loads((ref / "results.json").read_text())
    recs = doc["records"]
    warp, cupy, taichi, torch = (_find(recs, b) for b in ("warp", "cupy", "taichi", "torch"))
    lat = {b: dict(r["time"]["latency"]) for b, r in (("warp", warp), ("cupy", cupy))}
    # twice as slow with a tiny spread there: this run is faster, outside both spreads
    _set_latency(warp, 2 * lat["warp"]["median_s"], 1e-9)
    # 5 % slower there with this run's own spread: the quartile ranges overlap
    _set_latency(cupy, 1.05 * lat["cupy"]["median_s"], lat["cupy"]["iqr_s"])
    taichi.update(status="error", reason="perturbed: failed on the reference", time=None)
    recs.remove(torch)
    (ref / "results.json").write_text(json.dumps(doc))
    for f in ("results.json", "sweep.json", "stress.json"):    # every run of the reference
        d = json.loads((ref / f).read_text())
        for env in d["runs"]:
            env.setdefault("packages", {})["numpy"] = "9.9.9"
        (ref / f).write_text(json.dumps(d))
    monkeypatch.chdir(tmp_path)
    return {"mine": mine, "ref": ref, "tmp": tmp_path, "lat": lat}


def _saxpy_only(store: Path) -> None:
    """Keep only the SAXPY records of ``store``'s results.json (no sweep or stress file): a site
    of a few pages, for the tests that read only SAXPY rows of against.md."""
    doc = json.loads((store / "results.json").read_text())
    doc["records"] = [r for r in doc["records"] if r["scenario"] == "saxpy"]
    (store / "results.json").write_text(json.dumps(doc))
    for f in ("sweep.json", "stress.json"):
        (store / f).unlink()


def _site(stores: dict[str, Any], *against: Path) -> Path:
    out = stores["tmp"] / "out"
    before = _snapshot(stores["tmp"], out)
    rc = cli.main(["site", str(stores["mine"]), "--out", str(out),
                   *[w for a in against for w in ("--against", str(a))]])
    assert rc == 0
    assert _snapshot(stores["tmp"], out) == before, "the site wrote outside --out"
    return out


def _against_warp_edited(stores: dict[str, Any], edit: Any) -> str:
    """against.md of MINE's SAXPY rows against the reference, its warp SAXPY record changed by ``edit``."""
    _saxpy_only(stores["mine"])
    doc = json.loads((stores["ref"] / "results.json").read_text())
    edit(_find(doc["records"], "warp"))
    (stores["ref"] / "results.json").write_text(json.dumps(doc))
    return (_site(stores, stores["ref"]) / "against.md").read_text()


def _row(md: str, *cells: str) -> list[str]:
    """The cells of the Markdown table row that starts with ``cells``."""
    head = "| " + " | ".join(cells) + " |"
    line = next((ln for ln in md.splitlines() if ln.startswith(head)), None)
    assert line is not None, f"no row {head!r}"
    return [c.strip() for c in line.strip().strip("|").split(" | ")]


def test_against_page(stores: dict[str, Any]) -> None:
    out = _site(stores, stores["ref"])
    assert (out / "against.html").is_file() and (out / "against.md").is_file()
    md = (out / "against.md").read_text()
    html = (out / "against.html").read_text()
    assert "against.html" in (out / "index.html").read_text()          # in the navigation
    cell = ("cuda", "saxpy", "warp", "default", "float32", "defaults", "latency")
    row = _row(md, *cell)
    # ratio, ratio in launch floors (the same yardstick on both sides: the same ratio), verdict
    assert row[-3:] == ["0.50×", "0.50×", "faster"]                     # hand-checked: m / (2 m)
    assert _row(md, *cell[:-1], "throughput")[-3:] == ["1.00×", "1.00×", "within spread"]   # untouched
    row = _row(md, "cuda", "saxpy", "cupy", "default", "float32", "defaults", "latency")
    assert row[-3:] == [f"{1 / 1.05:.2f}×", "-", "within spread"]      # no yardstick: no floors
    # the page opens with what matched; the status change follows, the removed cell only counted
    status = md.index("## Status changes")
    assert md.index("## Every matched cell") < status
    assert "perturbed: failed on the reference" in md[status:md.index("## The two environments")]
    row = _row(md, "cuda", "taichi", "default")
    assert row[3].startswith("1: saxpy float32") and row[4] == "ok"
    assert not any(ln.startswith("| cuda | saxpy | torch | default | float32 | defaults |")
                   for ln in md.splitlines())
    assert re.search(r"1 only in this run \(saxpy\), 0 only in the reference", md)
    summary = md[md.index("## Summary"):md.index("## Every matched cell")]
    assert re.search(r"\*\*\d+ cells matched\*\*", summary) and "Median ratio on cuda" in summary
    # the environments: the package that differs is marked and named
    row = _row(md, "numpy")
    assert row[0] == "numpy" and "2.4.6" in row[1] and row[2] == "**9.9.9**" and row[3] == "≠"
    assert row[1].startswith("**")
    assert "differ (" in md and "numpy" in md[md.index("Package versions:"):]
    for probe in ("NVIDIA H100 80GB HBM3", "580.159.04", "copy bandwidth (cuda)", "launch pipelined (cuda)"):
        assert probe in md
    # the figure, its data and the command that reproduces it
    assert (out / "figures" / "against-ratio.png").is_file()
    assert (out / "figures" / "against-ratio.csv").read_text().startswith("panel,framework")
    assert "python -m compare site MINE --out REPORT --against REFERENCE" in md
    assert 'class="sortable"' in html and "figures/against-ratio.png" in html
    assert page_problems(out / "against.html") == []          # parses; every image and link resolves


def test_nothing_in_common(stores: dict[str, Any]) -> None:
    _saxpy_only(stores["mine"])
    ref = stores["ref"]
    (ref / "sweep.json").unlink()
    (ref / "stress.json").unlink()
    doc = json.loads((ref / "results.json").read_text())
    for r in doc["records"]:
        r["params"]["seed"] = 12345                      # no cell matches at other parameters
    (ref / "results.json").write_text(json.dumps(doc))
    md = (_site(stores, ref) / "against.md").read_text()
    assert "No cell of this run matches one of the reference's" in md
    assert "## Every matched cell" not in md and "## The two environments" in md


def test_against_one_of_the_results_is_refused(stores: dict[str, Any],
                                                capsys: pytest.CaptureFixture[str]) -> None:
    out = stores["tmp"] / "out"
    for same in (stores["mine"], stores["mine"] / "results.json"):
        assert cli.main(["site", str(stores["mine"]), "--out", str(out), "--against", str(same)]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("error: --against") and "\n" not in err
    assert not out.exists()


def _twice_the_run_floor(warp: dict[str, Any]) -> None:
    warp["hardware"]["launch_latency_s"] *= 2


def _twice_in_its_own_floor(warp: dict[str, Any]) -> None:
    warp["cell_floor"] = {"before": {"latency_s": 2 * warp["hardware"]["launch_latency_s"]},
                          "after": {"latency_s": 1e-9}}           # the after probe: never the divisor


@pytest.mark.parametrize("edit,floors,page,summary", [
    # the reference's run had twice the launch floor: the raw ratio stays beside the floors' and the
    # page names the unit
    (_twice_the_run_floor, "1.00×", "in units of each run's own launch floor",
     "In units of each run's own launch floor: **"),
    # its warp cell carries its own floor (cell_floor.before) at twice its run's yardstick: divided by
    # the cell's floor, not the run's, and the row, the page and the summary say so
    (_twice_in_its_own_floor, "1.00× (cell floors: there)", "divides that side by its cell's own floor",
     "(1 with a cell's own floor on one side or both)"),
], ids=["run-floor", "cell-floor"])
def test_against_compares_in_launch_floors(stores: dict[str, Any], edit: Any, floors: str, page: str,
                                           summary: str) -> None:
    """Warp's latency, twice as slow there in seconds, is the same in floors: (m / L) / (2 m / 2 L) = 1."""
    md = _against_warp_edited(stores, edit)
    row = _row(md, "cuda", "saxpy", "warp", "default", "float32", "defaults", "latency")
    assert row[-3:] == ["0.50×", floors, "faster"]
    # the pipelined floor was left alone (no probe of its own): its floors ratio is the raw one, unmarked
    assert _row(md, "cuda", "saxpy", "warp", "default", "float32", "defaults", "throughput")[-3:-1] == ["1.00×", "1.00×"]
    assert page in md
    assert summary in md[md.index("## Summary"):md.index("## Every matched cell")]


def test_against_without_cells_own_floors_reads_as_before(stores: dict[str, Any]) -> None:
    _saxpy_only(stores["mine"])
    md = (_site(stores, stores["ref"]) / "against.md").read_text()
    assert "cell floors" not in md and "cell's own floor" not in md
