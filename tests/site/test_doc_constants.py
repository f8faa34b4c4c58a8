"""The code's constants docs/measurement.md quotes, held to the code (issue 57, item 5: not store
figures, but as apt to drift): the timing protocol, the noise rules, the repeats, the sitting
check, the yardstick (as the stores' newest runs describe it), the preflight and the sweeps'
points. The ranking gaps and the coverages: test_measurement_claims.py. Fast tier."""
from __future__ import annotations

import inspect
import re
from typing import Any, Callable

import pytest

from compare import options
from compare.measuring import memory_sampler, noise, sitting, sitting_quiet, timing
from compare.planning import calibrate, preflight, publish_plan
from compare.running import cell_floor, hardware, repeats, worker
from compare.site import data
from compare.sweep.points import CHECK_SAMPLE
from compare.sweep.points import copy as copy_points
from compare.sweep.points import particles as particle_points
from compare.sweep.points import projectile as projectile_points
from compare.sweep.points import saxpy as saxpy_points
from measurement_doc import doc_text, machine, said

pytestmark = pytest.mark.xdist_group("measurement-claims")


@pytest.fixture(scope="module")
def doc() -> str:
    return doc_text()


def default(f: Callable[..., Any], name: str) -> Any:
    """A keyword's default in the code (the protocol's defaults live in signatures)."""
    return inspect.signature(f).parameters[name].default


def power(x: int) -> str:
    """2^20 as the doc writes a power of two."""
    assert x > 0 and x & (x - 1) == 0, x
    return f"2^{x.bit_length() - 1}"


def test_the_timing_protocol(doc: str) -> None:
    assert said(doc, r"`warmup` = (\d+) more calls, untimed") == (str(default(timing.steady_state, "warmup")),)
    assert float(said(doc, r"a cell stops early only after `max_time` \((\d+) s\)")[0]) == \
        default(timing.steady_state, "max_time")
    rep, mint, qrep, qmin = said(doc, r"Defaults: `repeat` = (\d+), `min_time` = ([\d.]+) s .*?the sweeps use the same "
                                      r"defaults, (\d+) and ([\d.]+) s with `--quick`\)")
    assert (int(rep), float(mint)) == (default(options.add_timing, "repeat"), default(options.add_timing, "min_time"))
    assert (int(rep), float(mint)) == (default(timing.steady_state, "repeat"), default(timing.steady_state, "min_time"))
    from compare.suites import sweep
    assert f"(3 if args.quick else {rep})" in inspect.getsource(sweep) and (qrep, qmin) == ("3", "0.05")
    assert f"(0.05 if args.quick else {mint})" in inspect.getsource(sweep)
    ms, batches = said(doc, r"k doubles from 1 until one batch lasts ≥ (\d+) ms, then (\d+) batches are timed")
    assert (float(ms) / 1e3, int(batches)) == (timing.BATCH_S, default(timing.pipelined, "repeat"))
    assert int(said(doc, r"a no-op `run` and the framework's synchronise on the now idle device, (\d+) times after 10")[0]) \
        == timing.NULL_CALLS
    below, rounds = said(doc, r"cells under (\d+) ms a call, in the first worker process of a cell only .*? alternated "
                              r"with our clock (\d+) times")
    assert (float(below) / 1e3, int(rounds)) == (worker.OWN_TIMER_BELOW_S, worker.CROSS_ROUNDS)
    timeout = said(doc, r"A cell predicted to take longer than `--timeout` \((\d+) s by default\)")[0]
    assert float(timeout) == default(options.add_timing, "timeout")


