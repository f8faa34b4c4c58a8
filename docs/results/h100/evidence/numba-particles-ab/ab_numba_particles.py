"""Numba's CUDA particle kernel before and after commit 02b6385 (one shared select-form step
function for CPU and CUDA), in one process on one GPU, interleaved: does the new source change
the kernel's time or only the host's launch path? Run in the project root as

    python docs/results/h100/evidence/numba-particles-ab/ab_numba_particles.py OLD_PARTICLES_PY OUT_JSON

OLD_PARTICLES_PY is `git show 02b6385~1:backends/numba/particles.py`. Per size and kernel: the
outputs against each other (bitwise), then ROUNDS alternating rounds of the latency regime
(call + synchronise) and the throughput regime (k calls, one synchronise) with the project's own
timing functions (compare/measuring/timing.py), a CUDA graph replay where the backend captures one, and a
host profile at the smallest size.
"""
from __future__ import annotations

import importlib.util
import json
import sys

import numpy as np

import backends
import scenarios
from compare.measuring import timing

SIZES = (256, 4096, 65536, 2**20, 2**24)
ROUNDS = 5


def load_old(path: str):
    spec = importlib.util.spec_from_file_location("backends.numba.particles_before_02b6385", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def main(old_path: str, out_path: str) -> None:
    be, sc = backends.get("numba"), scenarios.get("particles")
    be.setup("cuda", "float32", "default")
    be.ensure_context("cuda")
    from backends.numba import particles as new
    kernels = {"before": load_old(old_path), "after": new}
    sync = lambda r: be.synchronize("cuda", r)  # noqa: E731
    rows = []
    for n in SIZES:
        p = sc.params({"n": n})
        inp = sc.inputs(p, "float32")
        ks = {name: mod.Kernel(p, inp, "cuda", "float32", "default") for name, mod in kernels.items()}
        for k in ks.values():
            timing.call(k.run, sync)               # compile
        a, b = ks["before"].outputs(), ks["after"].outputs()
        same = all(np.array_equal(a[f], b[f]) for f in a)
        for r in range(ROUNDS):
            for name, k in ks.items():
                lat = timing.steady_state(k.run, sync, repeat=20, min_time=0.2)
                thr = timing.pipelined(k.run, sync)
                rows.append({"n": n, "kernel": name, "round": r, "bitwise_equal": same,
                             "latency_s": lat["wall"]["median_s"], "throughput_s": thr["median_s"],
                             "host_s": thr["host_s"], "k": thr["k"]})
        for name, k in ks.items():
            try:
                replay = be.capture("cuda", k.run)
                sync(None)
                rows.append({"n": n, "kernel": name, "graph_s": timing.pipelined(replay, sync)["median_s"]
                             if replay else None})
            except Exception as exc:    # the A/B stands without the graph figure
                rows.append({"n": n, "kernel": name, "graph_error": f"{type(exc).__name__}: {exc}"})
        if n == SIZES[0]:
            for name, k in ks.items():
                rows.append({"n": n, "kernel": name, "host_profile": timing.host_profile(k.run, sync, 2000, 12)})
        print(n, {name: np.median([r["throughput_s"] for r in rows if r.get("kernel") == name
                                   and r["n"] == n and "throughput_s" in r]) * 1e6 for name in ks}, "us", flush=True)
    with open(out_path, "w") as f:
        json.dump({"sizes": SIZES, "rounds": ROUNDS, "rows": rows}, f, indent=1, default=str)


if __name__ == "__main__":
    main(*sys.argv[1:3])
