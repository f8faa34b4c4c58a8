"""The CPU on a shared host: each framework's cells timed again while other processes keep cores
busy (``compare run --busy N``: a laptop or a CI runner is rarely idle), against the same cell
idle in the same run.

The row's figure is a framework's slowdown, the geometric mean over the four scenarios (defaults,
float32, default variant) of its busy latency over its idle latency; 1 means the busy core cost
nothing. The page explains each large slowdown from the records themselves: the cores the cell
used while idle (``time.noise.own_cores``): a loop split over every core waits for its slowest
thread, and with a core taken one thread waits for the other process.
"""
from __future__ import annotations

import math
from typing import Any, Literal

from compare.results.record import Record
from compare.site import data, fmt
from compare.site.matrix import IN_ALL, Cell
from compare.site.render import H, P, Table
from compare.spec import BUSY_TAG

LARGE = 2.0          # a slowdown the page explains
PARALLEL = 1.5       # cores used while idle above this: the cell runs a parallel loop


def _busy(r: Record) -> int:
    return int((r.tags or {}).get(BUSY_TAG) or 0)


def pairs(m: data.Machine, device: str = "cpu") -> list[tuple[Record, Record]]:
    """(idle, busy) records of one cell of the experiment, both of one run: at the defaults,
    float32, default variant, the four scenarios."""
    def ident(r: Record) -> tuple[Any, ...]:
        return (r.backend, r.scenario, (r.run or {}).get("created"))
    mine = [r for r in m.busy if (r.device, r.precision, r.variant) == (device, "float32", "default")
            and data.at_defaults(r) and r.scenario in IN_ALL]
    idle = {ident(r): r for r in mine if _busy(r) == 0}
    return [(idle[ident(b)], b) for b in mine if _busy(b) > 0 and ident(b) in idle]


def slowdown(idle: Record, busy: Record) -> float | None:
    a, b = data.timing(idle, "latency"), data.timing(busy, "latency")
    if idle.status != "ok" or busy.status != "ok" or a is None or b is None:
        return None
    return b.median / a.median


def pick(m: data.Machine, device: str) -> list[Record]:
    return [r for pair in pairs(m, device) for r in pair]


def cells(m: data.Machine, device: str) -> dict[str, Cell]:
    per: dict[str, dict[str, float | None]] = {}
    for idle, busy in pairs(m, device):
        per.setdefault(idle.backend, {})[idle.scenario] = slowdown(idle, busy)
    out = {}
    scen = {s for d in per.values() for s in d}
    for fw, got in per.items():
        vals = [v for v in got.values() if v is not None]
        if len(vals) != len(scen) or set(got) != scen:
            out[fw] = Cell(fw, None, status="absent", reason="not every scenario timed idle and busy")
            continue
        out[fw] = Cell(fw, math.exp(sum(math.log(v) for v in vals) / len(vals)), status="ok", variant="default")
    return out


def _cores(r: Record, key: Literal["own_cores", "others_cores"]) -> float | None:
    n = r.time.noise if r.time else None
    return data.num(None if n is None else n.own_cores if key == "own_cores" else n.others_cores)


def why(idle: Record, busy: Record) -> str:
    """A large slowdown in words, from the records: how many cores the cell used idle."""
    s = slowdown(idle, busy)
    own = _cores(idle, "own_cores")
    if s is None or s < LARGE:
        return ""
    if own is not None and own > PARALLEL:
        return (f"uses {own:.1f} cores when idle: a loop split over every core waits for its slowest "
                "thread, and one thread now shares its core with the busy process")
    return f"uses {own:.1f} core when idle: the host's scheduler gave it less than a core" if own is not None else ""


def section(m: data.Machine) -> list[Any]:
    got = pairs(m)
    if not got:
        return [H("CPU, one core busy"),
                P("No cells timed on a busy host in these records (`python -m compare all --devices cpu "
                  "--precision float32 --busy 1`).")]
    n = max(_busy(b) for _, b in got)
    rows = []
    for idle, busy in sorted(got, key=lambda p: (p[0].scenario, p[0].backend)):
        lat_i, lat_b = data.timing(idle, "latency"), data.timing(busy, "latency")
        s = slowdown(idle, busy)
        rows.append((idle.backend, idle.scenario, fmt.seconds(lat_i.median if lat_i else None),
                     fmt.seconds(lat_b.median if lat_b else None), f"{s:.3g}×" if s else "-",
                     f"{_cores(idle, 'own_cores'):.2f}" if _cores(idle, "own_cores") is not None else "-",
                     f"{_cores(busy, 'others_cores'):.2f}" if _cores(busy, "others_cores") is not None else "-",
                     why(idle, busy) or "-"))
    return [H("CPU, one core busy"),
            P(f"Each CPU cell at the defaults timed idle and again right after itself, in the same run, with {n} "
              f"core(s) of the {m.cpu_name()} kept busy by another process: the slowdown a user sees on a "
              "laptop or CI runner with other work on it. Latency regime; the large ones explained from "
              "the cores the cell used while idle."),
            Table(("framework", "scenario", "idle latency", "busy latency", "slowdown", "cores used idle",
                   "others' cores busy", "why"), tuple(rows))]
