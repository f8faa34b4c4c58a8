"""Regenerate the small store the site tests build from (results.json, sweep.json, stress.json).

    python tests/data/site/make_store.py

Selects, without changing a byte of any record, a slice of the committed H100 store
(docs/results/h100/) that still has every framework and every kind of figure the site derives:
compare-all cells at the default sizes (both precisions, a few variants), the largest SAXPY and
particles cells, the batched projectile's batch-scaling sweep at three batch sizes, a few
error-sweep and horizon-sweep points, and one stress experiment (some of its records, all of its
analysis rows, its series and provenance). Each file keeps the ``runs`` entries whose command
could have produced a kept record (a resumed run appears with its resume: the store cannot tell
which of the two wrote a cell). Written as compact JSON (Store.read reads it; indented, the
three files would pass the 400 KB the tests' data may take). Rerunning reproduces them byte for
byte as long as the source store is unchanged.
"""
from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path
from typing import Any, Callable

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[2]
SOURCE = ROOT / "docs" / "results" / "h100"
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from compare.results.store import Store, jsonable  # noqa: E402
from compare.suites import formats  # noqa: E402

formats.register()      # the sweep's and stress suite's formats, as the command line's start-up does

Record = dict[str, Any]
# The size parameters of the compare-all cells (the scenarios' defaults when these were run);
# fixed here so a later change of a default does not change what this script selects.
DEFAULT_SIZE = {"saxpy": {"n": 1000000}, "sdf": {"width": 512, "height": 512},
                "particles": {"n": 256, "steps": 300, "dt": 0.01}, "projectile": {"batch": 1}}
LARGEST = {"saxpy": {"n": 268435456}, "particles": {"n": 16777216}}
IN_ALL = ("saxpy", "sdf", "particles", "projectile")
SCALING_BATCHES = (1, 1024, 1048576)
ERROR_DTS = (0.005,)                          # particles, float32: one point per backend
HORIZON_STEPS = (1000, 10000)                 # contact 'hard' (the memory figure's), default variant
STRESS_EXPERIMENTS = ("particles-dt",)
STRESS_RECORD_DTS = (0.02,)                   # the particles-dt setting whose float32 records are kept


def _size(r: Record, size: dict[str, Any]) -> bool:
    return all(r["params"].get(k) == v for k, v in size.items())


def keep_run(r: Record) -> bool:
    """Run-suite cells: compare-all at default sizes, and the largest SAXPY / particles."""
    sc, prec, var = r["scenario"], r["precision"], r["variant"]
    if sc in DEFAULT_SIZE and _size(r, DEFAULT_SIZE[sc]):
        if var == "default":          # float64 for SAXPY only: the 400 KB budget
            return prec == "float32" or sc == "saxpy"
        return sc == "saxpy" and var == "graph"
    if sc in LARGEST and _size(r, LARGEST[sc]):   # SAXPY's every variant, particles' default
        return prec == "float32" and (sc == "saxpy" or var == "default")
    return False


def keep_sweep(r: Record) -> bool:
    tags, p = r.get("tags") or {}, r["params"]
    kind, value = tags.get("sweep"), (tags.get("knob") or {}).get("value")
    if kind == "scaling":
        return r["scenario"] == "projectile" and value in SCALING_BATCHES
    if kind == "error":
        return (r["scenario"] == "particles" and r["precision"] == "float32"
                and r["variant"] == "default" and value in ERROR_DTS)
    if kind == "horizon":
        return r["variant"] == "default" and p.get("contact") == "hard" and value in HORIZON_STEPS
    return False


def keep_stress(r: Record) -> bool:
    p = r["params"]
    return (r["scenario"] == "particles" and r["precision"] == "float32" and p.get("n") == 256 and p.get("bounce") == 0.82
            and p.get("record_every") == 0 and p.get("dt") in STRESS_RECORD_DTS
            and abs(p["steps"] * p["dt"] - 3.0) < 1e-9)      # particles-dt: T = 3 s


