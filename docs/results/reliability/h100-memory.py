"""Host peak RSS of CUDA cells (each in its own worker) against the memory preflight's estimate.
(h100-memory.txt is this script's output at its first version; 2026-11-27: rewritten for typed
cells and records: python docs/results/reliability/h100-memory.py warp,taichi,...)"""
import sys

from compare.planning import preflight
from compare.running import engine
from compare.spec import Cell

SIZES = {"saxpy": ({}, {"n": 1 << 24}), "sdf": ({}, {"width": 2048, "height": 2048}),
         "particles": ({}, {"n": 1 << 20, "steps": 10, "record_every": 5}),
         "projectile": ({}, {"steps": 100000, "iters": 1})}
backends = sys.argv[1].split(",")
cells = [Cell.make(sc, b, "cuda", prec, params=p, repeat=1, min_time=0.0, cache="warm", timer="wall")
         for b in backends for sc, sizes in SIZES.items() for p in sizes for prec in ("float32", "float64")]
probes = engine.availability(backends)
print({b: probes[b]["available"] for b in backends}, flush=True)
worst = None
for c, (rec, _) in zip(cells, engine.run_cells(cells, timeout=300, probes=probes, jobs=4)):
    peak = rec.memory.peak_host_rss_bytes if rec.memory else None
    est = preflight.cell_bytes(c)[0]
    ratio = est / peak if peak else None
    if ratio is not None and (worst is None or ratio < worst[0]):
        worst = (ratio, c.backend, c.scenario, c.params, c.precision)
    print(f"{c.backend:6s} {c.scenario:10s} {str(c.params):42s} {c.precision} {rec.status:8s} "
          f"peak {peak and peak / 2**20:8.0f} MiB  estimate {est / 2**20:7.0f} MiB  x{ratio and round(ratio, 2)} "
          f"{(rec.reason or '')[:80]}", flush=True)
print("lowest estimate/peak:", worst)
