"""One cell, in its own process: ``python -m compare.running.worker SPEC.json OUT_DIR``.

Process-global framework state (ti.init's precision, JAX's x64 flag, CUDA contexts) lives and dies
with this process, and a crash here becomes an ``error`` record in the parent, not a lost run.
Decodes each ``compare.spec.Cell`` (``Cell.from_dict``); writes OUT_DIR/record.json and
OUT_DIR/outputs.npz.

The kernel is not trusted: its outputs must be exactly the scenario's declared outputs
(``Scenario.output_shapes``: names and shapes) with the cell's precision as dtype, or the cell is
an ``error`` naming the violation; a float32 cell that computed in float64 is caught here.
"""
from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import platform
import subprocess
import sys
import time
import traceback
from pathlib import Path
from typing import Any, Iterator

import numpy as np

import backends
import scenarios
from backends.base import OWN_TIMER_S, Backend, Device
from compare.measuring import noise, phases, timing
from compare.running import caches, cell_floor, reuse, scaleout
from compare.running.gate import Gate
from compare.measuring.memory_sampler import Sampler, memory_pass
from compare.measuring.nvml import open_nvml
from compare.results.record import Record
from compare.results.record_parts import Check, Gradient, Memory, OwnTimer, Regime, Timing
from compare.spec import BUSY_TAG, IDENTITY, Cell
from compare.results.store import jsonable
from scenarios.base import Precision


def current_rss_bytes() -> int:
    """This worker's resident set size now (VmRSS), or 0 where /proc is missing."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0


def peak_rss_bytes() -> int:
    """Peak resident set size of this worker (the cell alone: each cell has its own process).

    VmHWM (Linux) belongs to this process image only. getrusage's ru_maxrss would not do: Linux
    carries the parent's high-water mark across fork + exec, so a large driver process (a sweep
    holding references and outputs) would set a floor under every cell's figure.
    """
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024                          # kB
    except (OSError, ValueError, IndexError):
        pass
    import resource
    scale = 1 if sys.platform == "darwin" else 1024                          # bytes on macOS, KiB on Linux
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * scale


def graph_regime(be: Backend, device: Device, kernel: Any, sync: Any, max_time: float) -> Regime:
    """The throughput regime with the backend's graph replays (``Backend.capture``), or why not."""
    try:
        replay = be.capture(device, kernel.run)
        if replay is None:
            return Regime.of(unavailable=f"{be.name} offers no graph capture on {device}")
        sync(None)
        return Regime.of(**timing.pipelined(replay, sync, max_time=max_time), how="captured run() replayed")
    except Exception as exc:  # a failed capture is a finding, never the cell
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        return Regime.of(failed=f"{type(exc).__name__}: {first}")


PROFILE_S = 2.0     # --host-profile's budget: shares of a call settle within a few seconds of calls


def profile_calls(throughput: Regime) -> int:
    """Calls ``timing.host_profile`` makes: the throughput regime's batch (20 to 2000 calls), fewer
    where those would outlast ``PROFILE_S`` (at least 3: a long call repeats its own work)."""
    calls = max(20, min(throughput.k or 0, 2000))
    per_call = throughput.median_s or 0.0
    return max(3, min(calls, int(PROFILE_S / per_call))) if per_call > 0 else calls


OWN_TIMER_BELOW_S = 0.01     # the framework's own timer cross-checks per-call cells, not long ones
CROSS_ROUNDS = 7     # our clock and the framework's own, alternated: the same minutes of the process


def in_blocks(times: list[float], block: int) -> float:
    """The median of the means of ``block`` consecutive calls: a tool's statistic (a timer that
    reports blocks' means, as torch.utils.benchmark does) applied to our own per-call times."""
    block = max(1, min(block, len(times)))
    means = [float(np.mean(times[i:i + block])) for i in range(0, len(times) - block + 1, block)]
    return float(np.median(means))


