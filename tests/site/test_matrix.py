"""The recommendation matrix ranks only what is separated, and like with like (fast tier).

Rows are evaluated on hand-made records (compare/site/matrix.py, compare/site/ranking.py):
intervals across worker processes that overlap or lie under 5 % apart tie; figures from one
process tie under 1.6x; equal deterministic figures tie; tied cells share the top band and the
bold; hand-written adjoints sit beside AD on the gradient rows, labelled and never best; the
first-call row sums set-up and first call; a hardware fraction that fits the L2 or passes the
copy is labelled.
"""
from __future__ import annotations

from typing import Any

import pytest

from compare.running import repeats
from compare.results.record import Record
from compare.site import data, fmt, matrix, pages, questions, ranking

RULES = {r.key: r for r in questions.RULES}


ONE_RUN = {"created": "2026-11-27T00:00:00+00:00", "commit": "abc1234", "dirty": False}


def rec(backend: str, scenario: str = "saxpy", *, status: str = "ok", time: dict[str, Any] | None = None,
        **fields: Any) -> Record:
    """A record of one run (a row ranks only figures of one run: tests/site/test_agreement.py)."""
    fields.setdefault("run", ONE_RUN)
    return Record(scenario=scenario, backend=backend, device="cuda", precision="float32", status=status,
                  time=time, **fields)


def latency(median: float, ci: tuple[float, float] | None = None, n: int = 6) -> dict[str, Any]:
    """A record's time block: the latency regime, and its median across ``n`` processes (the
    interval's confidence as compare.running.repeats.interval states it)."""
    t: dict[str, Any] = {"median_s": median, "iqr_s": 0.0, "repeats": 100,
                         "latency": {"median_s": median, "iqr_s": 0.0, "repeats": 100}}
    if ci is not None:
        cover = repeats.interval([float(i) for i in range(n)])[2]
        t["processes"] = {"count": n, "latency": {"values": [median] * n, "median_s": median,
                                                  "ci_lo_s": ci[0], "ci_hi_s": ci[1], "confidence": cover}}
    return t


def machine(run: list[Record] = (), sweep: list[Record] = ()) -> data.Machine:
    return data.Machine((), tuple(run), tuple(sweep), None, (), None)


def row(key: str, run: list[Record] = (), sweep: list[Record] = ()) -> matrix.Row:
    return matrix.evaluate(RULES[key], machine(run, sweep), fmt.value)


# ---- ties from intervals --------------------------------------------------------------------
def test_overlapping_intervals_tie():
    r = row("latency", [rec("warp", time=latency(10e-6, (9e-6, 12e-6))),
                        rec("cupy", time=latency(11.5e-6, (11e-6, 13e-6)))])
    assert r.tied == ("warp", "cupy") and r.best is None and r.top == "warp"
    assert r.verdict.startswith("Tie: warp, cupy") and "95 % intervals overlap" in r.verdict
    assert r.cells["cupy"].band == "best" and r.cells["cupy"].ratio == pytest.approx(1.15)
    assert r.best_text() == "tie: warp, cupy"


def test_intervals_apart_but_under_five_percent_tie():
    r = row("latency", [rec("warp", time=latency(10e-6, (9.9e-6, 10.1e-6))),
                        rec("cupy", time=latency(10.3e-6, (10.2e-6, 10.4e-6)))])
    assert r.tied == ("warp", "cupy")
    assert "intervals apart but within 3.0 %" in r.verdict


def test_intervals_apart_and_five_percent_name_a_best():
    r = row("latency", [rec("warp", time=latency(10e-6, (9.9e-6, 10.1e-6))),
                        rec("cupy", time=latency(11e-6, (10.8e-6, 11.2e-6)))])
    assert r.best == "warp" and r.tied == ("warp",)
    assert r.verdict.startswith("Best: warp") and "separated from cupy (1.1×; 95 % intervals apart" in r.verdict
    assert r.cells["cupy"].band == "near" and not r.cells["cupy"].tied      # 1.10x, but separated
    assert r.cells["warp"].ci == (9.9e-6, 10.1e-6) and r.cells["warp"].processes == 6


