"""This run against the stored report of the closest machine kind, at the end of ``compare all | run``.

The reference is the published store of the machine kind nearest this one: ``docs/results/h200``
where an H200 is visible and that report is stored, ``docs/results/h100`` for any other NVIDIA GPU
(an H200's figures are not an H100's), ``docs/results/cpu`` otherwise (``--against DIR`` names another,
``--against none`` turns it off). Cells are matched as ``compare site --against`` matches them
(``compare.site.against.match``: same scenario, framework, device, precision, variant and
parameters); per matched cell one regime (the throughput regime where both measured it, else
the one they share), per device and scenario the median ratio this run / reference and the
quartiles of the ratios. The block names the reference, how far the two machines differ before
any framework (copy bandwidth, launch latency, cores) and ``<out>/against.md``, the details
from the same match (no site build: no figures).
"""
from __future__ import annotations

import os
import re
import statistics
import textwrap
from pathlib import Path
from typing import Any

from compare.options import UsageError
from compare.results.environment import RunEnvironment, Yardstick
from compare.results.record import Record

# the stored reports, one folder per machine kind (a test points this at its own)
REFERENCES = Path(__file__).resolve().parents[2] / "docs" / "results"
KINDS = {"cpu": "CPU", "h100": "H100", "h200": "H200"}
PAGE = "against.md"
PREFERRED = ("throughput", "latency", "graph")      # the regime a cell's ratio is taken from


def chosen(against: str | None, env: RunEnvironment) -> tuple[str, Path] | None:
    """(words naming the reference, its folder); None for ``--against none``."""
    if against is not None and against.strip().lower() == "none":
        return None
    if against is not None:
        return f"the report in {against}", Path(against)
    kind = _kind(env.get("gpus") or [])
    return f"the {KINDS[kind]} report ({_shown(REFERENCES / kind)})", REFERENCES / kind


def _kind(gpus: list[Any]) -> str:
    """The stored report of the closest kind to a run on ``gpus`` (what nvidia-smi lists): its
    GPU's own where stored, else the H100's; no GPU: the CPU's."""
    if not gpus:
        return "cpu"
    names = " ".join(str(g.get("name", "")) if isinstance(g, dict) else str(g) for g in gpus).upper()
    own = next((k for k in KINDS if k != "cpu" and re.search(rf"\b{k.upper()}\b", names)), "h100")  # not GH200
    return own if (REFERENCES / own / "results.json").is_file() else "h100"


def check(against: str | None) -> None:
    """A named reference that holds no run results is refused before anything runs."""
    if against is None or against.strip().lower() == "none":
        return
    if not against.strip():
        raise UsageError("--against is empty (give a results folder, or none)")
    given = Path(against)
    if not ((given / "results.json").is_file() or (given.name == "results.json" and given.is_file())):
        raise UsageError(f"--against {against}: no results.json there (give a results folder, or none)")


def _shown(p: Path) -> str:
    try:
        rel = os.path.relpath(p)
    except ValueError:
        return str(p)
    return rel if not rel.startswith("..") else str(p)


def _ratio(r: float) -> str:
    from compare.site import fmt
    return fmt.ratio(r)


def _figure(env: RunEnvironment, device: str, name: str) -> object:
    """The copy bandwidth (``name`` 'copy') or launch latency of a run's yardstick of ``device``."""
    hw: Yardstick = (env.get("hardware") or {}).get(device) or {}
    return hw.get("copy_bytes_per_s") if name == "copy" else hw.get("launch_latency_s")


def _hardware(env: RunEnvironment, ref_runs: tuple[RunEnvironment, ...], devices: list[str]) -> str:
    """The two machines before any framework: copy bandwidth and launch latency per device (this
    run's yardstick against the median of the reference runs' that timed the matched cells),
    and cores."""
    parts = []
    for dev in devices:
        for name, unit in (("copy", "GB/s"), ("launch", "µs")):
            a = _figure(env, dev, name)
            bs = [v for e in ref_runs if isinstance(v := _figure(e, dev, name), (int, float))]
            if not isinstance(a, (int, float)) or not bs or not a:
                continue
            b = statistics.median(bs)
            scale = 1e-9 if unit == "GB/s" else 1e6
            parts.append(f"{dev} {name} {a * scale:.3g} {unit} here, {b * scale:.3g} {unit} there ({_ratio(a / b)})")
    cores = sorted({int(c) for e in ref_runs if isinstance(c := e.get("cores"), int)})
    if isinstance(env.get("cores"), int) and cores:
        parts.append(f"cores {env['cores']} on both" if cores == [env["cores"]]
                     else f"cores {env['cores']} here, {'/'.join(map(str, cores))} there")
    return "; ".join(parts)


def _quartiles(xs: list[float]) -> tuple[float, float, float]:
    if len(xs) < 2:
        return xs[0], xs[0], xs[0]
    q1, q2, q3 = statistics.quantiles(xs, n=4, method="inclusive")
    return q1, q2, q3


