"""compare/site/untimed.py: a ranked row says which of a framework's variants it never timed at
its point, and its verdict ranks only the variants timed (fast tier). A toy backend offers two
variants besides the default (one of them CUDA only) and fast math, which no row ranks."""
from __future__ import annotations

from typing import Any, ClassVar

import pytest

import backends
from compare.results.record import Record
from compare.site import answers, data, fmt, pages, questions, untimed
from compare.site import questions_pages as qp
from compare.site.render import P

RUN = {"created": "2026-11-27T00:00:00+00:00", "commit": "abc1234", "dirty": False}
RULES = {r.key: r for r in questions.RULES}


class Toy(backends.Backend):
    name = "toy"
    package = "toy"
    variants = ("default", "fastmath", "wide")
    scenario_variants: ClassVar[dict[str, tuple[str, ...]]] = {"saxpy": ("graph",)}

    def variant_unavailable(self, variant: str, device: str) -> str | None:
        return "CUDA only" if variant == "graph" and device != "cuda" else None


@pytest.fixture(autouse=True)
def toy(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(backends.BACKENDS, "toy", Toy())


def rec(variant: str, median: float = 1e-5, backend: str = "toy", device: str = "cuda",
        status: str = "ok", **fields: Any) -> Record:
    t = {"median_s": median, "iqr_s": 0.0, "repeats": 100}
    return Record(scenario="saxpy", backend=backend, device=device, precision="float32", status=status,
                  variant=variant, run=RUN, time={**t, "latency": t, "throughput": {**t, "k": 4}}, **fields)


def latency_row(*recs: Record) -> Any:
    rows, _ = pages.evaluate(data.Machine((), recs, (), None, (), None))
    return next(r for r in rows if r.rule.key == "latency")


def page_text(row: Any) -> str:
    return "\n".join(b.text for b in qp.verdicts([row]) if isinstance(b, P))


def test_a_variant_offered_and_not_timed_is_named_on_the_row_its_cell_and_its_page():
    row = latency_row(rec("default"), rec("wide", 2e-5))
    cell = row.cells["toy"]
    assert cell.untimed == ("graph",) and cell.variant == "default"
    assert row.verdict.endswith("Not timed at this point: toy (graph). The ranking is of the variants timed.")
    assert "not timed at this point: graph" in fmt.cell_title(cell, "s")
    assert fmt.cell_text(cell) == f"1.00×{fmt.UNTIMED_MARK}"
    assert "Not timed at this point: toy (graph)" in page_text(row)
    assert fmt.UNTIMED_MARK in pages.matrix_md([row], ["toy"])
    assert answers.answer(row).endswith("; variants not timed: toy")


def test_every_variant_timed_says_nothing():
    row = latency_row(rec("default"), rec("wide", 2e-5), rec("graph", 3e-5))
    cell = row.cells["toy"]
    assert cell.untimed == () and "not timed" not in row.verdict.lower()
    assert "not timed" not in fmt.cell_title(cell, "s") and fmt.UNTIMED_MARK not in fmt.cell_text(cell)
    assert "not timed" not in answers.answer(row)


def test_fast_math_is_never_named_nor_a_variant_the_device_cannot_run():
    assert untimed.offered("toy", "saxpy", "cuda") == ("default", "wide", "graph")
    assert untimed.offered("toy", "saxpy", "cpu") == ("default", "wide")       # graph: CUDA only
    assert untimed.offered("toy", "sdf", "cuda") == ("default", "wide")        # graph: saxpy's own
    assert untimed.missing([rec("default", device="cpu")], "cpu") == {"toy": ("wide",)}
    row = latency_row(rec("default"))
    assert row.cells["toy"].untimed == ("wide", "graph")
    assert "fastmath" not in row.verdict and "fastmath" not in fmt.cell_title(row.cells["toy"], "s")


def test_a_failed_variant_was_timed_and_a_framework_skipped_everywhere_is_not_named():
    row = latency_row(rec("default"), rec("wide", status="error", reason="boom"), rec("graph", 3e-5),
                      rec("default", backend="jax", status="skipped", reason="not installed"))
    assert all(c.untimed == () for c in row.cells.values()) and "Not timed" not in row.verdict


def test_frameworks_missing_the_same_variants_are_named_together():
    gone = {"jax": ("checkpoint",), "drjit": ("checkpoint",), "warp": ("tape_zero",)}
    assert untimed.note(gone) == ("Not timed at this point: jax, drjit (checkpoint); warp (tape_zero). "
                                  "The ranking is of the variants timed.")
    assert untimed.note({}) == ""


def test_rows_of_default_variants_only_say_nothing():
    """The rows over every scenario rank defaults only (their rule): no variant is 'untimed' there."""
    assert not untimed.ranks_variants(RULES["accuracy"]) and not untimed.ranks_variants(RULES["compile"])
    assert not untimed.ranks_variants(RULES["cpu"]) and not untimed.ranks_variants(RULES["busy"])
    assert untimed.ranks_variants(RULES["latency"]) and untimed.ranks_variants(RULES["gradients"])