def own_latency(be: Backend, device: Device, run: Any, sync: Any) -> OwnTimer | None:
    """The framework's own timing of one call + synchronise (``Backend.own_latency``) alternated
    with our latency clock over the same call, ``CROSS_ROUNDS`` stretches each, so the two are
    compared in the same minutes of the process, and in the same statistic (a timer's median of
    blocks' means against ours in blocks of its size: a long tail of slow calls moves a mean, not
    a median). Returns the tool's median, ours in its statistic (``ours_s``), our latency's own
    statistic in those stretches (``ours_call_s``) and the median of the rounds' ratios."""
    theirs, ours, per_call, ratios = [], [], [], []
    try:
        for _ in range(CROSS_ROUNDS):
            got = be.own_latency(device, lambda: sync(run()))
            if got is None:             # the framework ships no timer: nothing more to time
                return None
            last = got
            times = timing.until(lambda: timing.call(run, sync), 10, OWN_TIMER_S, 1.0, 100_000)
            theirs.append(got["median_s"])
            ours.append(in_blocks(times, int(got.get("block") or 1)))
            per_call.append(float(np.median(times)))
            ratios.append(ours[-1] / theirs[-1])
    except Exception as exc:  # a cross-check failing is a note, never the cell
        return OwnTimer.of(failed=f"{type(exc).__name__}: {str(exc).strip()[:200]}")
    return OwnTimer.from_json({**last, "median_s": float(np.median(theirs)), "ours_s": float(np.median(ours)),
                               "ours_call_s": float(np.median(per_call)), "ratio": float(np.median(ratios)),
                               "rounds": CROSS_ROUNDS})


def contract_violation(sc: Any, params: Any, precision: Precision, outputs: dict[str, np.ndarray]) -> str | None:
    """The first way the kernel's outputs break the scenario's declared contract, or None."""
    want = sc.output_shapes(params)
    missing = [k for k in want if k not in outputs]
    if missing:
        return f"contract: kernel returned no {missing[0]!r} (declared outputs: {', '.join(want)})"
    extra = [k for k in outputs if k not in want]
    if extra:
        return f"contract: kernel returned undeclared output {extra[0]!r} (declared: {', '.join(want)})"
    dtype = np.dtype(precision.scalar)
    for k, shape in want.items():
        a = outputs[k]
        if a.dtype != dtype:
            return f"contract: output {k!r} has dtype {a.dtype}, the cell's precision is {precision}"
        if shape is not None and a.shape != tuple(shape):
            return f"contract: output {k!r} has shape {a.shape}, expected {tuple(shape)}"
    return None


def device_memory(be: Backend, device: Device) -> dict[str, int | float | str]:
    """The backend's own device-memory figures; a failing reader is noted, not fatal."""
    try:
        return be.memory(device)
    except Exception as exc:
        return {"device_memory_error": f"{type(exc).__name__}: {exc}"}


