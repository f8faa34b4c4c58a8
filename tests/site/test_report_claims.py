"""What the README and the docs say of the reports is what the stores hold (issue 58, item 6):
which reports measure Dr.Jit, Triton and MLX; where hand-written adjoints are a "ceiling" for
automatic differentiation; why the CPU accuracy row names JAX best and the H100 does not. Each
test reads the page or doc and the store behind it (fast tier)."""
from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from compare.render import charts
from compare.site import data, fmt, matrix, pages, questions
from compare.site import questions_pages as qp
from compare.site.render import page_md

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
MACHINES = {"h100": "H100", "cpu": "AMD EPYC", "xeon": "Intel Xeon", "h200": "H200"}
NEWEST = {"drjit": "Dr.Jit", "triton": "Triton", "mlx": "MLX"}
RULES = {r.key: r for r in questions.RULES}


# one xdist worker: the four machines' stores, loaded once (seconds) for every test of the module, not once per worker
pytestmark = pytest.mark.xdist_group("report-claims")


@pytest.fixture(scope="module")
def stores() -> dict[str, data.Machine]:
    from compare.suites import formats
    formats.register()
    return {k: data.load([DOCS / "results" / k]) for k in MACHINES}


def test_the_machine_reports_are_the_four_the_docs_name() -> None:
    """Four machine reports (one more, the scale-out, is against another run): none is 'both'."""
    machine = sorted(p.parent.parent.name for p in DOCS.glob("results/*/report/site.json")
                     if not json.loads(p.read_text())["against"])
    assert machine == sorted(MACHINES)
    for doc in (ROOT / "README.md", DOCS / "install.md", DOCS / "measurement.md"):
        assert "both reports" not in doc.read_text(encoding="utf-8"), doc


def test_install_names_the_reports_that_measure_the_newest_ports(stores) -> None:
    said = []
    for key, label in MACHINES.items():
        ran = {r.backend for r in stores[key].run if r.status == "ok"}
        said.append(f"{label}: " + ", ".join(n for f, n in NEWEST.items() if f in ran))
    sentence = "Reports that measure them: " + "; ".join(said) + " (Triton compiles for GPUs only)."
    assert sentence in (DOCS / "install.md").read_text(encoding="utf-8")


@pytest.mark.parametrize("key", list(MACHINES))
def test_hand_adjoints_are_a_ceiling_only_where_every_one_beats_the_best_ad_figure(stores, key) -> None:
    """The gradient rows' verdict and rule text, as their page prints them (qp.verdicts), from the
    store: 'ceiling' only where every hand-written adjoint outruns the best AD figure."""
    m = stores[key]
    for rule in (RULES["gradients"], RULES["gradients-memory"]):
        row = matrix.evaluate(rule, m, fmt.value)
        refs = [c for c in row.cells.values() if c.reference and c.ratio is not None]
        if not refs:
            continue
        text = page_md("t", [], qp.verdicts([row]))
        lead = all((c.ratio or 1.0) < 1 for c in refs)
        assert lead or "ceiling" not in text, (key, rule.key, text)
        if rule.reference and f"{rule.reference.what} (" in text:     # the verdict names them (ranked)
            assert ("reference ceiling" in text) == lead, (key, rule.key, text)


def test_measurement_md_says_where_hand_adjoints_lead_as_the_stores_do(stores) -> None:
    text = re.sub(r"\s+", " ", (DOCS / "measurement.md").read_text(encoding="utf-8"))
    assert "on the H100 and on the 2-core CPUs the best AD figure outruns every one" in text
    for key, ahead in (("h100", False), ("cpu", False), ("xeon", False)):
        row = matrix.evaluate(RULES["gradients"], stores[key], fmt.value)
        refs = [c.ratio for c in row.cells.values() if c.reference and c.ratio is not None]
        assert refs and all((r < 1) == ahead for r in refs), (key, refs)


@pytest.mark.parametrize("key, once", [("cpu", True), ("h100", False)])
def test_the_accuracy_page_says_why_jax_leads_on_the_cpu_and_not_on_the_h100(stores, key, once, tmp_path,
                                                                          monkeypatch) -> None:
    """The CPU row names JAX best (1.00 against 1.09-1.10); the H100 puts it at 1.16×. The page
    says why from the records: JAX's SAXPY error fits one rounding of a*x + y on the CPU and shows
    two on the H100."""
    from compare.sweep import plots as sweep_plots
    monkeypatch.setattr(sweep_plots, "plot_time_vs_error", lambda recs, dev, path: Path(path).write_bytes(b"png") or True)
    monkeypatch.setattr(charts, "write_csv", lambda *a, **k: None)
    m = stores[key]
    rows, _ = pages.evaluate(m)
    text = page_md("Accuracy", [], pages.accuracy(qp.Ctx(m, rows, tmp_path, "STORE")))
    why = re.search(r"Why the shares differ: .*", text)
    assert why, text[:2000]
    fits = re.search(r"the errors of ([\w, ]+) fit one rounding", why.group(0))
    assert fits and ("jax" in fits.group(1).split(", ")) == once
    acc = next(r for r in rows if r.rule.key == "accuracy")
    assert (acc.top == "jax") == once and ("jax" in acc.tied) == once


