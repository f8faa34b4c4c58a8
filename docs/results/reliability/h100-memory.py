"""Host peak RSS of CUDA cells (each in its own worker) against the run suite's estimate."""
import sys
from compare.running import engine
from compare.suites import run as run_suite
SIZES = {"saxpy": ({}, {"n": 1 << 24}), "sdf": ({}, {"width": 2048, "height": 2048}),
         "particles": ({}, {"n": 1 << 20, "steps": 10, "record_every": 5}),
         "projectile": ({}, {"steps": 100000, "iters": 1})}
backends = sys.argv[1].split(",")
specs = [{"scenario": sc, "backend": b, "device": "cuda", "precision": prec, "params": p, "repeat": 1,
          "min_time": 0.0, "cache": "warm", "timer": "wall"}
         for b in backends for sc, sizes in SIZES.items() for p in sizes for prec in ("float32", "float64")]
probes = engine.availability(backends)
print({b: probes[b]["available"] for b in backends}, flush=True)
res = engine.run_cells(specs, timeout=300, probes=probes, jobs=4)
worst = None
for s, (r, _) in zip(specs, res):
    peak = (r.get("memory") or {}).get("peak_host_rss_bytes")
    est = run_suite.cell_bytes(s)[0]
    ratio = est / peak if peak else None
    if ratio is not None and (worst is None or ratio < worst[0]):
        worst = (ratio, s["backend"], s["scenario"], s["params"], s["precision"])
    print(f"{s['backend']:6s} {s['scenario']:10s} {str(s['params']):42s} {s['precision']} {r['status']:8s} "
          f"peak {peak and peak / 2**20:8.0f} MiB  estimate {est / 2**20:7.0f} MiB  x{ratio and round(ratio, 2)} "
          f"{r.get('reason', '')[:80]}", flush=True)
print("lowest estimate/peak:", worst)
