"""A memory row's cells beside what their ports' designs predict (the gradients page, issue 56).

Measured: ``memory.device_bytes`` (compare/measuring/nvml.py), the process's NVML device memory
above the framework's context at its peak, the largest of a sampling thread's readings (every 2 ms
through the first call and an untimed memory pass: ``compare.measuring.memory_sampler``) and of
the milestone samples; records made before the sampling thread have the milestones alone, and the
table says which figure each cell shows. Beside it: the framework's own high-water mark where the
backend reports one (``memory.device_peak_bytes``), and the bytes the port's design predicts,
``info.design_bytes`` (named byte counts: states kept x batch x bytes, adstacks or per-thread
storage, the descent history), summed; "—" where the port gives none.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from compare.results.record import Record
from compare.site import data, fmt
from compare.site.render import Block, P, Table

NONE = "—"       # a port that predicts nothing, or a figure not measured

WHAT_IS_MEASURED = (
    "Device memory above the framework's CUDA context: this process's NVML figure at its peak, "
    "sampled every 2 ms through the first call and an untimed pass of calls after the timed regimes "
    "(never during them), and read after set-up, the first call and each timing regime; the largest "
    "of these. Records measured before the sampling thread have the milestone readings alone "
    "(a call's transient peak may fall between them); the table under the memory row says which "
    "figure each cell shows.")


def memory_of(r: Record) -> Mapping[str, Any]:
    return r.memory.to_json() if r.memory else {}


def design_bytes(r: Record) -> dict[str, float] | None:
    """The port's predicted bytes by name (``info.design_bytes``), or None where it gives none."""
    got = (r.info or {}).get("design_bytes")
    if isinstance(got, (int, float)) and not isinstance(got, bool) and got > 0:
        return {"total": float(got)}          # a port that gives one sum (Warp)
    if not isinstance(got, Mapping):
        return None
    parts = {str(k): v for k, v in got.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}
    return parts or None


def predicted(r: Record) -> float | None:
    parts = design_bytes(r)
    return float(sum(parts.values())) if parts else None


def shown(r: Record) -> str:
    """Which figure ``device_bytes`` is: the sampled peak, or the milestones alone."""
    m = memory_of(r)
    if data.num(m.get("device_bytes")) is None:
        return NONE
    sampled, milestones = data.num(m.get("device_bytes_sampled")), data.num(m.get("device_bytes_milestones"))
    if sampled is None:
        return "milestones only (no sampling thread)"
    if milestones is not None and milestones > sampled:
        return "a milestone (above every sample)"
    return f"sampled peak (milestones: {fmt.nbytes(milestones)})"


def row(r: Record, reference: Callable[[Record], bool]) -> tuple[str, ...]:
    m = memory_of(r)
    measured, want = data.device_bytes(r), predicted(r)
    own = data.num(m.get("device_peak_bytes"))
    parts = design_bytes(r)
    ratio = f"{measured / want:.2f}×" if measured is not None and want else NONE
    name = r.backend + (" ✎" if reference(r) else "")
    return (name, r.variant, fmt.nbytes(measured) if measured is not None else NONE, shown(r),
            fmt.nbytes(own) if own is not None else NONE, fmt.nbytes(want) if want is not None else NONE,
            ratio, ", ".join(f"{k} {fmt.nbytes(v)}" for k, v in parts.items()) if parts else NONE)


def table(records: list[Record], reference: Callable[[Record], bool]) -> list[Block]:
    """The memory row's cells, measured beside predicted; nothing where no cell has a device figure."""
    cells = [r for r in records if r.status in ("ok", "mismatch") and data.device_bytes(r) is not None]
    if not cells:
        return []
    cells.sort(key=lambda r: (reference(r), data.device_bytes(r) or 0.0, r.backend, r.variant))
    return [P("Measured against designed: each cell's device-memory peak (" + WHAT_IS_MEASURED[0].lower()
              + WHAT_IS_MEASURED[1:] + "), the framework's own high-water mark where it reports one, "
              "and the bytes the port's design keeps (its info's design_bytes: inputs, the loss history "
              "of the descent, states kept per trajectory, adstacks; the parts are listed), summed. "
              "What the design does not name (a framework's pools and caches, per-thread storage the "
              "driver reserves for resident threads, its kernels) is the difference; " + NONE
              + " where the port predicts nothing. ✎ marks a hand-written adjoint."),
            Table(("framework", "variant", "measured", "which figure", "framework's own peak", "predicted",
                   "measured / predicted", "predicted parts"),
                  tuple(row(r, reference) for r in cells))]