def block(records: list[Record], env: RunEnvironment, out: Path, against: str | None = None,
          quick: bool = False) -> list[str]:
    """The closing block (several lines, or one where nothing compares); writes ``out/against.md``
    when some cell matched."""
    pick = chosen(against, env)
    if pick is None:
        return []
    label, ref_dir = pick
    if ref_dir.name == "results.json":
        ref_dir = ref_dir.parent
    if ref_dir.resolve() == Path(out).resolve():
        return [f"against {label}: this run's --out is that report itself; nothing to compare"]
    if not (ref_dir / "results.json").is_file():
        return [f"against {label}: no stored report there (no results.json)"]
    from compare.site import against as vs, data, floors
    from compare.results.store import StoreError
    try:
        ref = data.load([ref_dir / "results.json"])
    except StoreError as exc:
        return [f"against {label}: cannot read it ({exc})"]
    mine = data.Machine((Path(out) / "results.json",), tuple(records), (), None, (env,), None)
    mm = vs.match(mine, ref)
    per: dict[int, Any] = {}                    # one regime per cell
    for c in mm.compared:
        if id(c.rec) not in per or PREFERRED.index(c.regime) < PREFERRED.index(per[id(c.rec)].regime):
            per[id(c.rec)] = c
    if not per:
        why = " (the reference ran the default sizes; --quick never matches)" if quick else ""
        return [f"against {label}: no timed cell of this run matches one of its {len(ref.run)} "
                f"(same scenario, framework, device, precision, variant and parameters){why}"]
    groups: dict[tuple[str, str], list[Any]] = {}
    for c in per.values():
        groups.setdefault((c.rec.device, c.rec.scenario), []).append(c)
    devices = sorted({d for d, _ in groups}, key=lambda d: (d != "cuda", d))
    noisy = sum(bool(c.mine.noisy) for c in per.values())
    lines = [f"This run against {label}: {ref.name()}; {len(per)} timed cells matched"
             + (f" ({noisy} noisy here ~)." if noisy else "."),
             f"  ratio = per-call time here / there (below 1: faster here), median and quartiles; every cell: "
             f"{_shown(Path(out) / PAGE)}"]
    if any(c.floor_ratio is not None for c in per.values()):
        lines.append(f"  'in floors': the same ratio {vs.FLOORS} (the raw ratio beside it moves with the sitting)"
                     + floors.note(per.values()))
    for (dev, scenario), cs in sorted(groups.items(), key=lambda kv: (devices.index(kv[0][0]), kv[0][1])):
        q1, q2, q3 = _quartiles(sorted(c.ratio for c in cs))
        within = sum(c.verdict == vs.WITHIN for c in cs)
        fl = [f for c in cs if (f := c.floor_ratio) is not None]
        lines.append(f"    {scenario:<11} {dev:<5} {_ratio(q2):>7}  (quartiles {_ratio(q1)} – {_ratio(q3)}; "
                     f"{len(cs)} cells, {within} within both runs' spread"
                     + (f"; {_ratio(statistics.median(fl))} in floors, {len(fl)} cells)" if fl else ")"))
    # the yardstick of the reference runs that timed the matched cells (a store's runs may span hosts)
    stamps = {(c.there.run or {}).get("created") for c in per.values() if c.there is not None}
    ref_runs = tuple(e for e in ref.runs if e.get("created") in stamps) or ref.runs
    hw = [got] if (got := _hardware(env, ref_runs, devices)) else []
    loads = [vs.host_load(x) for x in (mine, ref)]        # a busy host slows every cell alike
    if all(v is not None for v in loads):
        hw.append(f"host load {loads[0]:.1f} here, {loads[1]:.1f} there")
    if hw:
        lines += textwrap.wrap(f"  the machines: {'; '.join(hw)}", 118, subsequent_indent="    ")
    write_page(Path(out) / PAGE, label, mine, ref, mm)
    return lines


def write_page(path: Path, label: str, mine: Any, ref: Any, mm: Any) -> None:
    """``against.md``: the site's --against page from the same match, without its figure."""
    from compare.site import against as vs
    from compare.site.render import H, P, block_md
    from compare.results.store import atomic_write
    yard = vs.yardstick_line(mine, ref, sorted({x.rec.device for x in mm.compared}))
    blocks = [P(f"This run ({_shown(path.parent)}) against {label}: {ref.name()}. Ratio = this run's "
                "per-call time / the reference's: below 1, faster here. The full page, with a figure: "
                f"`{vs.COMMAND}`."),
              H("Summary", "summary"), *vs.summary(mm), *([P(yard)] if yard else []), *vs.tables(mm), *vs.environments(mine, ref)]
    atomic_write(path, "\n\n".join(["# This run against the reference", *map(block_md, blocks)]) + "\n")


__all__ = ["REFERENCES", "block", "check", "chosen", "write_page"]