# ---- which runs could have written a record ---------------------------------------------------
def _command(run: Record) -> tuple[list[str], dict[str, str], list[str]]:
    """(positional words after `python -m compare`, --option values, --set pairs)."""
    words = shlex.split(run.get("command") or "")
    if words[:3] == ["python", "-m", "compare"]:
        words = words[3:]
    pos, opts, sets = [], {}, []
    i = 0
    while i < len(words):
        w = words[i]
        if w.startswith("--"):
            name, eq, val = w[2:].partition("=")
            has_value = i + 1 < len(words) and not words[i + 1].startswith("--")
            if not eq and has_value:
                val, i = words[i + 1], i + 1
            if name == "set":
                sets += val.split(",")
            else:
                opts[name] = val
        else:
            pos.append(w)
        i += 1
    return pos, opts, sets


def _listed(opts: dict[str, str], name: str, value: str) -> bool:
    """An option naming a comma list (absent or 'all': every value)."""
    v = opts.get(name, "all")
    return v == "all" or value in v.split(",")


def could_write(run: Record, r: Record, suite: str) -> bool:
    pos, opts, sets = _command(run)
    if run.get("backends") and r["backend"] not in run["backends"]:
        return False
    if not (_listed(opts, "backends", r["backend"]) and _listed(opts, "devices", r["device"])
            and _listed(opts, "precision", r["precision"])):
        return False
    for pair in sets:                         # --set k=v: the record was run at that value
        k, _, v = pair.partition("=")
        if str(r["params"].get(k)) != v:
            return False
    if suite == "sweep":
        return (pos[:2] == ["sweep", (r.get("tags") or {}).get("sweep")]
                and _listed(opts, "scenarios", r["scenario"]))
    # the run suite: `all`, `run S...` or `S`, at the default size unless --set said otherwise
    variants = opts.get("variants", "default")           # the run suite's default: 'default' only
    if variants != "all" and r["variant"] not in variants.split(","):
        return False
    scen = list(IN_ALL) if pos[:1] == ["all"] else pos[1:] if pos[:1] == ["run"] else pos[:1]
    if r["scenario"] not in scen:
        return False
    return bool(sets) or _size(r, DEFAULT_SIZE.get(r["scenario"], {}))


def select(name: str, keep: Callable[[Record], bool]) -> Store:
    src = Store.read(SOURCE / name)
    records = [r for r in src.records if keep(r)]
    runs = src.runs if src.suite == "stress" else \
        [run for run in src.runs if any(could_write(run, r, src.suite) for r in records)]
    analysis: dict[str, Any] = {}
    if src.suite == "stress":                 # the kept experiments' findings, whole
        a = src.analysis
        analysis = {"provenance": {k: v for k, v in a["provenance"].items() if k in STRESS_EXPERIMENTS},
                    "rows": [row for row in a["rows"] if row["experiment"] in STRESS_EXPERIMENTS],
                    "series": {k: v for k, v in a["series"].items() if k in STRESS_EXPERIMENTS}}
    return Store(HERE / name, src.suite, runs, records, analysis)


def write(store: Store) -> int:
    # the exact document Store.save would write, without its indentation
    text = json.dumps(jsonable(json.loads(store.to_json())), separators=(",", ":")) + "\n"
    store.path.write_text(text)
    return len(text.encode())


def main() -> int:
    total = 0
    for name, keep in (("results.json", keep_run), ("sweep.json", keep_sweep), ("stress.json", keep_stress)):
        store = select(name, keep)
        size = write(store)
        total += size
        backends = sorted({r["backend"] for r in store.records})
        print(f"{name}: {len(store.records)} records, {len(store.runs)} runs, "
              f"{len(store.analysis.get('rows', []))} analysis rows, {size / 1000:.0f} kB; {', '.join(backends)}")
    print(f"total {total / 1000:.0f} kB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
