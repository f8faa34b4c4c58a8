"""compare/site/fmt.py: numbers in words as the site prints them (fast tier)."""
from __future__ import annotations

import math

import pytest

from compare.site import fmt
from compare.site.matrix import Cell


@pytest.mark.parametrize("v,text", [
    (2.5e-6, "2.5 µs"), (1.0, "1 s"), (0.0123, "12.3 ms"), (3e-10, "0.3 ns"), (999.6e-6, "1000 µs"),
    (180.0, "3 min"), (None, "-"), (math.nan, "-"), (math.inf, "-")])
def test_seconds(v, text):
    assert fmt.seconds(v) == text


@pytest.mark.parametrize("v,unit,text", [
    (2.5e9, "/s", "2.5 G/s"), (1500.0, "B/s", "1.5 kB/s"), (12.0, "/s", "12 /s"), (3e12, "/s", "3 T/s")])
def test_rate(v, unit, text):
    assert fmt.rate(v, unit) == text


@pytest.mark.parametrize("v,text", [(512, "512 B"), (2048, "2 KiB"), (3 * 2**20, "3 MiB"),
                                    (1.5 * 2**30, "1.5 GiB"), (None, "-")])
def test_nbytes_uses_binary_units(v, text):
    assert fmt.nbytes(v) == text


def test_value_picks_the_rows_unit():
    assert fmt.value(1e-3, "s") == "1 ms" and fmt.value(2**20, "B") == "1 MiB"
    assert fmt.value(2e6, "1/s") == "2 M/s" and fmt.value(1.23456, "x") == "1.23"
    assert fmt.value(None, "s") == "-"


def test_pct_ratio_and_fraction():
    assert fmt.pct(0.456) == "46 %" and fmt.pct(None) == "-"
    assert fmt.ratio(1.0) == "1.00×" and fmt.ratio(12.34) == "12.3×" and fmt.ratio(12345) == "12345×"
    assert fmt.fraction(1.54, "cache") == "cache (154 %)" and fmt.fraction(0.5) == "50 %"


def test_cell_text_shows_the_ratio_or_why_there_is_none():
    assert fmt.cell_text(Cell("warp", 1e-6, ratio=2.0, status="ok")) == "2.00×"
    assert fmt.cell_text(Cell("warp", 1e-6, ratio=2.0, status="ok", reference=True)) == f"2.00× {fmt.REFERENCE_MARK}"
    assert fmt.cell_text(Cell("warp", None, status="mismatch")) == "✗ mismatch"
    assert fmt.cell_text(Cell("warp", None, status="skipped")) == "skipped"
    assert fmt.cell_text(Cell("warp", None)) == "—"


def test_cell_title_names_the_variant_spread_and_interval():
    c = Cell("warp", 2e-6, lo=1e-6, hi=3e-6, variant="graph", status="ok", ratio=1.0, tied=True,
             ci=(1.5e-6, 2.5e-6), processes=4, default_value=4e-6, default_ratio=2.0)
    title = fmt.cell_title(c, "s")
    assert title.startswith("2 µs; shares the top of the row; fastest variant graph")
    assert "the default variant: 4 µs (2.00×)" in title and "quartiles 1 µs – 3 µs" in title
    assert "95 % interval over 4 processes 1.5 µs – 2.5 µs" in title
    assert fmt.cell_title(Cell("warp", None, status="error", reason="boom"), "s") == "boom"
    assert fmt.variant_label(c) == "graph" and fmt.variant_label(Cell("warp", 1.0, variant="default")) == ""


def test_params_text_lists_only_what_differs_from_the_defaults():
    assert fmt.params_text({"n": 10, "dt": 0.1}, {"n": 1000, "dt": 0.1}) == "n=10"
    assert fmt.params_text({"n": 1000}, {"n": 1000}) == "defaults" and fmt.params_text({}, {}) == "defaults"


def test_every_band_has_an_emoji():
    from compare.render.colors import BANDS
    assert set(fmt.BAND_EMOJI) == {b.name for b in BANDS}


def test_with_floors_gives_the_figure_and_its_launch_floors():
    assert fmt.with_floors(37.9e-6, 37.9 / 13.7) == "37.9 µs = 2.77 floors"
    assert fmt.with_floors(37.9e-6, None) == "37.9 µs"            # no yardstick: the figure alone
    assert fmt.with_floors(None, 2.0) == "-"
    assert fmt.with_floors(37.9e-6, 37.9 / 13.7, own=True) == "37.9 µs = 2.77 cell floors"   # the cell's own
