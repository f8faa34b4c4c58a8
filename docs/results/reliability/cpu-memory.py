# CPU calibration of Scenario.footprint (docs/reliability.md): python docs/results/reliability/cpu-memory.py warp,numba,jax,taichi
import json, sys, time
from compare.running import engine
import scenarios
cases = [("saxpy",{"n":1<<22}),("saxpy",{"n":1<<24}),
         ("sdf",{"width":1024,"height":1024}),("sdf",{"width":2048,"height":2048}),
         ("particles",{"n":1<<18,"steps":10}),("particles",{"n":1<<20,"steps":10}),
         ("particles",{"n":1<<16,"steps":200,"record_every":2}),
         ("projectile",{"steps":10000,"iters":1}),("projectile",{"steps":200000,"iters":1}),
         ("copy",{"n":1<<24}),("launch",{"n":1<<20})]
bes = sys.argv[1].split(",")
specs=[]
for b in bes:
    for prec in ("float32","float64"):
        for sc,p in cases:
            specs.append({"scenario":sc,"backend":b,"device":"cpu","precision":prec,"params":p,"repeat":1,"min_time":0.0,"cache":"warm"})
base = {}
for b in bes:
    r,_ = engine.run_cells([{"scenario":"saxpy","backend":b,"device":"cpu","precision":"float64","params":{"n":16},"repeat":1,"min_time":0.0,"cache":"warm"}], timeout=300)[0]
    base[b] = r["memory"]["peak_host_rss_bytes"]
res = engine.run_cells(specs, timeout=900)
out=[]
for (r,o),s in zip(res,specs):
    sc = scenarios.get(s["scenario"]); p = sc.params(s["params"])
    peak = r.get("memory",{}).get("peak_host_rss_bytes",0)
    fp = sc.footprint(p, s["precision"])
    out.append(dict(b=s["backend"],sc=s["scenario"],params=s["params"],prec=s["precision"],status=r["status"],peak=peak,base=base[s["backend"]],fp=fp))
    print(s["backend"], s["scenario"], s["params"], s["precision"], r["status"], f"peak {peak/2**20:.0f} base {base[s['backend']]/2**20:.0f} data {(peak-base[s['backend']])/2**20:.0f} fp {fp/2**20:.0f} MiB", flush=True)
json.dump(out, open(f"/tmp/calib_{'_'.join(bes)}.json","w"))