def test_the_noise_rules_and_the_repeats(doc: str) -> None:
    spread, times, core, slow = said(doc, r"\| spread \| a regime's IQR above (\d+) % of its median .*?\| repeats \| a "
                                          r"regime timed fewer than (\d+) times .*?above ([\d.]+) core and, .*?the "
                                          r"pipelined per-call time above (\d+)x the synchronised call's wall time")
    assert (float(spread) / 100, int(times), float(core), float(slow)) == (
        noise.SPREAD, noise.MIN_REPEATS, noise.IDLE_FLOOR, noise.SLOW_THROUGHPUT)
    target, lo, hi = said(doc, r"`auto` adds processes until every figure's interval lies within ±(\d+) % of its median "
                               r".*?from (\d+) to (\d+) \(the microsecond")
    assert (float(target) / 100, int(lo), int(hi)) == (repeats.TARGET, repeats.AUTO_MIN, repeats.AUTO_MAX)
    assert float(said(doc, r"when its interval strays beyond ±(\d+) % of the median")[0]) / 100 == data.PROCESS_SPREAD
    assert int(said(doc, r"`publish` passes \*\*`--sitting (\d+)`\*\*")[0]) == publish_plan.SITTING_S


def test_the_sitting_check(doc: str) -> None:
    assert float(said(doc, r"at least ([\d.]+) \(`BUSY_SHARE`\)")[0]) == sitting.BUSY_SHARE
    assert int(said(doc, r"fewer than (\d+) runs of the kind give no quiet reference")[0]) == sitting_quiet.MIN_RUNS
    assert "The quiet figure is the best quartile of those runs'" in doc and sitting_quiet.QUIET_QUANTILE == 0.25
    assert float(said(doc, r"its launch loops within ([\d.]+) s, seconds before the cell's timed window")[0]) == \
        cell_floor.BUDGET_S
    from compare.suites import publish
    more, apart = said(doc, r"A noisy check is first taken (\w+) more, (\d+) s apart \(`RECHECKS`")
    assert ({"once": 1, "twice": 2}[more], float(apart)) == (publish.RECHECKS, publish.RECHECK_S)


def test_the_yardstick_as_the_newest_runs_describe_it(doc: str) -> None:
    """The copies and launches the doc describes are what the H100 and CPU stores' newest runs say
    they measured (each run keeps its yardstick's `copy_how` and `launch_how`)."""
    gib, copies, launches = said(doc, r"`cuMemcpyDtoDAsync` of (\d+) GiB timed with driver events, 2 × bytes / time, "
                                      r"median of (\d+); - `launch_latency_s`: an empty kernel .*?median of (\d+);")
    newest = max(machine("h100").runs, key=lambda e: str(e.get("created")))
    cuda = newest["hardware"]["cuda"]
    assert f"cuMemcpyDtoDAsync of {gib} GiB, CUDA events, median of {copies}" in cuda["copy_how"]
    assert f"(median of {launches}); pipelined = {launches} launches" in cuda["launch_how"]
    mib, reps = said(doc, r"\*\*CPU\*\*: `numpy.copyto` of (\d+) MiB float32, 2 × bytes / time, median of (\d+)")
    newest = max(machine("cpu").runs, key=lambda e: str(e.get("created")))
    how = newest["hardware"]["cpu"]["copy_how"]
    assert how.startswith(f"numpy.copyto of {mib} MiB float32") and f"median of {reps}" in how
    small, large = said(doc, r"at every power of two from (\d+) KiB to (\d+) MiB per array")
    assert (int(small) * 2**10, int(large) * 2**20) == (min(hardware.CURVE_BYTES), max(hardware.CURVE_BYTES))
    (bound,) = said(doc, r"else a stated (\d+) MB for the H100/H200 class")
    assert set(data.L2_BOUND.values()) == {float(bound) * 1e6}
    f32, f64 = said(doc, r"H100 SXM5: ([\d.]+) TFLOP/s float32, ([\d.]+) float64")
    peak = [v for k, v in vars(hardware).items() if isinstance(v, dict) and "H100 80GB HBM3" in v]
    assert peak
    assert [f"{peak[0]['H100 80GB HBM3'][p] / 1e12:g}" for p in ("float32", "float64")] == [f32, f64]