# ---- no intervals: the one-process gap ------------------------------------------------------
def test_one_process_figures_tie_below_the_one_process_gap():
    r = row("latency", [rec("warp", time=latency(10e-6)), rec("cupy", time=latency(15.9e-6)),
                        rec("jax", time=latency(16.1e-6))])
    assert r.tied == ("warp", "cupy") and r.best is None
    assert f"under the {ranking.ONE_PROCESS_GAP:g}× they need" in r.verdict
    assert r.cells["cupy"].band == "best" and r.cells["jax"].band == "near"


def test_one_interval_is_not_enough():
    """A cell with an interval against one without: the one-process gap applies."""
    r = row("latency", [rec("warp", time=latency(10e-6, (9.9e-6, 10.1e-6))), rec("cupy", time=latency(13e-6))])
    assert r.tied == ("warp", "cupy")
    r = row("latency", [rec("warp", time=latency(10e-6, (9.9e-6, 10.1e-6))), rec("cupy", time=latency(17e-6))])
    assert r.best == "warp" and "figures without a 95 % interval need 1.6×" in r.verdict


# ---- exact ties -----------------------------------------------------------------------------
def accurate(backend: str, share: float, scenario: str = "saxpy") -> Record:
    return rec(backend, scenario, error={"vs_oracle": share, "tolerance": 1.0}, time=latency(1e-3))


def test_exact_equal_figures_tie_and_the_column_stays_short():
    same = 0.20699706903787302
    names = ("cupy", "warp", "torch", "numba", "triton", "mlx")
    r = row("accuracy", [accurate(b, same) for b in names] + [accurate("jax", same * 1.2)])
    assert r.best is None and set(r.tied) == set(names) and r.tied[0] == r.top
    assert "equal figures" in r.verdict and r.cells["jax"].band == "near"
    assert r.best_text() == f"tie: {r.tied[0]}, {r.tied[1]} +4"
    md = pages.matrix_md([r], [*names, "jax"])
    assert md.count("**🟩 1.00×**") == 6 and "🟨 1.20×" in md


def test_deterministic_figures_separate_at_five_percent():
    r = row("accuracy", [accurate("cupy", 0.2), accurate("warp", 0.2 * 1.04)])
    assert r.tied == ("cupy", "warp")
    r = row("accuracy", [accurate("cupy", 0.2), accurate("warp", 0.2 * 1.06)])
    assert r.best == "cupy" and "deterministic figures need 5 %" in r.verdict


def test_tied_cells_are_bold_and_in_the_top_band_in_html():
    r = row("latency", [rec("warp", time=latency(10e-6)), rec("cupy", time=latency(14e-6))])
    html = pages.matrix_html([r], ["warp", "cupy"])
    assert html.count('class="cell best"') == 2 and html.count("<strong>") == 2
    assert ">tie: warp, cupy</td>" in html


# ---- like with like: hand adjoints ----------------------------------------------------------
def gradients(backend: str, per_s: float, device_bytes: float, method: str | None = None) -> Record:
    t = {"median_s": 1.0 / per_s, "iqr_s": 0.0, "repeats": 5,
         "throughput": {"median_s": 1.0 / per_s, "iqr_s": 0.0, "repeats": 5}}
    return rec(backend, "projectile", time=t, params={"batch": 4096}, tags={"sweep": "scaling"},
               work={"gradients": 1.0, "items": 180.0}, memory={"device_bytes": device_bytes},
               gradient={"method": method} if method else None)


ADJ = [gradients("warp", 100.0, 4e8, "tape"), gradients("jax", 40.0, 1e8, "ad"),
       gradients("triton", 1360.0, 5e7),               # no gradient block: its backend says adjoint
       gradients("cupy", 1200.0, 5e7, "adjoint")]


