"""The horizon sweep's table and plot: memory, time and gradient quality against the horizon.

A scenario takes part through its sweeps (compare/sweep/points/): ``points('horizon', ...)``
(the knob is the horizon, e.g. the projectile's steps), ``labels`` 'horizon_items' (the parameter
that counts independent items per run, e.g. batch) and 'horizon_memory' (the parameter values
whose points the memory and time panels draw, e.g. {'contact': 'hard'}), and
``state_bytes_per_step`` (the floor a tape needs). Definitions (docs/measurement.md):
  * memory = ``memory.device_bytes`` on CUDA (NVML above the context), ``memory.host_bytes`` on the
    CPU (resident set above the baseline taken before the kernel was built);
  * bytes per item-step = the memory's growth from the previous horizon of the same group over the
    items x extra steps (the slope: fixed costs cancel);
  * FD agreement = ``gradient.fd_agreement``, the share of checked items whose gradient agrees with
    float64 central differences (scenarios/projectile.py ``check``).
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from backends.base import DEFAULT_VARIANT
from compare.results.record import Record
from compare.render.report import fmt_bytes, fmt_time
from compare.render.figure_check import place_legends
from compare.files import save_figure
from compare.sweep.points import sweeps
from compare.sweep.rows import checked_items, knob, knob_value, label, need, ok, tag, throughput_s, wall_s


def memory(rec: Record) -> tuple[float | None, str]:
    """The cell's own memory and what it is: device bytes on CUDA, host bytes on the CPU."""
    what = "host" if rec.device == "cpu" else "device"
    v = None if rec.memory is None else rec.memory.host_bytes if rec.device == "cpu" else rec.memory.device_bytes
    return (float(v), what) if isinstance(v, (int, float)) else (None, what)


def items(rec: Record) -> int:
    return int(need(rec, "params").get(label(rec.scenario, "horizon_items"), 1) or 1)


def group_key(rec: Record) -> tuple:
    """Cells that differ only in the horizon: same backend, variant, precision, other params."""
    name = knob(rec).name
    other = {k: v for k, v in need(rec, "params").items() if k != name}
    return rec.backend, rec.variant, rec.precision, json.dumps(other, sort_keys=True)


def series(records: list[Record], device: str, scenario: str) -> dict[tuple, list[Record]]:
    out: dict[tuple, list[Record]] = {}
    for r in ok(records, sweep="horizon", device=device, scenario=scenario):
        out.setdefault(group_key(r), []).append(r)
    return {k: sorted(v, key=knob_value) for k, v in sorted(out.items())}


def gradient_cells(records: list[Record], device: str, scenario: str) -> list[Record]:
    """The horizon cells that returned a gradient: ok ones and mismatches (error past its bound)."""
    return [r for r in records if r.status in ("ok", "mismatch") and r.gradient is not None
            and tag(r, "sweep") == "horizon" and r.device == device and r.scenario == scenario]


def slopes(rows: list[Record]) -> list[float | None]:
    """Bytes per item-step between consecutive horizons of one group (None for the first)."""
    out: list[float | None] = [None]
    for a, b in zip(rows, rows[1:]):
        (ma, _), (mb, _) = memory(a), memory(b)
        dn = knob_value(b) - knob_value(a)
        out.append((mb - ma) / (items(b) * dn) if ma is not None and mb is not None and dn else None)
    return out


def varying(rows: list[Record], knob_name: str) -> list[str]:
    """Parameters other than the knob that differ between the sweep's cells (e.g. contact)."""
    keys = {k for r in rows for k in need(r, "params") if k != knob_name}
    return sorted(k for k in keys if len({json.dumps(need(r, "params").get(k)) for r in rows}) > 1)


def table(records: list[Record], device: str, scenario: str) -> str:
    from tabulate import tabulate
    groups = series(records, device, scenario)
    if not groups:
        return ""
    every = [r for rows in groups.values() for r in rows]
    kname = knob(every[0]).name or "size"
    extra = varying(every, kname)
    out = []
    for rows in groups.values():
        for r, slope in zip(rows, slopes(rows)):
            mem, what = memory(r)
            share = r.fd_agreement
            out.append([r.backend, r.variant, r.precision, *(need(r, "params").get(k) for k in extra),
                        knob_value(r), fmt_time(wall_s(r)), fmt_time(throughput_s(r)),
                        f"{fmt_bytes(mem)} ({what})" if mem is not None else "-",
                        f"{slope:.3g}" if slope is not None else "-",
                        f"{100 * share:.0f} %" if share is not None else "-",
                        checked_items(r)])
    unit = label(scenario, "horizon_items", "item")
    return tabulate(out, headers=["backend", "variant", "precision", *extra, kname, "latency median",
                                  "throughput: per call", "memory", f"bytes per {unit}-step (slope)",
                                  "FD agreement", "checked vs oracle"], tablefmt="github") + "\n"