def run_cell(cell: Cell, out_dir: Path, cache_note: str = "", set_up: bool = False,
             laps: phases.Laps | None = None, gate: Gate | None = None) -> Record:
    """Build, time, download and check one cell. Exceptions propagate (the parent records them).
    ``laps``: where the cell's time goes (``time.phases``), begun before the caller's part.
    ``gate``: in an overlapped run, the driver's word before the clocks start (``compare.running.gate``);
    everything from the kernel's build to the graph regime is the cell's timed window."""
    laps = laps or phases.Laps()
    gate = gate or Gate(out_dir)
    sc = scenarios.get(cell.scenario)
    be = backends.get(cell.backend)
    device, precision, variant, params = cell.device, cell.precision, cell.variant, cell.params
    inputs = sc.inputs(params, precision)
    laps.lap("inputs")

    nvml, nvml_note = open_nvml(device)       # baseline before the framework touches the GPU
    floor = cell_floor.Probes(device, laps, gate.gated)     # the cell's own launch floor (CUDA)
    if not set_up:
        be.setup(device, precision, variant)
    be.ensure_context(device)
    if nvml:
        nvml.mark_baseline()                  # the metric leaves the framework's context out
    sync = lambda r: be.synchronize(device, r)  # noqa: E731
    rss_before = current_rss_bytes()          # the host-memory baseline, framework started
    laps.lap("framework")
    gate.wait()
    if gate.gated:
        laps.lap("wait")
    floor.gate_opened()
    t0 = time.perf_counter()
    kernel = be.kernel(sc.name)(params, inputs, device, precision, variant)
    sync(None)
    setup_s = time.perf_counter() - t0
    laps.lap("build")
    sampler = Sampler(nvml)      # NVML's milestones, and a thread on in the first call and an untimed pass
    sampler.milestone()
    with sampler:
        first_call_s = timing.call(kernel.run, sync)
    laps.lap("first_call")
    sampler.milestone()
    timer, clock = timing.event_timer(be, device, cell.timer)
    meter = noise.HostMeter()
    t = timing.steady_state(kernel.run, sync, warmup=cell.warmup, repeat=cell.repeat, min_time=cell.min_time,
                            max_time=cell.max_time, timer=timer)
    events_error = {"events_error": clock} if timer is None and clock != timing.CLOCK else {}   # why no events
    laps.lap("steady")
    sampler.milestone()
    latency = Regime.of(**{k: t["wall"][k] for k in ("median_s", "iqr_s", "min_s")}, repeats=t.repeats)
    throughput: Regime | None = None
    if cell.throughput:
        throughput = timing.pipelined(kernel.run, sync, max_time=cell.max_time, latency=latency)
        laps.lap("throughput")
        sampler.milestone()
    host = meter.stop()
    nvml_pass = memory_pass(kernel.run, sync, sampler) if cell.check else {}     # {} without NVML
    if nvml_pass:
        laps.lap("memory_pass")
    run_peak = peak_rss_bytes()               # before the download and the oracle add theirs
    # a repeat process (compare.running.repeats) times the figures alone: the first process
    # downloaded, checked, profiled and cross-checked the cell; no figure reads those again
    first = cell.check
    download_s: float | None = None
    outputs: dict[str, np.ndarray] = {}
    if first:
        t0 = time.perf_counter()
        got = kernel.outputs()
        download_s = time.perf_counter() - t0
        laps.lap("download")
        if not isinstance(got, dict):
            raise ContractError(f"contract: outputs() returned {type(got).__name__}, not a dict of arrays")
        outputs = {k: np.asarray(v) for k, v in got.items()}

    # the regimes after the latency, in the order the time block keeps them
    regimes: dict[str, Regime | OwnTimer | timing.HostProfile] = {}
    if throughput is not None:
        regimes["throughput"] = throughput
        # after the download: a failed capture cannot touch the outputs
        regimes["graph"] = graph_regime(be, device, kernel, sync, cell.max_time)
        laps.lap("graph")
    if first and cell.host_profile and throughput is not None:   # after the peaks and the download too
        regimes["host_profile"] = timing.host_profile(kernel.run, sync, profile_calls(throughput),
                                                      cell.host_profile)
        laps.lap("host_profile")
    if first:
        regimes["null"] = timing.null_call(sync)   # the harness's floor, on the now idle device
        laps.lap("null")
    # the framework's own clock, to cross-check ours: once per cell (its first process; a repeat
    # process times the figures alone, compare.running.repeats), never in a sweep (Cell.own_timer)
    if cell.check and cell.own_timer and (latency.median_s or 0.0) < OWN_TIMER_BELOW_S:
        if (own := own_latency(be, device, kernel.run, sync)) is not None:
            regimes["own_timer"] = own
        laps.lap("own_timer")
    floor.after()
    gate.release()

    def timed() -> Timing:
        """The ``time`` block, with the cell's phases so far."""
        partial = Timing.of(first_call_s=first_call_s, **t, **events_error, latency=latency, **regimes,
                            setup_s=setup_s, download_s=download_s, clock=timing.CLOCK, timer="wall",
                            first_call_clock=timing.CLOCK, cache=cache_note,
                            window=[round(w, 4) for w in gate.window])   # epoch seconds: no two cells' overlap
        return Timing.of(**partial, noise=noise.verdict(partial, host),
                         phases={k: round(v, 4) for k, v in laps.spent.items()})
    params_json = dataclasses.asdict(params)
    if not cell.check:      # a repeat process (compare.running.repeats): the first process checked the cell
        # a miniature's (compare.planning.calibrate) peak, which the memory preflight scales to its big cell
        return record_of(cell, status="ok", reason="", params=params_json, time=timed(),
                         memory=Memory.of(peak_host_rss_bytes=run_peak), **floor.fields())
    violation = contract_violation(sc, params, precision, outputs)
    if violation:
        raise ContractError(violation)
    sampled = sc.sample(params, inputs, outputs, cell.check_sample)
    c_in, c_out = (sampled.inputs, sampled.outputs) if sampled else (inputs, outputs)
    reference = reuse.oracle(sc, params, c_in, precision)     # the tests': kept across workers
    check = sc.check(params, c_in, c_out, reference, precision)
    work = sc.work(params, precision)
    laps.lap("check")
    gradient = None
    if sc.has_gradient:
        gradient = Gradient.of(
            method=be.gradient_method,
            value=check.details.get("gradient_value", outputs["grad"]),
            reference=check.details.get("gradient_reference"),
            reference_value=check.details.get("gradient_reference_value", reference["grad"]),
            vs_oracle=check.details.get("gradient_error"),
            vs_oracle_rel=check.details.get("gradient_rel_error"),
            vs_fd64_rel=check.details.get("gradient_vs_fd64_rel"),
            tolerance=check.details.get("gradient_tolerance"),
            **{k: check.details[f"gradient_{k}"] for k in ("fd_agreement", "fd_resolved")
               if f"gradient_{k}" in check.details})
    # useful work per second in the throughput regime (the latency regime where not measured)
    per_call = (throughput or t).median_s
    rates = {f"{k}_per_s": v / per_call for k, v in work.items() if per_call is not None and per_call > 0}
    memory = Memory.from_json({
        "peak_host_rss_bytes": peak_rss_bytes(),
        "host_bytes": max(0, run_peak - rss_before) if rss_before and run_peak else None,
        **device_memory(be, device),
        **(nvml.figures() if nvml else {}), **sampler.figures(), **nvml_pass,
        **({"nvml_note": nvml_note} if nvml_note else {})})
    info, versions = kernel.info(), be.versions()
    host_name, load, cores = platform.node(), os.getloadavg()[0], len(os.sched_getaffinity(0))
    laps.lap("record")
    # (numpy's stubs read ** as possibly setting savez's allow_pickle: bool)
    if cell.save_outputs:
        np.savez(out_dir / "outputs.npz", **outputs)  # type: ignore[arg-type]
    if cell.save_inputs:
        np.savez(out_dir / "inputs.npz", **inputs)  # type: ignore[arg-type]
    if cell.save_outputs or cell.save_inputs:
        laps.lap("save")
    return record_of(
        cell, status="ok" if check.ok else "mismatch",
        reason="" if check.ok else f"error {check.error:.3g} exceeds tolerance {check.tolerance:.3g}",
        params=params_json, time=timed(),
        # (a mapping first: a detail named as a field takes its place, as before)
        error=Check.from_json({"vs_oracle": check.error, "tolerance": check.tolerance, "vs_reference": None,
                               **check.details, "checked_items": sampled.text() if sampled else "all"}),
        work=work, throughput=rates, memory=memory, info=info,
        host=host_name,
        host_load_1m=load,          # other processes on the host perturb CPU timings
        host_cores=cores,           # fewer than the host's under a Dask core set
        versions=versions, **({"gradient": gradient} if gradient is not None else {}), **floor.fields())


