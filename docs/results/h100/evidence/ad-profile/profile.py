"""Profile one steady-state run of the batched projectile under Nsight Compute (issue 15's
'measured reason'): python profile.py BACKEND [BATCH]. The kernel is built and run once (compile,
warm caches) outside the profiled range; the second run() is bracketed by cuProfilerStart/Stop on
the CUDA primary context, so `ncu --profile-from-start off` sees exactly one run's kernels."""
import ctypes
import sys

import backends
import scenarios

name, batch = sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 1 << 18
sc = scenarios.get("projectile")
params = sc.params({"batch": batch, "contact": "hard", "iters": 20})
be = backends.get(name)
be.setup("cuda", "float32", "default")
be.ensure_context("cuda")
k = be.kernel("projectile")(params, sc.inputs(params, "float32"), "cuda", "float32", "default")
be.synchronize("cuda", k.run())
be.synchronize("cuda", k.run())
cu = ctypes.CDLL("libcuda.so.1")
ctx = ctypes.c_void_p()
cu.cuDevicePrimaryCtxRetain(ctypes.byref(ctx), 0)
cu.cuCtxSetCurrent(ctx)
cu.cuProfilerStart()
be.synchronize("cuda", k.run())
cu.cuProfilerStop()
print(f"{name}: profiled one run at batch {batch}")
