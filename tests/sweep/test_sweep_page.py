"""compare/sweep/page.py: the sweep's page from stored sweep files (moved here from
tests/suites/test_sweep.py). Named test_sweep_page: pytest collects test files by basename, and
compare/stress/ has a page module too."""
from __future__ import annotations

import pytest

from compare.results.record import Record
from compare.results.store import Store
from compare.suites import sweep
from compare.sweep import page as sweep_page
from conftest import ROOT


@pytest.mark.parametrize("published,device,old_format", [
    ("docs/results/cpu/sweep.json", "cpu", None),    # today's format
    ("tests/data/format1-sweep.json", "cuda", 1)])   # a format-1 file, upgraded on reading
def test_published_sweep_file_still_renders(tmp_path, published, device, old_format):
    store = Store.read(ROOT / published, "sweep")
    assert store.upgraded_from == old_format
    data = sweep.contents(store)
    assert all(r.tags is not None for r in data.records)
    text = sweep_page.page(data, {}, tmp_path / "page.md", "t", ["sweep.json"])
    for heading in (f"## {device}: launch overhead", f"## {device}: copy bandwidth (roofline)",
                    f"## {device}: SAXPY bandwidth against size", "### projectile",
                    f"## {device}: particles scaling"):
        assert heading in text
    assert "| 2^24 " in text and "| particle-steps/s " in text and "No data." not in text
    assert "Roofline for this device" in text


# ---- the page's parts, on hand-made records ------------------------------------------------------
def rec(status="ok", reason="", knob=None, device="cpu"):
    return Record(scenario="saxpy", backend="warp", device=device, precision="float32", status=status, reason=reason,
                  params={"n": 16}, tags={"sweep": "bandwidth", "knob": knob or {"name": "n", "value": 16}})


def test_numbers_in_words():
    assert sweep_page.fmt_rate(2.5e9, "B/s") == "2.5 GB/s" and sweep_page.fmt_rate(12.0) == "12"
    assert sweep_page.fmt_rate(None) == "-" and sweep_page.fmt_rate(float("inf")) == "-"
    assert sweep_page.pct(0.256) == "26%" and sweep_page.pct(None) == "-"
    assert sweep_page.knob_text(rec()) == "n=16" and sweep_page.knob_text(rec(knob={"name": "precision"})) == "-"


def test_problems_list_every_cell_that_is_not_ok():
    assert sweep_page.problems([rec()]) == "None: every cell ran and passed its check.\n"
    text = sweep_page.problems([rec(), rec("error", "boom"), rec("skipped", "no GPU", device="cuda")])
    assert text.splitlines() == ["- bandwidth saxpy/warp/cpu/float32/default (n=16): **error**: boom",
                                 "- bandwidth saxpy/warp/cuda/float32/default (n=16): **skipped**: no GPU"]


def test_plot_keys_and_images_are_relative_to_the_page(tmp_path):
    assert sweep_page.plot_key("scaling", "cpu", "sdf", ["sdf"]) == "scaling-cpu"
    assert sweep_page.plot_key("scaling", "cpu", "sdf", ["sdf", "particles"]) == "scaling-sdf-cpu"
    written = {"scaling-cpu": tmp_path / "plots" / "scaling_cpu.png"}
    assert sweep_page._img(written, "scaling-cpu", tmp_path / "sweep.md", "alt") == "![alt](plots/scaling_cpu.png)\n\n"
    assert sweep_page._img(written, "horizon-cpu", tmp_path / "sweep.md", "alt") == ""


def test_summary_counts_statuses():
    assert sweep_page.summary([rec(), rec(), rec("error")]) == "1 error, 2 ok"


@pytest.mark.parametrize("dirty,words", [(False, "abc1234\n"), (True, "abc1234 (dirty tree)"),
                                         (None, "abc1234 (tree state unknown)")])
def test_the_environment_says_the_last_runs_tree_state(dirty, words) -> None:
    """A run whose tree state is unknown (a copied tree not checked) is not shown as a clean commit."""
    env = {"git_commit": "abc1234", "created": "t", "packages": {}, **({} if dirty is None else {"git_dirty": dirty})}
    assert f"git commit of the last run {words}" in sweep_page.environment([env], []) + "\n"
