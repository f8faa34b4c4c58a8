"""The questions a framework-chooser asks, each a matrix row with its rule and its page.

The order is the matrix's: each scenario's own questions (compare/site/topics/, in the
scenarios' order), then those over every scenario. Every rule names the records it reads and
the figure it compares; its ``text`` is printed on the overview and on its page, so a reader
can check each cell.
"""
from __future__ import annotations

from compare.results.record import Record
from compare.site import data, shared_host, topics
from compare.site.matrix import IN_ALL, Rule, all_defaults


def _defaults_of_all(m: data.Machine, device: str) -> list[Record]:
    return [r for r in all_defaults(m, device) if r.scenario in IN_ALL]


def _first_result(r: Record) -> float | None:
    t = data.first_result(r)
    return t.median if t else None


RULES: tuple[Rule, ...] = topics.RULES + (
    Rule("accuracy", "float32 accuracy against the float64 oracle", "accuracy", "x", "lower",
         "The four scenarios at their defaults, float32, default variant: each cell's error "
         "against the float64 oracle divided by the scenario's derived tolerance (1 = the whole "
         "error budget used; a cell above it is a mismatch, marked failed); a framework's figure "
         "is the geometric mean of its four shares. Deterministic figures: a best is named only "
         "5 % or more ahead of the rest.",
         _defaults_of_all, lambda r: None, exact=True),
    Rule("compile", "First-call (compile) cost", "compile", "s", "lower",
         "The four scenarios at their defaults, float32, default variant, kernel caches emptied "
         "first: the sum over the four of the time to first result, set-up (the kernel's "
         "constructor: allocation, upload, and whatever a port builds there) plus the first call "
         "(compilation, tracing and the call itself), the median over cold processes where "
         "several ran. Ports compile in one or the other, so neither alone compares; a record "
         "without a set-up time is not comparable.",
         _defaults_of_all, _first_result),
    Rule("cpu", "CPU-only use", "cpu", "x", "lower",
         "On the CPU, the four scenarios at their defaults, float32, default variant: the "
         "geometric mean over the scenarios of the framework's throughput-regime time divided by "
         "the fastest framework's on that scenario (1 = fastest everywhere).",
         _defaults_of_all, lambda r: None, device="cpu"),
    Rule("busy", "CPU, one core busy", "cpu", "x", "lower",
         "On the CPU, the four scenarios at their defaults, float32, default variant, each timed "
         "twice in one run: idle, then with one core kept busy by another process (`--busy 1`); a "
         "framework's figure is its time under load, the geometric mean over the scenarios of its "
         "busy latency divided by the fastest framework's busy latency on that scenario (1 = fastest "
         "under load everywhere; a framework missing a scenario is not comparable). Its slowdown, "
         "busy over idle latency, is shown beside it on the page, not ranked; a busy figure faster "
         "than its idle one is marked as noise unless the records explain it. A best is named only "
         "where every figure has a 95 % interval across processes (`--processes 6`); from one "
         "process a cell the row shows its ratios and ranks nothing.",
         shared_host.pick, lambda r: None, device="cpu", cells=shared_host.cells, repeated=shared_host.REPEAT),
)

PAGES = {**{k: label for k, (label, _) in topics.PAGES.items()},
         "accuracy": "Accuracy", "compile": "First-call cost", "cpu": "CPU-only use",
         "stability": "Stability", "machine": "Machine and method"}