def test_the_memory_figures_and_the_preflight(doc: str) -> None:
    passing, ms = said(doc, r"untimed memory pass after the timing regimes \(calls until ([\d.]+) s have passed\), a "
                            r"sampling thread polls it every (\d+) ms")
    assert (float(ms) / 1e3, float(passing)) == (memory_sampler.INTERVAL_S, memory_sampler.MEMORY_PASS_S)
    from scenarios import projectile
    one, per = said(doc, r"modelled per step as the larger of (\d+) B \(a single trajectory: per-operation overheads "
                         r"dominate\) and (\d+) B per trajectory of the batch")
    assert (float(one), float(per)) == projectile.TAPE_STEP_BYTES
    from compare.spec import Cell
    asks = said(doc, r"at B = 2\^20 it asks (\d+) GiB of each CPU cell")[0]
    big = Cell.make("projectile", "numpy", "cpu", "float32", params={"batch": 1 << 20})
    assert f"{preflight.cell_bytes(big)[0] / 2**30:.0f}" == asks
    first, second = said(doc, r"the same cell at 1/(\d+) and 1/(\d+) of its size, each in its own process")
    assert (int(first), int(second)) == preflight.MEMORY_FACTORS
    said(doc, r"times the rest of the size, twice, plus the check's arrays at full size .*? The margin of two:")
    assert preflight.SLOPE_MARGIN == 2
    steps, batch, gib = said(doc, r"\(the CPU projectile at\s+10\^(\d+) steps and B = 2\^(\d+) under `--quick`, (\d+) GiB "
                                  r"by its check alone")
    from scenarios import get
    hopeless = Cell.make("projectile", "numpy", "cpu", "float32",
                         params={**get("projectile").quick, "steps": 10**int(steps), "batch": 1 << int(batch)})
    assert f"{preflight.floor_bytes(hopeless) / 2**30:.0f}" == gib


def test_big_cells_and_checks_at_scale(doc: str) -> None:
    from scenarios import particles, projectile
    factor, trajectories, n = said(doc, r"the same cell at 1/(\d+) of its size\s+\(`Scenario.scaled`: a projectile batch "
                                        r"from (\d+) trajectories, particles from (\S+)\)")
    assert (int(factor), int(trajectories), n) == (calibrate.FACTOR, projectile.BIG_BATCH, power(particles.BIG_N))
    (least,) = said(doc, r"Each miniature runs within an eighth of `--timeout`,\s+at least (\d+) s")
    assert calibrate.MINIATURE_SHARE == 1 / 8 and float(least) == calibrate.MINIATURE_MIN_S
    items, sampled, batched, rollout = said(
        doc, r"Sampling is the default above these sizes: (\d+) items \(`CHECK_SAMPLE` in `compare/sweep/points/`.*?(\d+) "
             r"particles \(`SCALING_CHECKED`.*?a batched projectile (\d+) trajectories \(`BATCH_CHECKED`.*?particles (\d+) of "
             r"them \(`PARTICLES_CHECKED`")
    assert (int(items), int(sampled), int(batched), int(rollout)) == (
        CHECK_SAMPLE, particle_points.SCALING_CHECKED, projectile.BATCH_CHECKED, particles.PARTICLES_CHECKED)
    assert "`CHECK_SAMPLE` in `compare/planning/publish_plan.py`: publish's large cells" in doc
    assert publish_plan.CHECK_SAMPLE == int(sampled)
    from backends import jax as jax_backend
    cuda, cpu = said(doc, r"`lax.fori_loop`s that do `UNROLL` time steps per\s+iteration \(backends/jax/__init__.py\): "
                          r"(\d+) on CUDA, (\d+) on the CPU")
    assert jax_backend.UNROLL == {"cuda": int(cuda), "cpu": int(cpu)}