def test_every_run_of_the_results_stores_is_of_a_checked_clean_commit() -> None:
    """measurement.md: "Every run entry of the four `results.json` stores is now of a checked clean
    commit": each names a commit (older runs by its short hash) and a tree known clean (not dirty, not unknown)."""
    assert "Every run entry\nof the four `results.json` stores is now of a checked clean commit" in (
        DOCS / "measurement.md").read_text()
    for key in MACHINES:
        runs = json.loads((DOCS / "results" / key / "results.json").read_text())["runs"]
        assert runs, key
        for r in runs:
            assert re.fullmatch(r"[0-9a-f]{7,40}", str(r.get("git_commit"))) and r.get("git_dirty") is False, (
                key, r.get("created"))


def test_measurement_md_names_the_rows_without_a_second_sitting(stores) -> None:
    """measurement.md lists, per machine, the rows no later sitting has re-measured: the rows the
    site's sittings comparison (compare/site/sittings.py) finds no figure for."""
    from compare.site import sittings
    text = " ".join((DOCS / "measurement.md").read_text(encoding="utf-8").split())
    said = re.search(r"Rows without a second sitting yet: (.*?) Each machine page", text)
    assert said, "measurement.md: the sentence naming rows without a second sitting"
    for key, label in MACHINES.items():
        rows = pages.evaluate(stores[key])[0]
        have = {b.row for b in sittings.compare(rows, sittings.load_all([DOCS / "results" / key]))}
        without = [r.rule.question for r in rows if r.rule.key not in have]
        part = re.search(rf"{re.escape(label)}[^:]*: (.*?)\.", said.group(1))
        assert part, label
        words = part.group(1)
        if not without:
            assert words == "none", (label, words)
        elif len(without) == len(rows):
            assert words.startswith("every row"), (label, words)
        else:
            assert words.split("; ") == without, (label, words)


def test_the_h200_readme_says_how_its_orderings_meet_the_h100s(stores) -> None:
    """docs/results/h200/README.md quotes `compare agree` of the H100's and the H200's stores."""
    from compare.site import agreement
    got = agreement.hold(stores["h100"], stores["h200"]).rows
    text = " ".join((DOCS / "results" / "h200" / "README.md").read_text(encoding="utf-8").split())
    agree, sig, ties, rev = (int(x) for x in re.search(
        r"\*\*(\d+) of (\d+) significant orderings agree, (\d+) became a tie in one of them, (\d+) reversed\*\*",
        text).groups())
    assert (agree, sig, ties, rev) == (sum(r.agree for r in got), sum(r.significant - r.missing for r in got),
                                       sum(r.tie for r in got), sum(r.disagree for r in got))


def test_the_h200_readme_says_what_its_store_holds() -> None:
    """docs/results/h200/README.md: the cut-off matrix part's process counts, from its records and
    its run's start check."""
    from compare.measuring.sitting import SittingCheck, summary
    store = json.loads((DOCS / "results" / "h200" / "results.json").read_text())
    text = " ".join((DOCS / "results" / "h200" / "README.md").read_text(encoding="utf-8").split())
    counts: dict[int, list[dict]] = {}
    for r in store["records"]:
        if r["status"] == "ok":
            counts.setdefault(((r["time"].get("processes") or {}).get("count") or 1), []).append(r)
    ranked, = re.search(r"after four processes a cell where a row ranks its timings \((\d+) cells;", text).groups()
    assert sorted(counts) == [1, 3, 4] and len(counts[4]) == int(ranked)
    assert {r["scenario"] for r in counts[3]} == {"sdf", "projectile"} and all(r["variant"] == "default" for r in counts[3])
    assert "three for the SDF's and projectile's default variants, one for the others" in text
    (run,) = store["runs"]
    start = summary(SittingCheck.from_json(run["sitting"]["start"]))
    figures = re.search(r"Its start check was quiet \(launch \+ sync ([\d.]+) µs, pipelined ([\d.]+) µs, "
                        r"(3rd best of 7 processes)\)", text).groups()
    assert start.startswith(f"launch + sync {figures[0]} us, pipelined {figures[1]} us, {figures[2]}")
    assert run["git_commit"].startswith("fb68863") and run["git_dirty"] is False
