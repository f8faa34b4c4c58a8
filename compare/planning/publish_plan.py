"""The parts a ``publish`` runs, planned (no process started): which parts, in which order, with
which exact commands, and what is left out because it does not fit this machine's memory. The
publish command (compare/suites/publish.py) runs them; the site's machine page lists them."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import backends
import scenarios
from compare.measuring import environment
from compare import options
from compare.planning import outdir

HOST_PROFILE_TOP, CHECK_SAMPLE, STAGED = 12, 4096, "stress-parts"
SWEEPS = ("bandwidth", "scaling", "error", "horizon")
GROUPS = ("large", "stress")
MATRIX_PROCESSES = "auto"      # the matrix part: every figure from interleaved processes (compare.running.repeats)
MATRIX_OVERLAP = "auto"        # ... whose set-ups run side by side, each cell timed alone (compare.running.overlap)
SITTING_S = 1500               # ... and rounds past the fewest only while they fit 25 minutes (--sitting)
PROTOCOL = ("--processes", MATRIX_PROCESSES, "--overlap", MATRIX_OVERLAP, "--sitting", str(SITTING_S))
# every other part that runs cells (float64, the sweeps) overlaps their set-ups too: one rule for all
# (docs/measurement.md, "Overlapped set-ups"; on a host of fewer than 8 cores every window is alone)
SETUPS = ("--overlap", MATRIX_OVERLAP)


@dataclasses.dataclass(frozen=True)
class Part:
    """One part of a publish run: the command after ``python -m compare``; compare/suites/publish.py
    plans them."""
    name: str
    argv: tuple[str, ...]
    reads: tuple[str, ...] = ()     # a derived part: it reruns after any of these ran
    resumes: bool = True            # a rerun continues where a cut-off attempt stopped


def memory() -> dict[str, float]:
    """Bytes free for one worker on the host, and on the smallest GPU (absent: none listed)."""
    import psutil
    have = {"cpu": float(psutil.virtual_memory().available)}
    heads = [g.get("memory", "").split()[:1] for g in environment.gpus()]    # "81559 MiB"
    sizes = [float(m[0]) * 2**20 for m in heads if m and m[0].isdigit()]
    return {**have, "cuda": min(sizes)} if sizes else have


def large_parts(devices: list[str], chosen: list[str], common: list[str], quick: bool,
                have: dict[str, float]) -> tuple[list[Part], list[str]]:
    """The large parts, and a line per size left out because it does not fit."""
    from compare.planning.preflight import WORKER_BASELINE_BYTES
    from compare.sweep.points import SWEEPS
    parts, left = [], []
    for dev in devices:
        # each scenario's sizes (compare/sweep/points/; --quick shrinks them), in registry order
        sizes = [(n, e) for n, sw in SWEEPS.items() for e in (sw.large_quick if quick else sw.large.get(dev, ()))]
        for name, exp in sizes:
            sc, sw = scenarios.get(name), SWEEPS[name]
            p = sc.params({"n": 2**exp}, quick=quick)
            host = WORKER_BASELINE_BYTES[dev] + sc.footprint(p, "float32", dev)
            arrays = sc.input_bytes(p, "float32") + sc.output_bytes(p, "float32")
            if host > have.get("cpu", float("inf")) or (dev == "cuda" and arrays > have.get("cuda", float("inf"))):
                left.append(f"large-{dev}-{name}{exp}: left out, needs {outdir.gib(host)} of host memory"
                            + (f" and {outdir.gib(arrays)} on the GPU" if dev == "cuda" else ""))
                continue
            variants = [v for v in sw.large_variants if any(
                v in backends.get(b).variants_for(name) and not backends.get(b).variant_unavailable(v, dev)
                for b in chosen)] or ["default"]
            argv = ["run", name, "--devices", dev, *common, "--precision", "float32", "--variants",
                    ",".join(variants), "--set", f"n={2**exp}"] + (["--check-sample", str(CHECK_SAMPLE)]
                                                                   if sw.large_sampled else [])
            parts.append(Part(f"large-{dev}-{name}{exp}", tuple(argv)))
    return parts, left


def plan(out: str, devices: list[str], backends_arg: str, quick: bool = False,
         timeout: float | None = None, have: dict[str, float] | None = None) -> tuple[list[Part], list[str]]:
    """Every part in run order, and notes on what was left out. ``out`` as the user spelled it."""
    chosen = options.names(backends_arg, backends.BACKENDS, "backends")
    devs = ",".join(devices)
    sel = ["--backends", backends_arg]
    tmo = ["--timeout", f"{timeout:g}"] if timeout is not None else []
    tail = ["--resume", "--out", out, "--no-plots", *(["--quick"] if quick else []), *tmo]
    procs, setups = ((), ()) if quick else (PROTOCOL, SETUPS)
    alone = ("--against", "none")      # a store is a reference itself: no block against another
    # The matrix part and the large parts are what the matrix reads (float32), in repeated
    # processes; float64 cells (parity with the oracle, no row ranks them) run once, in their own
    # part after the matrix part.
    parts = [Part("all", ("all", "--devices", devs, *sel, "--precision", "float32",
                          "--variants", "all", "--host-profile", str(HOST_PROFILE_TOP), *procs, *alone, *tail)),
             Part("float64", ("all", "--devices", devs, *sel, "--precision", "float64", "--variants", "all",
                              *setups, *alone, *tail))]
    large, notes = large_parts(devices, chosen, sel, quick, have if have is not None else memory())
    parts += [dataclasses.replace(p, argv=p.argv + procs + alone + tuple(tail)) for p in large]
    parts += [Part(k, ("sweep", k, "--devices", devs, *sel, *setups, *tail)) for k in SWEEPS]
    from compare.stress import generic
    from compare.stress.registry import experiments
    for exp in experiments():      # ulps and races compare each device with the CPU
        d = [x for x in backends.DEVICES if x in devices or (x == "cpu" and exp in generic.EXPERIMENTS)]
        folder = Path(out) / STAGED / (exp if backends_arg == "all" else "-".join([exp, *chosen]))
        parts.append(Part(f"stress-{exp}", ("stress", "--devices", ",".join(d), *sel, "--only", exp,
                                            "--out", str(folder), "--no-plots", *tmo)
                          + (("--quick",) if quick or "cuda" not in devices else ()), resumes=False))
    parts.append(Part("stress-merge", ("stress", "--merge", str(Path(out) / "stress.json"),
                                       str(Path(out) / STAGED / "*" / "stress.json"), "--out", out, "--no-plots"),
                      reads=tuple(p.name for p in parts if p.name.startswith("stress-"))))
    parts.append(Part("site", ("site", out, "--out", str(Path(out) / "report")),
                      reads=tuple(p.name for p in parts)))
    return parts, notes