def test_the_sweeps_points(doc: str) -> None:
    cpu, cuda = said(doc, r"Scenario `copy`: .*?\(sweep default: (\S+) on the CPU, (\S+) on CUDA\)")
    assert (cpu, cuda) == (power(copy_points.COPY_N[("cpu", False)]), power(copy_points.COPY_N[("cuda", False)]))
    cpu_hi, quick, cuda_hi = said(doc, r"SAXPY size sweep: n = 2\^10, 2\^12, … 2\^(\d+) on the CPU \((2\^10 and 2\^20) with "
                                       r"`--quick`\), 2\^10 … 2\^(\d+) on CUDA")
    exp = saxpy_points.SAXPY_EXP
    assert (max(exp[("cpu", False)]), max(exp[("cuda", False)])) == (int(cpu_hi), int(cuda_hi))
    assert min(exp[("cpu", False)]) == min(exp[("cuda", False)]) == 10 and quick == " and ".join(
        f"2^{e}" for e in exp[("cpu", True)])
    dts, t = said(doc, r"\| particles \| dt = ([\d.]+ … [\d.]+) \(halving\) at fixed simulated time T = ([\d.]+) s")
    pdt = particle_points.PARTICLES_DT[False]
    assert (dts, float(t)) == (f"{pdt[0]:g} … {pdt[-1]:g}", particle_points.PARTICLES_T)
    dts, t = said(doc, r"\| projectile \| dt = ([\d.]+ … [\d.]+) \(halving\) at T = ([\d.]+) s")
    jdt = projectile_points.PROJECTILE_DT[False]
    assert (dts, float(t)) == (f"{jdt[0]:g} … {jdt[-1]:g}", projectile_points.PROJECTILE_T)
    sizes = said(doc, r"Particles at n = ([\w^, ]+) on the CPU \(([\d ]+and [\d ]+) with `--quick`\) and up to (\S+) on\s+CUDA")
    def words(ns: tuple[int, ...], powers_from: int = 2**20) -> str:
        return ", ".join(str(n) if n < powers_from else power(n) for n in ns)
    assert sizes == (words(particle_points.PARTICLES_N[("cpu", False)]),
                     " and ".join(map(str, particle_points.PARTICLES_N[("cpu", True)])),
                     power(max(particle_points.PARTICLES_N[("cuda", False)])))
    cuda_b, cpu_b, steps, evals, descents = said(
        doc, r"against its `batch` B: (1, 4, 16, … \S+) on CUDA \(([\w^, ]+) on a CPU\), hard contact, (\d+) steps, (\d+) loss "
             r"\+ gradient evaluations per run \((\d+) descent steps\)")
    bs = projectile_points.BATCH_SWEEP
    assert cuda_b == f"1, 4, 16, … {power(max(bs[('cuda', False)]))}" and bs[("cuda", False)][:3] == (1, 4, 16)
    assert cpu_b == words(bs[("cpu", False)], 2**16)
    params = projectile_points.BATCH_SWEEP_PARAMS
    iters = int(params["iters"])
    assert params["contact"] == "hard" and (int(evals), int(descents)) == (iters + 1, iters)
    from scenarios import get
    assert get("projectile").Params().steps == int(steps)
    got = said(doc, r"`sweep horizon` runs the projectile at a fixed batch \((\d+) on CUDA, (\d+) on a CPU; `--quick` (\d+) "
                    r"and\s+(\d+)\)")
    hb = projectile_points.HORIZON_BATCH
    assert tuple(map(int, got)) == (hb[("cuda", False)], hb[("cpu", False)], hb[("cuda", True)], hb[("cpu", True)])
    hard, soft = said(doc, r"at horizons of ([\d, ]+ and [\d ]+) steps \(no contact\s+and hard contact\) and ([\d, ]+ and \d+) "
                           r"\(soft contact")
    steps_of = projectile_points.HORIZON_STEPS[False]

    def listed(xs: tuple[int, ...]) -> str:
        return re.sub(r"\b(\d{2,})(\d{3})\b", r"\1 \2", ", ".join(map(str, xs[:-1])) + f" and {xs[-1]}")
    assert (hard, soft) == (listed(steps_of["hard"]), listed(steps_of["soft"])) and steps_of["none"] == steps_of["hard"]