def test_hand_adjoints_are_never_best_and_are_labelled():
    r = row("gradients", sweep=ADJ)
    assert r.best == "warp" and r.tied == ("warp",)          # 2.5x ahead of jax: one-process gap met
    tri, cup = r.cells["triton"], r.cells["cupy"]
    assert tri.reference and cup.reference and not tri.tied
    assert tri.ratio == pytest.approx(100 / 1360) and tri.band == "ref"
    assert fmt.cell_text(tri).endswith(fmt.REFERENCE_MARK)
    assert r.verdict.startswith("Best AD: warp")
    assert "Hand-written adjoints (reference ceiling, not AD): triton 13.6× faster than warp; cupy 12× faster." \
        in r.verdict
    md = pages.matrix_md([r], ["warp", "jax", "triton", "cupy"])
    assert f"🟦 0.07× {fmt.REFERENCE_MARK}" in md and f"**🟦" not in md and md.rstrip().endswith("| warp |")
    assert 'class="cell ref"' in pages.matrix_html([r], ["warp", "jax", "triton", "cupy"])


def test_gradient_memory_ranks_ad_only():
    r = row("gradients-memory", sweep=ADJ)
    assert r.best == "jax" and r.cells["triton"].reference       # the adjoints' 5e7 is not best
    assert "triton 2× less memory than jax" in r.verdict


def test_only_adjoints_ahead_never_turn_an_ad_tie_into_a_best():
    r = row("gradients", sweep=[gradients("warp", 100.0, 1e8, "tape"), gradients("jax", 90.0, 1e8, "ad"),
                                gradients("triton", 1000.0, 1e8)])
    assert r.best is None and r.tied == ("warp", "jax") and r.verdict.startswith("Tie among AD: warp, jax")


# ---- first call = set-up + first call -------------------------------------------------------
def first(backend: str, setup: float | None, first_call: float, processes: dict[str, Any] | None = None) -> Record:
    t: dict[str, Any] = {"first_call_s": first_call, "median_s": 1e-3, "iqr_s": 0.0, "repeats": 10}
    if setup is not None:
        t["setup_s"] = setup
    if processes:
        t["processes"] = processes
    return rec(backend, time=t)


def test_first_call_row_sums_setup_and_first_call():
    # warp compiles in its constructor, jax in its first call: the first calls alone would put
    # warp 10x ahead; the sums put jax 1.91x ahead
    r = row("compile", [first("warp", 2.0, 0.1), first("jax", 0.1, 1.0)])
    assert r.cells["warp"].value == pytest.approx(2.1) and r.cells["jax"].value == pytest.approx(1.1)
    assert r.best == "jax"
    assert "set-up" in RULES["compile"].text


def test_first_call_without_setup_is_not_comparable():
    r = row("compile", [first("warp", None, 0.1), first("jax", 0.5, 1.0)])
    assert r.cells["warp"].value is None and r.cells["warp"].status == "absent"
    assert "setup_s" in r.cells["warp"].reason


def test_first_call_uses_the_median_of_cold_processes():
    # compare.running.repeats stores each process's set-up + first call as time.processes.first_result
    procs = {"first_result": {"values": [1.3, 1.5, 1.7], "median_s": 1.5, "ci_lo_s": 1.3, "ci_hi_s": 1.7,
                              "confidence": 0.75}}
    t = data.first_result(first("jax", 0.5, 3.0, procs))
    assert t.median == pytest.approx(1.5) and t.processes == 3 and (t.lo, t.hi) == pytest.approx((1.3, 1.7))
    assert t.ci is None           # 3 processes: the range covers the median with 75 %, no 95 % interval
    one = data.first_result(first("jax", 0.5, 3.0))
    assert one.median == pytest.approx(3.5) and one.processes == 1 and one.ci is None


# ---- hardware fractions above 100 % ---------------------------------------------------------
def fraction(f: float, nbytes: float, **hardware: Any) -> Record:
    return rec("warp", work={"bytes": nbytes}, throughput={"hw_fraction": f},
               hardware={"gpu": "NVIDIA H100 80GB HBM3", **hardware})


