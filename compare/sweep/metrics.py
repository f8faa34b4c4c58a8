"""Derived figures of a sweep's records (docs/measurement.md), pure functions of saved records:
  * achieved bandwidth = bytes the kernel must move (scenario ``work``) / median time per call;
  * copy roofline = the same-run hardware yardstick, or in older files the highest bandwidth of
    any backend on that device in the run, measured by the scenario whose role is 'copy';
  * launch share = trivial-launch wall time (role 'launch') / the cell's wall time
    (>= 1/2: overhead-bound);
  * Pareto front = points no other point beats in both time and error.
"""
from __future__ import annotations

import math
from typing import TypedDict

from compare.results.record import Record
from compare.render.report import fmt_bytes
from compare.sweep.rows import need, ok, timed, wall_s
from scenarios.base import Precision

OVERHEAD_SHARE = 0.5     # launch time >= half the cell's time: overhead-bound
BANDWIDTH_SHARE = 0.5    # >= half the copy roofline: bandwidth-bound
CACHE_SHARE = 1.25       # above the roofline by more than write-allocate accounting (9/8) explains
ERROR_FLOOR = 1e-17      # where an exact (0) error is drawn on a log axis


def gbps(nbytes: float, seconds: float) -> float:
    """Achieved bandwidth in GB/s (10^9 bytes per second)."""
    return nbytes / seconds / 1e9 if seconds > 0 else math.nan


class Roofline(TypedDict):
    """A device's copy roofline and where it comes from."""
    gbps: float
    backend: str            # 'hardware yardstick', or the backend whose copy was fastest
    precision: str
    n: int | str            # the copy's size, or how the yardstick copied
    clock: str


class BandwidthRow(TypedDict):
    gbps: float
    wall_gbps: float
    roof_share: float | None
    launch_share: float | None
    regime: str


class ErrorPoint(TypedDict, total=False):
    """One error-sweep cell on the time-against-error plane, with its Pareto flags."""
    rec: Record
    time: float
    error: float
    front_backend: bool     # on its backend's own front
    front_all: bool         # on the front of every backend


def roofline(records: list[Record], device: str) -> Roofline | None:
    """The copy roofline of ``device``: the same-run hardware yardstick (a driver memcpy that no
    contestant controls; ``compare/running/hardware.py``) where the records carry it; for files made
    before it existed, the best copy bandwidth of any backend (primary clock), so labelled."""
    hw = next((r.hardware for r in records if r.device == device
               and r.hardware and r.hardware.copy_bytes_per_s), None)
    if hw:
        return {"gbps": hw["copy_bytes_per_s"] / 1e9, "backend": "hardware yardstick",
                "precision": "bytes", "n": hw.get("copy_how", ""), "clock": "same-run"}
    best: Roofline | None = None
    for r in ok(records, sweep="bandwidth", role="copy", device=device):
        t = timed(r)
        bw = gbps(need(r, "work")["bytes"], t.median_s)
        if best is None or bw > best["gbps"]:
            best = {"gbps": bw, "backend": r.backend, "precision": r.precision,
                    "n": need(r, "params")["n"], "clock": t.timer if t.timer is not None else "wall"}
    return best


def launch_wall(records: list[Record], backend: str, device: str, precision: Precision) -> float | None:
    hits = ok(records, sweep="bandwidth", role="launch", backend=backend, device=device, precision=precision)
    return wall_s(hits[-1]) if hits else None


def regime(launch_share: float | None, roof_share: float | None) -> str:
    if launch_share is not None and launch_share >= OVERHEAD_SHARE:
        return "overhead-bound"
    if roof_share is not None and roof_share > CACHE_SHARE:
        return "cache-resident"
    if roof_share is not None and roof_share >= BANDWIDTH_SHARE:
        return "bandwidth-bound"
    return "mixed" if launch_share is not None and roof_share is not None else "-"


def bandwidth_row(rec: Record, records: list[Record]) -> BandwidthRow:
    """Achieved GB/s, % of the copy roofline, launch share and regime of one bandwidth cell."""
    nbytes = need(rec, "work")["bytes"]
    bw = gbps(nbytes, timed(rec).median_s)
    roof = roofline(records, rec.device)
    lw = launch_wall(records, rec.backend, rec.device, rec.precision)
    share = lw / wall_s(rec) if lw else None
    frac = bw / roof["gbps"] if roof else None
    return {"gbps": bw, "wall_gbps": gbps(nbytes, wall_s(rec)), "roof_share": frac,
            "launch_share": share, "regime": regime(share, frac)}


def pareto_front(points: list[tuple[float, float]]) -> list[bool]:
    """For each (time, error) point: True if no other point is <= in both and < in one."""
    flags = []
    for i, (t, e) in enumerate(points):
        dominated = any((t2 <= t and e2 <= e) and (t2 < t or e2 < e)
                        for j, (t2, e2) in enumerate(points) if j != i)
        flags.append(not dominated)
    return flags


def error_points(records: list[Record], device: str, scenario: str) -> list[ErrorPoint]:
    """Time-against-error points (ok cells with a finite error), with Pareto flags."""
    pts: list[ErrorPoint] = []
    for r in ok(records, sweep="error", device=device, scenario=scenario):
        e = r.converged.error if r.converged else None
        if isinstance(e, (int, float)) and math.isfinite(e):
            pts.append({"rec": r, "time": wall_s(r), "error": max(float(e), ERROR_FLOOR)})
    overall = pareto_front([(p["time"], p["error"]) for p in pts])
    for backend in {p["rec"].backend for p in pts}:
        mine = [p for p in pts if p["rec"].backend == backend]
        for p, f in zip(mine, pareto_front([(p["time"], p["error"]) for p in mine])):
            p["front_backend"] = f
    for p, f in zip(pts, overall):
        p["front_all"] = f
    return pts


def device_bytes(rec: Record) -> tuple[int | None, str]:
    m = rec.memory          # the framework's own figures are its extra keys, by the framework's names
    if m is None:
        return None, "-"
    if isinstance(m.device_bytes, (int, float)):     # the one metric every backend shares
        own = m.get("device_peak_bytes")
        return int(m.device_bytes), "NVML above the context" + (
            f"; framework's own figure {fmt_bytes(own)}" if isinstance(own, (int, float)) else "")
    for k, src in (("device_peak_bytes", m.get("device_memory_source", "framework")),
                   ("nvml_process_peak_bytes", "nvml process"),
                   ("nvml_device_delta_peak_bytes", "nvml device delta")):
        if isinstance(m.get(k), (int, float)):
            return int(m[k]), src
    return None, m.get("nvml_note", "-") if rec.device != "cpu" else "-"