def plot(records: list[Record], device: str, path: Path, scenario: str, colors: dict[str, str],
         plt: Any) -> bool:
    """Memory and time against the horizon (the scenario's 'horizon_memory' points), per backend
    and variant, with the tape floor; FD agreement against the horizon per contact and precision."""
    groups = series(records, device, scenario)
    if not groups:
        return False
    tape = sweeps(scenario)
    want = dict(json.loads(label(scenario, "horizon_memory", "{}")))
    fig, (a1, a2, a3) = plt.subplots(1, 3, figsize=(16, 4.8))
    floor_done = set()
    every = [r for rows in groups.values() for r in rows]
    kname = knob(every[0]).name or "size"
    for (backend, variant, prec, _), rows in groups.items():
        if any(need(rows[0], "params").get(k) != v for k, v in want.items()):
            continue
        style = "-" if variant == DEFAULT_VARIANT else ":"
        mark = "^" if prec == "float32" else "o"
        lab = f"{backend}{'' if variant == 'default' else '/' + variant}{'' if prec == 'float32' else ' f64'}"
        n = [knob_value(r) for r in rows]
        mem = [memory(r)[0] for r in rows]
        a1.plot(n, [m / 2**20 if m else math.nan for m in mem], style + mark, color=colors.get(backend),
                ms=4, label=lab)
        a2.plot(n, [(throughput_s(r) or wall_s(r)) for r in rows], style + mark, color=colors.get(backend),
                ms=4, label=lab)
        floor = tape.state_bytes_per_step(prec)
        if floor and prec not in floor_done:
            floor_done.add(prec)
            a1.plot(n, [floor * items(r) * knob_value(r) / 2**20 for r in rows], "k" + ("--" if prec == "float32" else "-."),
                    lw=1, label=f"state per step x {label(scenario, 'horizon_items', 'items')} x {kname} ({prec})")
    shares: dict[tuple[str, str], dict[float, list[float]]] = {}
    extra = [k for k in varying(every, kname) if k not in ("batch",)]
    # a cell whose error exceeds its bound still returned a gradient: its FD agreement counts too
    # (dropping it would leave a horizon's mean to the frameworks that happened to pass)
    for r in gradient_cells(records, device, scenario):
        if (s := r.fd_agreement) is not None:
            key = (", ".join(f"{k}={need(r, 'params').get(k)}" for k in extra), r.precision)
            shares.setdefault(key, {}).setdefault(knob_value(r), []).append(s)
    for (what, prec), pts in sorted(shares.items()):
        n = sorted(pts)
        lo = [100 * min(pts[k]) for k in n]
        hi = [100 * max(pts[k]) for k in n]
        mid = [100 * sum(pts[k]) / len(pts[k]) for k in n]
        line, = a3.plot(n, mid, "-" if prec == "float32" else "--", marker="o", ms=4, label=f"{what} {prec}")
        a3.fill_between(n, lo, hi, color=line.get_color(), alpha=0.15)
    where = ", ".join(f"{k}={v}" for k, v in want.items())
    for ax in (a1, a2, a3):
        ax.set_xscale("log")
        ax.set_xlabel(f"{kname} (log)")
        ax.grid(True, which="both", alpha=0.3)
    a1.set_yscale("log"); a2.set_yscale("log")
    a1.set_ylabel(f"{'host' if device == 'cpu' else 'device'} memory above baseline [MiB] (log)")
    a1.set_title(f"memory against the horizon ({where}, {device})", fontsize=9)
    a2.set_ylabel("time per call, throughput regime [s] (log)")
    a2.set_title(f"time against the horizon ({where}, {device})", fontsize=9)
    a3.set_ylabel("gradients agreeing with float64 FD [%]")
    a3.set_ylim(-5, 105)
    a3.set_title("gradient quality: mean over backends, band = min..max", fontsize=9)
    place_legends([a1, a2, a3], fontsize=6, ncol=2)    # each clear of its data, else below its axes
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return True
