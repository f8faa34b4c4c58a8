"""Why does our clock read PyTorch's SAXPY call (n = 10^6, float32, CUDA) up to 18 % above
torch.utils.benchmark.Timer's, alternated in one process? (issue 43, its 15 % check.)
Each round times the same call + synchronise several ways, back to back, ROUNDS times:
  timer       torch.utils.benchmark.Timer(stmt="call()").blocked_autorange(0.2): its median of block means
  timer_raw   the same with the statement written out (no closure), plain torch.cuda.synchronize()
  ours        compare.measuring.timing.until(call, 10, 0.05, ...): the median of per-call wall clocks (our latency)
  ours_0.2    the same for 0.2 s, as long as the Timer's stretch
  ours_nogc   the same with the garbage collector off (timeit, under the Timer, turns it off)
  block       one clock pair around 1000 calls, the mean (the Timer's way, without the Timer)
and the synchronise alone three ways (the null call). Prints one JSON line per round, then medians.
Run from the repository root on the GPU machine: python docs/results/h100/evidence/session18-owntimer/probe.py"""
import gc
import json
import statistics
import sys
import time

import torch
from torch.utils import benchmark

sys.path.insert(0, ".")
import backends  # noqa: E402
import scenarios  # noqa: E402
from compare.measuring import timing  # noqa: E402
from scenarios.base import Precision  # noqa: E402

ROUNDS = 10
sc, be = scenarios.get("saxpy"), backends.get("torch")
params = sc.params({})
inputs = sc.inputs(params, Precision.FLOAT32)
be.setup("cuda", Precision.FLOAT32, "default")
be.ensure_context("cuda")
kernel = be.kernel("saxpy")(params, inputs, "cuda", Precision.FLOAT32, "default")
run = kernel.run
sync = lambda r: be.synchronize("cuda", r)  # noqa: E731
call = lambda: sync(run())  # noqa: E731
x, y, out, alpha = kernel.x, kernel.y, kernel.out, kernel.alpha
dev = torch.device("cuda", 0)
for _ in range(200):
    call()


def ours(min_time: float) -> list[float]:
    return timing.until(lambda: timing.call(run, sync), 10, min_time, 1.0, 100_000)


def block(k: int = 1000) -> float:
    t0 = time.perf_counter()
    for _ in range(k):
        sync(run())
    return (time.perf_counter() - t0) / k


def null(s) -> float:
    return statistics.median(timing.call(lambda: None, s) for _ in range(2000))


rows = []
for r in range(ROUNDS):
    row = {"round": r}
    row["timer"] = benchmark.Timer(stmt="call()", globals={"call": call}).blocked_autorange(min_run_time=0.2).median
    row["timer_raw"] = benchmark.Timer(
        stmt="torch.add(y, x, alpha=alpha, out=out); torch.cuda.synchronize()",
        globals={"torch": torch, "x": x, "y": y, "out": out, "alpha": alpha}).blocked_autorange(min_run_time=0.2).median
    o = ours(0.05)
    row["ours"] = statistics.median(o)
    row["ours_p10"], row["ours_p90"] = (statistics.quantiles(o, n=10)[i] for i in (0, 8))
    row["ours_n"] = len(o)
    row["ours_0.2"] = statistics.median(ours(0.2))
    gc.disable()
    row["ours_nogc"] = statistics.median(ours(0.2))
    gc.enable()
    row["block"] = block()
    row["null_port"] = null(sync)
    row["null_plain"] = null(lambda r: torch.cuda.synchronize())
    row["null_stream"] = null(lambda r: torch.cuda.current_stream().synchronize())
    rows.append(row)
    print(json.dumps({k: (round(v * 1e6, 2) if isinstance(v, float) else v) for k, v in row.items()}), flush=True)
print("medians (us):", json.dumps({k: round(statistics.median(r[k] for r in rows) * 1e6, 2)
                                   for k in rows[0] if k not in ("round", "ours_n")}))
print("torch", torch.__version__, torch.cuda.get_device_name(0))
