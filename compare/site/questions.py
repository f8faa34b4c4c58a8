"""The questions a framework-chooser asks, each a matrix row with its rule and its page.

The order is the matrix's. Every rule names the records it reads and the figure it compares;
its ``text`` is printed on the overview and on its page, so a reader can check each cell.
"""
from __future__ import annotations

from compare.record import Record
from compare.site import data
from compare.site.matrix import (IN_ALL, Rule, all_defaults, defaults_of, largest_of, rate,
                                 regime)


def _defaults_of_all(m: data.Machine, device: str) -> list[Record]:
    return [r for r in all_defaults(m, device) if r.scenario in IN_ALL]


def _first_call(r: Record) -> float | None:
    t = data.timing(r, "first")
    return t.median if t else None


RULES: tuple[Rule, ...] = (
    Rule("bandwidth", "Large bandwidth-bound arrays", "bandwidth", "s", "lower",
         "SAXPY (out = a·x + y, float32) at the largest n in the records that two or more frameworks "
         "ran; time per call in the throughput regime (k calls, one synchronise); each framework's "
         "fastest variant (fast-math variants and graph replay excluded).",
         largest_of("saxpy", (None, "bandwidth")), regime("throughput")),
    Rule("latency", "Small kernel: one synchronised call", "per-call", "s", "lower",
         "SAXPY at its default n = 10^6, float32: median time of one call followed by a "
         "synchronise (the latency regime), each framework's fastest variant (fast-math excluded).",
         defaults_of("saxpy"), regime("latency")),
    Rule("pipelined", "Small kernel: pipelined calls", "per-call", "s", "lower",
         "SAXPY at n = 10^6, float32: per-call time of k back-to-back calls and one synchronise "
         "(the throughput regime), each framework's fastest variant (fast-math variants and graph "
         "replay excluded).",
         defaults_of("saxpy"), regime("throughput")),
    Rule("graph", "Small kernel: graph replay", "per-call", "s", "lower",
         "SAXPY at n = 10^6, float32: per-call time of a captured call replayed (CUDA graphs, or "
         "the framework's own graph variant); a framework without replay has no cell.",
         defaults_of("saxpy"), regime("graph")),
    Rule("particles-small", "Particle loop, small n", "particles", "s", "lower",
         "Particles at the defaults (256 particles × 300 steps), float32: time per whole rollout "
         "in the throughput regime, each framework's fastest variant (fast-math variants and graph "
         "replay excluded).",
         defaults_of("particles"), regime("throughput")),
    Rule("particles-large", "Particle loop, large n", "particles", "1/s", "higher",
         "Particles at the largest n in the records that two or more frameworks ran (run or "
         "scaling sweep), float32: particle-steps per second in the throughput regime.",
         largest_of("particles", (None, "scaling")), rate),
    Rule("gradients", "Gradients through a simulation at scale: rate", "gradients", "1/s", "higher",
         "The batched differentiable projectile (hard contact, 180 steps, a descent of loss + "
         "gradient evaluations) at the largest batch in the scaling sweep, float32: trajectory-"
         "gradients per second in the throughput regime.",
         largest_of("projectile", ("scaling",)), rate),
    Rule("gradients-memory", "Gradients through a simulation at scale: device memory", "gradients",
         "B", "lower",
         "The same cells: device memory above the framework's CUDA context (NVML peak of the "
         "process), the one memory figure every framework shares.",
         largest_of("projectile", ("scaling",)), data.device_bytes),
    Rule("accuracy", "float32 accuracy against the float64 oracle", "accuracy", "x", "lower",
         "The four scenarios at their defaults, float32, default variant: each cell's error "
         "against the float64 oracle divided by the scenario's derived tolerance (1 = the whole "
         "error budget used; a cell above it is a mismatch, marked failed); a framework's figure "
         "is the geometric mean of its four shares.",
         _defaults_of_all, lambda r: None),
    Rule("compile", "First-call (compile) cost", "compile", "s", "lower",
         "The four scenarios at their defaults, float32, default variant, kernel caches emptied "
         "first: the sum of the four first calls (compilation, tracing and the call itself).",
         _defaults_of_all, _first_call),
    Rule("cpu", "CPU-only use", "cpu", "x", "lower",
         "On the CPU, the four scenarios at their defaults, float32, default variant: the "
         "geometric mean over the scenarios of the framework's throughput-regime time divided by "
         "the fastest framework's on that scenario (1 = fastest everywhere).",
         _defaults_of_all, lambda r: None, device="cpu"),
)

PAGES = {"bandwidth": "Large arrays", "per-call": "Per-call cost", "particles": "Particle loops",
         "gradients": "Gradients at scale", "accuracy": "Accuracy", "compile": "First-call cost",
         "cpu": "CPU-only use", "stability": "Stability", "machine": "Machine and method"}
