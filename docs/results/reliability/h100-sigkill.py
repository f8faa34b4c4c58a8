"""A driver SIGKILLed while its CUDA worker hangs (after the cell ran: its CUDA context is live):
the worker must be gone within seconds, its temporary directory removed, the GPU process list
empty of it; a second driver on the same --out refused naming the PID; --resume takes over."""
import os, signal, subprocess, sys, time
from pathlib import Path

def procs(marker):
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                cmd = (d / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            except OSError:
                continue
            if "compare.running.worker" in cmd and marker in cmd:
                out.append(int(d.name))
    return out

def gpu_pids():
    p = subprocess.run(["nvidia-smi", "--query-compute-apps=pid", "--format=csv,noheader"], capture_output=True, text=True)
    return {int(x) for x in p.stdout.split() if x.strip().isdigit()}

for b in sys.argv[1].split(","):
    tmp, out = Path(f"/tmp/skt-{b}"), Path(f"/tmp/sko-{b}")
    tmp.mkdir(exist_ok=True)
    args = [sys.executable, "-m", "compare", "saxpy", "--quick", "--devices", "cuda", "--backends", b,
            "--precision", "float32", "--repeat", "1", "--min-time", "0", "--no-plots", "--out", str(out)]
    env = {**os.environ, "TMPDIR": str(tmp)}
    # (2026-11-27: the fault hook moved from the worker to the tests' backend `faulty`: rerun with
    # env COMPARE_BACKENDS_EXTRA=tests/extra_backends, COMPARE_FAULTY_WRAPS=b, COMPARE_FAULT=saxpy:hang
    # and --backends faulty)
    drv = subprocess.Popen(args, env={**env, "COMPARE_FAULT": f"saxpy/{b}:hang"}, stdout=subprocess.DEVNULL,
                           stderr=subprocess.PIPE, text=True)
    t0 = time.monotonic()
    w = []
    while time.monotonic() - t0 < 240:
        w = procs(str(tmp))
        if w and (set(w) & gpu_pids()):
            break
        if drv.poll() is not None:
            break
        time.sleep(0.5)
    on_gpu = bool(set(w) & gpu_pids())
    time.sleep(3)                          # the cell finishes and hangs with its context live
    second = subprocess.run(args, env=env, capture_output=True, text=True)
    drv.send_signal(signal.SIGKILL); drv.wait()
    t1 = time.monotonic()
    while (procs(str(tmp)) or list(tmp.iterdir()) or (set(w) & gpu_pids())) and time.monotonic() - t1 < 15:
        time.sleep(0.2)
    gone_after = time.monotonic() - t1
    again = subprocess.run([*args, "--resume"], env=env, capture_output=True, text=True)
    print(f"{b}: worker {w} seen on GPU {on_gpu}; second driver rc={second.returncode} "
          f"{second.stderr.strip()[-160:]!r}; after SIGKILL: workers {procs(str(tmp))}, temp {list(tmp.iterdir())}, "
          f"GPU pids of it {set(w) & gpu_pids()}, settled in {gone_after:.1f} s; --resume rc={again.returncode} "
          f"lock left {(out / '.compare.running.lock').exists()}", flush=True)
