# CPU calibration of Scenario.footprint (docs/reliability.md): python docs/results/reliability/cpu-memory.py warp,numba,jax,taichi
# (cpu-memory.txt is this script's output at its first version; 2026-11-27: rewritten for typed cells and records)
import json
import sys

import scenarios
from compare.running import engine
from compare.spec import Cell

cases = [("saxpy", {"n": 1 << 22}), ("saxpy", {"n": 1 << 24}),
         ("sdf", {"width": 1024, "height": 1024}), ("sdf", {"width": 2048, "height": 2048}),
         ("particles", {"n": 1 << 18, "steps": 10}), ("particles", {"n": 1 << 20, "steps": 10}),
         ("particles", {"n": 1 << 16, "steps": 200, "record_every": 2}),
         ("projectile", {"steps": 10000, "iters": 1}), ("projectile", {"steps": 200000, "iters": 1}),
         ("copy", {"n": 1 << 24}), ("launch", {"n": 1 << 20})]
settings = {"repeat": 1, "min_time": 0.0, "cache": "warm"}
bes = sys.argv[1].split(",")
cells = [Cell.make(sc, b, "cpu", prec, params=p, **settings)
         for b in bes for prec in ("float32", "float64") for sc, p in cases]
base = {}
for b in bes:
    rec, _ = engine.run_cells([Cell.make("saxpy", b, "cpu", "float64", params={"n": 16}, **settings)], timeout=300)[0]
    base[b] = (rec.memory.peak_host_rss_bytes if rec.memory else None) or 0
out = []
for (rec, _), c in zip(engine.run_cells(cells, timeout=900), cells):
    peak = (rec.memory.peak_host_rss_bytes if rec.memory else None) or 0
    fp = scenarios.get(c.scenario).footprint(c.params, c.precision, "cpu")
    out.append(dict(b=c.backend, sc=c.scenario, params=c.params.__dict__, prec=c.precision, status=rec.status,
                    peak=peak, base=base[c.backend], fp=fp))
    print(c.backend, c.scenario, c.params, c.precision, rec.status, f"peak {peak / 2**20:.0f} base "
          f"{base[c.backend] / 2**20:.0f} data {(peak - base[c.backend]) / 2**20:.0f} fp {fp / 2**20:.0f} MiB", flush=True)
json.dump(out, open(f"/tmp/calib_{'_'.join(bes)}.json", "w"), default=str)