def record_of(cell: Cell, **measured: Any) -> Record:
    """The cell's record: what the worker measured, then the cell's identity, in the order the
    stored files keep (the measured fields, the identity, then tags)."""
    layout = tuple(measured) + IDENTITY + (("tags",) if cell.tags else ())
    return Record(scenario=cell.scenario, backend=cell.backend, device=str(cell.device), precision=cell.precision,
                  variant=cell.variant, tags=cell.tags or None, **measured, layout=layout)


class ContractError(RuntimeError):
    """A kernel's outputs break the scenario's declared contract."""


_SET_UP: set[tuple[str, str, str, str]] = set()
_SPIN = "import time\nt = time.time() + 3600\nwhile time.time() < t: pass\n"


@contextlib.contextmanager
def busy_cores(n: int) -> Iterator[None]:
    """``n`` processes that each keep one core busy for as long as the cell runs (a laptop or CI
    runner with other work on it); ended, and waited for, whatever happens."""
    spinners = [subprocess.Popen([sys.executable, "-c", _SPIN], stdin=subprocess.DEVNULL,
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for _ in range(n)]
    try:
        if spinners:
            time.sleep(0.2)      # running before the cell's clocks start
        yield
    finally:
        for p in spinners:
            p.kill()
            p.wait()


def run_one(raw: dict[str, Any], cell_dir: Path) -> None:     # raw: the driver's JSON of the cell
    """One cell of the batch: its record (and outputs) in ``cell_dir``, whatever happens."""
    laps = phases.Laps(phases.since_launch() if not _SET_UP else 0.0)   # the process start: first cell only
    cell_dir.mkdir(parents=True, exist_ok=True)
    gate = Gate(cell_dir)       # gated (an overlapped run): the driver's word before the clocks and the exit
    try:
        cell = Cell.from_dict(raw)
        be = backends.get(cell.backend)
        if not _SET_UP:       # the first cell of the process sets the caches, then the framework
            cache_note = caches.apply(cell.cache, be, cell_dir, cell.cache_dir)
        else:
            if cell.cache != "warm":
                raise ValueError("only warm-cache cells may share a worker process")
            cache_note = "warm: shares a worker process with earlier cells of the same set-up"
        ident = (cell.backend, str(cell.device), str(cell.precision), cell.variant)
        if _SET_UP and ident not in _SET_UP:
            raise ValueError(f"cells sharing a worker must share backend, device, precision and variant; got {ident}")
        with busy_cores(int((cell.tags or {}).get(BUSY_TAG) or 0)):
            record = run_cell(cell, cell_dir, cache_note, set_up=ident in _SET_UP, laps=laps, gate=gate)
        _SET_UP.add(ident)
        text = json.dumps(jsonable(record.to_json()))     # the record crosses to the driver once, as JSON
    except ContractError as exc:  # the port broke the contract: say how, no traceback needed
        text = json.dumps({"status": "error", "reason": str(exc)})
    except Exception as exc:  # the record says what went wrong; the parent keeps going
        text = json.dumps({"status": "error",
                           "reason": f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}",
                           "traceback": traceback.format_exc()})
    tmp = cell_dir / "record.json.tmp"     # the parent polls for record.json: never half a file
    tmp.write_text(text)
    os.replace(tmp, cell_dir / "record.json")
    gate.park()


def main(argv: list[str], leave: bool = False) -> int:
    """argv: CELLS.json (a list of ``Cell.to_dict``) and OUT_DIR; cell i writes OUT_DIR/cell-i/.
    ``leave`` (the worker process, never an importer): exit at once where ``caches.leave`` may."""
    scaleout.apply_cpu_set()          # a Dask worker's core set, before any framework starts
    got = json.loads(Path(argv[0]).read_text())
    for i, raw in enumerate(specs := got if isinstance(got, list) else [got]):
        run_one(raw, Path(argv[1]) / f"cell-{i}")
    caches.leave(specs if leave else [])    # cold caches, deleted with the cell: no teardown to wait for
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:], leave=True))