def test_a_cache_resident_fraction_is_labelled_cache():
    small = fraction(1.54, 24e6)                  # float64 SAXPY at n = 10^6: 24 MB, in the L2
    assert data.fraction_label(small) == "cache"
    assert fmt.fraction(data.hw_fraction(small), data.fraction_label(small)) == "cache (154 %)"
    assert data.fraction_label(fraction(0.7, 24e6)) == "cache"          # in the L2 whatever the figure
    assert data.l2_bytes(small)[0] == data.L2_BOUND["H100"]


def test_an_l2_field_wins_over_the_stated_bound():
    assert data.fraction_label(fraction(0.9, 24e6, l2_bytes=16e6)) == ""
    env = {"hardware": {"cuda": {"l2_bytes": 16e6}}}
    assert data.l2_bytes(fraction(0.9, 24e6), [env]) == (16e6, "l2_bytes")


def test_a_fraction_above_the_copy_beyond_the_l2_is_labelled_too():
    big = fraction(1.02, 3.2e9)
    assert data.fraction_label(big) == "above copy" and fmt.fraction(1.02, "above copy") == "above copy (102 %)"
    assert data.fraction_label(fraction(0.9, 3.2e9)) == ""
    unknown = rec("warp", work={"bytes": 24e6}, throughput={"hw_fraction": 1.3}, hardware={"gpu": "Some GPU"})
    assert data.fraction_label(unknown) == "cache"          # above the copy, no L2 known: cache


# ---- a winning variant that is not the default ------------------------------------------------
def test_a_winning_variant_other_than_the_default_is_named_and_the_default_shown_beside_it():
    from compare.site import questions_pages
    r = row("latency", [rec("warp", variant="record_cmd", time=latency(10e-6)),
                        rec("warp", variant="default", time=latency(48e-6)),
                        rec("cupy", variant="default", time=latency(30e-6))])
    warp, cupy = r.cells["warp"], r.cells["cupy"]
    assert warp.variant == "record_cmd" and warp.winner_not_default and not cupy.winner_not_default
    assert warp.default_value == pytest.approx(48e-6) and warp.default_ratio == pytest.approx(4.8)
    md, html = pages.matrix_md([r], ["warp", "cupy"]), pages.matrix_html([r], ["warp", "cupy"])
    assert "**🟩 1.00×** <sub>record_cmd</sub>" in md and md.count("<sub>") == 1
    assert '<span class="variant">record_cmd</span>' in html and html.count('class="variant"') == 1
    assert "fastest variant record_cmd; the default variant: 48 µs (4.80×)" in html
    table = next(b for b in questions_pages.verdicts([r]) if isinstance(b, pages.Table))
    assert table.rows == (("warp", "record_cmd", "10 µs", "1.00×", "48 µs (4.80×)"),)


def test_a_winning_variant_without_a_default_figure_says_so():
    r = row("latency", [rec("warp", variant="record_cmd", time=latency(10e-6)),
                        rec("warp", variant="default", status="error", reason="boom"),
                        rec("cupy", time=latency(30e-6))])
    assert r.cells["warp"].default_value is None and r.cells["warp"].default_ratio is None
    assert "the default variant: not measured for this row" in fmt.cell_title(r.cells["warp"], "s")


# ---- one definition of the bands in every format ----------------------------------------------
# The colour squares as emoji fonts draw them (Twemoji): the Markdown matrix's meaning of a band.
EMOJI_RGB = {"🟩": "#78b159", "🟨": "#fdcb58", "🟧": "#f4900c", "🟥": "#dd2e44", "🟦": "#55acee"}


def _hue(hex_rgb: str) -> float:
    import colorsys
    r, g, b = (int(hex_rgb[i:i + 2], 16) / 255 for i in (1, 3, 5))
    return 360 * colorsys.rgb_to_hsv(r, g, b)[0]


def test_the_markdown_legend_and_the_html_classes_name_the_same_bands():
    import re

    from compare.render import colors
    from compare.site.render import CSS, inline_html
    legend = pages.legend()
    for b in colors.BANDS:
        words = colors.band_words(b)
        # the Markdown legend puts the band's emoji before its words; the HTML one its class
        assert f"{b.emoji} {words}" in legend.markdown
        assert re.search(rf'<span class="cell {b.name}"[^>]*>&nbsp;</span> {re.escape(inline_html(words))}',
                         legend.html), b.name
        css = re.search(r"\." + b.name + r"\{background:(#[0-9a-f]{6})", CSS)
        assert css and css.group(1) == b.background
        if b.emoji in EMOJI_RGB:           # the swatch is the emoji's colour, not a neighbour's
            near = min(EMOJI_RGB, key=lambda e: min(abs(_hue(EMOJI_RGB[e]) - _hue(b.background)),
                                                    360 - abs(_hue(EMOJI_RGB[e]) - _hue(b.background))))
            assert near == b.emoji, (b.name, b.background)
    # a cell within a band's bound is drawn with that band's emoji and class in both formats
    for ratio, band in ((1.9, "near"), (4.9, "far"), (5.1, "poor")):
        r = row("latency", [rec("warp", time=latency(10e-6)), rec("cupy", time=latency(ratio * 10e-6))])
        assert r.cells["cupy"].band == band
        assert f"{colors.BAND[band].emoji} {fmt.ratio(ratio)}" in pages.matrix_md([r], ["warp", "cupy"])
        assert f'class="cell {band}"' in pages.matrix_html([r], ["warp", "cupy"])


def test_interval_below_confidence_separates_nothing():
    """Two processes' range covers the median with 50 %: apart ranges 1.3x apart are no ranking."""
    r = row("latency", [rec("warp", time=latency(10e-6, (9.9e-6, 10.1e-6), n=2)),
                        rec("cupy", time=latency(13e-6, (12.9e-6, 13.1e-6), n=2))])
    assert r.best is None and r.tied == ("warp", "cupy")
    assert "figures without a 95 % interval within 1.3×" in r.verdict
    far = row("latency", [rec("warp", time=latency(10e-6, (9.9e-6, 10.1e-6), n=2)),
                          rec("cupy", time=latency(17e-6, (16.9e-6, 17.1e-6), n=2))])
    assert far.best == "warp"


def test_latest_prefers_the_repeated_record():
    """Of two records of one cell, the one timed in more processes is the row's, whatever the order."""
    one = rec("warp", time=latency(5e-6))
    six = rec("warp", time=latency(10e-6, (9e-6, 11e-6)))
    assert matrix.latest([six, one]) == [six] and matrix.latest([one, six]) == [six]


# ---- one arithmetic rule ------------------------------------------------------------------------
def test_a_figure_that_ran_with_fast_math_is_never_ranked_whatever_its_variant():
    """Every ranked figure is IEEE arithmetic (docs/ports.md): a fast-math variant, and a default
    cell whose info says it ran with fast math (Dr.Jit's records before its default became
    exact), are left out of the row; an exact record of the same framework is ranked."""
    fast = rec("drjit", time=latency(1e-6), info={"fast_math": True})
    named = rec("taichi", variant="fastmath", time=latency(1e-6))
    r = row("latency", [fast, named, rec("warp", time=latency(10e-6)), rec("cupy", time=latency(20e-6))])
    assert r.cells["drjit"].value is None and "fast math" in r.cells["drjit"].reason
    assert "taichi" not in r.cells and r.top == "warp"
    exact = rec("drjit", time=latency(5e-6), info={"fast_math": False})
    assert row("latency", [fast, exact, rec("warp", time=latency(10e-6))]).top == "drjit"
    # a Dr.Jit float32 record from before its info said: its FastMath default (the backend reads it)
    older = rec("drjit", time=latency(1e-6), info={})
    assert row("latency", [older, rec("warp", time=latency(10e-6))]).cells["drjit"].value is None
    # an exact record of the same cell is read before a fast-math one timed in more processes
    assert row("latency", [older, exact, rec("warp", time=latency(10e-6))]).cells["drjit"].value == 5e-6
    assert row("latency", [rec("warp", time=latency(1e-6), info={}), rec("cupy", time=latency(10e-6))]).top == "warp"
