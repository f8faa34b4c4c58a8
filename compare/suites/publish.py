"""Run what a machine's report needs, then build its site (``python -m compare publish``).

    compare publish --out DIR [--part NAME[,NAME...]] [--list] [--devices ...] [--backends ...]
                    [--timeout S] [--quick] [--budget S] [--allow-dirty] [--allow-noisy-sitting]

DIR is one machine's store, as docs/results/h100/ and cpu/ are: results.json, sweep.json,
stress.json, and the site in DIR/report/. The parts, in order (``--list`` prints each command):

  all             every scenario in 'all', float32, every variant, both timing regimes,
                  --host-profile, each cell in 6-10 interleaved processes (--processes auto)
                  whose set-ups run side by side, each cell timed alone (--overlap auto)
  float64         the same cells in float64, one process each (parity with the oracle)
  large-DEV-SCn   a kernel-dominated size, float32, the default variant and those that change how
                  a bandwidth-bound kernel is issued or loads memory (graph, vector, tile). CUDA:
                  saxpy n=2^26 and 2^28, particles 2^24 (as the H100 store). CPU: saxpy 2^24 and
                  2^26 (arrays of 64 MiB and more: far beyond the last-level cache, so DRAM-bound,
                  yet seconds per cell on 2 cores), particles 2^20 (the CPU scaling sweep's top n).
                  Sizes that do not fit the host's free memory (or the GPU's) are left out, said by
                  --list. Particles check 4096 sampled items (the float64 oracle of all: minutes).
  bandwidth, scaling, error, horizon       the sweeps (compare sweep KIND --resume)
  stress-EXPERIMENT    the stability suite, one experiment each (--only), into DIR/stress-parts/;
                  full where CUDA is in the plan, else --quick; ulps and races also on the CPU
  stress-merge    stress --merge of DIR/stress.json and DIR/stress-parts/*/stress.json into DIR
  site            compare site DIR --out DIR/report (compare.site.build([DIR], DIR/report))

The plan is CUDA's when --devices includes cuda (the default where nvidia-smi lists a GPU, else
cpu). ``--part`` takes names or the groups ``large`` and ``stress``.

Resuming. Every measuring part passes --resume: a rerun keeps the cells its store holds as ok,
mismatch or skipped and runs the rest (other plans' records stay, so large and default sizes
share results.json). Stress has no --resume (an experiment rerun replaces its rows for every
backend), so each experiment runs into its own folder (named with --backends unless all) and
``stress --merge`` carries them into DIR (newer files win per experiment, backend and device).
An experiment cut off twice in a row is not retried by a plain rerun: run it per backend with
``--part stress-E --backends B``. A part is done when its latest attempt with the same command
(--timeout aside) exited 0, or 1 (it ran to the end; the report marks its failed cells);
stress-merge and site when they ran after every part they read. A done part is skipped unless
--part names it.

Parts run one by one as subprocesses, not in-process through compare.cli.main: a driver that
crashes, exhausts memory or hangs in an import takes only its part down; each part starts with
clean process-global state (frameworks, matplotlib, test hooks) and exits with the subcommand's
own status; and --budget, Ctrl-C or SIGTERM can stop it (SIGINT, SIGKILL after a grace) while
publish logs the attempt. A failed part does not stop later ones. --budget S: after S seconds the running part
is interrupted (its finished cells are kept) and none starts; the same command continues (under
a 10-minute call limit, --budget 540 leaves time to copy DIR out).

A checkout with uncommitted changes is refused (exit 2) unless --allow-dirty: a published store
names the commit that measured it (each run keeps ``git_dirty_paths``). A copied tree whose .git
may be stale names its commit in COMPARE_GIT_COMMIT and that commit's tree in COMPARE_GIT_TREE,
which its files must match (its runs then say clean); with the commit alone it is taken on its
word (tree state unknown). A folder whose log names another machine (GPU models, else the CPU
model) is refused too: one store, one machine.

The sitting check (compare.measuring.sitting, compare.running.sitting_run; docs/measurement.md): before each measuring part
(not stress-merge, not site) publish checks the sitting (the launch floor and its spread, the copy,
host load, other GPU processes, throttling) against the quiet sittings of this machine kind in DIR
and docs/results/*/, and refuses a measurably worse one (exit 2, one line; after two more checks
30 s apart, so a host slow for a moment after the last part is not a refusal) unless
--allow-noisy-sitting; the part keeps the check as its run's sitting start, measures its end, and a
run let through is stamped noisy_sitting (its pages say "noisy sitting").

Exit: 0 every selected part done with 0; 1 some part ended with 1 or failed (rerun); 2 bad usage
(one line, nothing written); 3 stopped by --budget with parts left; 130 Ctrl-C.

DIR/publish.json, the progress log, and its format: compare/suites/publish_log.py.
"""
from __future__ import annotations

import argparse
import os
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Callable

import backends
from compare.measuring import environment
from compare import options
from compare.planning import outdir
from compare.suites.driver import Command, claim
from compare.options import EXIT_FAIL, EXIT_INTERRUPTED, EXIT_OK, UsageError
from compare.results.environment import machine
from compare.suites.publish_log import Entry, Log, host, load_log, other_machine, save_log, started, state
from compare.planning.publish_plan import GROUPS, Part, plan

LOCK = ".publish.lock"         # publish's own lock: each part locks DIR itself while it writes
EXIT_BUDGET = 3
GRACE_S, HEARTBEAT_S = 30.0, 60.0   # a driver saves and exits within seconds of SIGINT
def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help="the machine's store (the site goes to OUT/report)")
    p.add_argument("--part", default=None, metavar="NAME[,NAME...]",
                   help="run only these parts (or groups: large, stress), also when done")
    p.add_argument("--list", action="store_true", help="print the parts, commands, states; run nothing")
    p.add_argument("--devices", default=None, help="cpu, cuda or both (default: cuda if nvidia-smi lists a GPU)")
    p.add_argument("--backends", default="all", help="comma-separated backend names, or all")
    p.add_argument("--timeout", type=options.seconds, default=None, help="seconds before a cell is killed")
    p.add_argument("--quick", action="store_true", help="pass --quick to every part (small sizes: CI)")
    p.add_argument("--allow-dirty", action="store_true",
                   help="run from a checkout with uncommitted changes (its runs name the changed paths)")
    p.add_argument("--allow-noisy-sitting", action="store_true",
                   help="run parts in a sitting noisier than this machine kind's quiet ones (their runs say so)")
    p.add_argument("--budget", type=options.seconds, default=None, metavar="S",
                   help="stop after S seconds (the running part keeps its finished cells)")


def merge_argv(part: Part) -> tuple[str, ...] | None:
    """stress-merge's command with the files that exist now, oldest first (a newer file wins);
    None when no experiment has run."""
    i, j = part.argv.index("--merge"), part.argv.index("--out")
    staged = [str(f) for f in Path(part.argv[i + 2]).parent.parent.glob("*/stress.json")]   # DIR taken literally
    files = sorted([f for f in part.argv[i + 1:i + 2] if Path(f).is_file()] + staged, key=os.path.getmtime)
    return (*part.argv[:i + 1], *files, *part.argv[j:]) if staged else None


def select(parts: list[Part], spec: str | None) -> list[Part]:
    """The parts --part names (names or groups), in plan order; all without --part."""
    if spec is None:
        return parts
    names = options.no_duplicates([s.strip() for s in spec.split(",") if s.strip()], "--part")
    known = f"parts: {', '.join(p.name for p in parts)}; groups: {', '.join(GROUPS)}"
    if not names:
        raise UsageError(f"--part is empty ({known})")
    bad = [n for n in names if n not in GROUPS and n not in {p.name for p in parts}]
    if bad:
        raise UsageError(f"unknown part {bad[0]!r} ({known})")
    return [p for p in parts if p.name in names or any(p.name.startswith(g + "-") for g in names if g in GROUPS)]


# ---- running ------------------------------------------------------------------------------
def child_env() -> dict[str, str]:
    """This environment, with the tree on PYTHONPATH (a copied tree may not be installed)."""
    env = dict(os.environ)
    paths = [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p]
    if str(environment.ROOT) not in paths:
        env["PYTHONPATH"] = os.pathsep.join([str(environment.ROOT), *paths])
    return env


def stop(proc: subprocess.Popen, interrupt: bool = True) -> int:
    """Interrupt a part (SIGINT: its driver saves and exits); kill it after the grace."""
    if interrupt:
        proc.send_signal(signal.SIGINT)
    try:
        return proc.wait(timeout=GRACE_S)
    except subprocess.TimeoutExpired:
        proc.kill()
        return proc.wait()


# A noisy check is taken again before a part is refused: right after a heavy part a host can read
# a slow copy for a while (docs/results/cpu/evidence/session44), which a refusal would turn into
# an unattended publish stopped; a sitting still noisy after the rechecks is refused.
RECHECKS = 2
RECHECK_S = 30.0


def sitting_gate(devices: list[str], out: Path, allowed: bool) -> Callable[[], str]:
    """The check before each measuring part: what to hand the part (``sitting_run.ENV``), or a
    refusal of a sitting measurably worse than the kind's quiet ones in ``RECHECKS`` + 1 checks
    (unless ``allowed``: the first check is handed on, noisy or not)."""
    from compare.measuring import sitting, sitting_quiet
    from compare.running import sitting_run
    device = sitting_run.device_of(devices)
    learned: dict[str, sitting.Quiet | None] = {}

    def gate() -> str:
        for attempt in range(RECHECKS + 1):
            check = sitting_run.check_sitting(device)
            if "quiet" not in learned:       # the stores are read once
                learned["quiet"] = sitting_quiet.quiet_for(check, [out, *sitting_quiet.repository_stores()])
            quiet = learned["quiet"]
            why = sitting.judge(check, quiet)
            if not why or allowed or attempt == RECHECKS:
                break
            print(f"publish: sitting: {sitting.summary(check)}; noisy ({'; '.join(why)}): checking again in "
                  f"{RECHECK_S:.0f} s ({attempt + 1} of {RECHECKS})", flush=True)
            time.sleep(RECHECK_S)
        if why and not allowed:
            raise UsageError(f"a noisy sitting: {'; '.join(why)} (against "
                             f"{f'{quiet.runs} stored runs of {quiet.kind}' if quiet else 'the absolute limits'}; "
                             f"{RECHECKS + 1} checks {RECHECK_S:.0f} s apart); "
                             "wait or take another machine, or pass --allow-noisy-sitting (its runs then say so)")
        print(f"publish: sitting: {sitting.summary(check)}" + (f"; NOISY, let through: {'; '.join(why)}" if why else
                                                               "; quiet" if quiet else "; no quiet reference"),
              flush=True)
        return sitting_run.handed(check, why, quiet)
    return gate


def execute(argv: list[str], deadline: float | None, tick: Any, sitting: str | None = None) -> tuple[int, str | None]:
    """Run one part to its end; (exit code, None | 'budget' | 'interrupted'). ``sitting``: the
    check publish hands the part."""
    from compare.running.sitting_run import ENV
    env = child_env()
    env.pop(ENV, None)
    if sitting is not None:
        env[ENV] = sitting
    proc = subprocess.Popen([sys.executable, "-m", "compare", *argv], env=env)
    try:
        while True:
            left = HEARTBEAT_S if deadline is None else min(HEARTBEAT_S, deadline - time.monotonic())
            try:
                return proc.wait(timeout=max(0.0, left)), None
            except subprocess.TimeoutExpired:
                tick()
                if deadline is not None and time.monotonic() >= deadline:
                    return stop(proc), "budget"
    except KeyboardInterrupt:       # Ctrl-C reaches the part too; kill -INT/-TERM is passed on
        try:
            return proc.wait(timeout=2.0), "interrupted"
        except subprocess.TimeoutExpired:
            return stop(proc), "interrupted"


def catch_signals() -> None:
    """SIGINT and SIGTERM stop the running part cleanly, even where SIGINT came in ignored (as a
    background job of a non-interactive shell gets it, and Python then raises nothing)."""
    def interrupt(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, interrupt)


def run_parts(chosen: list[Part], forced: bool, out_s: str, out: Path, budget: float | None,
              gate: Callable[[], str] | None = None) -> int:
    """Run the chosen parts not done yet (all of them when ``forced``), logging every attempt;
    ``gate`` checks the sitting before each measuring part (``sitting_gate``)."""
    log = load_log(out)
    deadline = None if budget is None else time.monotonic() + budget
    who = host()
    for k, part in enumerate(chosen, 1):
        st = state(part, log, out_s)
        if not forced and st.startswith(("done", "given up")):
            print(f"publish: {part.name}: {st}, skipped", flush=True)
            continue
        if deadline is not None and time.monotonic() >= deadline:
            print(f"publish: --budget spent before {part.name}; run the same command again", file=sys.stderr)
            return EXIT_BUDGET
        argv = merge_argv(part) if part.name == "stress-merge" else part.argv
        if argv is None:
            print(f"publish: {part.name}: no stress experiment has run, nothing to merge", flush=True)
            continue
        handed = gate() if gate is not None and not part.reads else None     # may refuse (exit 2)
        print(f"publish: [{k}/{len(chosen)}] {part.name}: python -m compare {shlex.join(argv)}", flush=True)
        entry = Entry(name=part.name, argv=list(argv), started=started(), seconds=0.0, exit_code=None,
                      interrupted=False, host=who)
        log["parts"].append(entry)
        save_log(out, log)
        t0 = time.monotonic()

        def tick() -> None:          # a publish killed mid-part still shows the time spent
            entry["seconds"] = round(time.monotonic() - t0, 1)
            try:
                save_log(out, log)
            except OSError:
                pass
        code, why = execute(list(argv), deadline, tick, handed)
        entry["seconds"], entry["exit_code"] = round(time.monotonic() - t0, 1), code
        entry["interrupted"] = why is not None
        save_log(out, log)
        print(f"publish: {part.name}: exit {code} after {entry['seconds']:.0f} s", flush=True)
        if why is not None:
            print("interrupted" if why == "interrupted" else f"publish: --budget spent during {part.name} "
                  "(its finished cells are kept); run the same command again", file=sys.stderr)
            return EXIT_INTERRUPTED if why == "interrupted" else EXIT_BUDGET
    bad = [f"{p.name}: {st}" for p in chosen if (st := state(p, log, out_s)) != "done"]
    print("publish: " + ("every part done" if not bad else "; ".join(bad)), flush=True)
    return EXIT_FAIL if bad else EXIT_OK


def print_list(parts: list[Part], chosen: list[Part], log: Log, out_s: str,
               devices: list[str], notes: list[str]) -> None:
    print(f"publish {out_s} (devices: {','.join(devices)}; {len(parts)} parts, in this order):")
    for p in chosen:
        print(f"  {p.name}: {state(p, log, out_s)}")
        argv = (merge_argv(p) or p.argv) if p.name == "stress-merge" else p.argv
        print(f"      python -m compare {shlex.join(argv)}")
    for n in notes:
        print(f"  {n}")


def refuse_other_machine(out: str, log: Log) -> None:
    """A store is one machine's (its report compares like with like): a publish into a folder
    whose log names another machine is refused."""
    other = other_machine(log, host())
    if other is not None:
        raise UsageError(f"{out} holds runs of {other}, not of this machine ({machine(host())}): a store "
                         "holds one machine; publish into another --out")


def refuse_dirty(allowed: bool) -> None:
    """A published store names the commit that measured it: a checkout with uncommitted changes
    is refused unless allowed. A copied tree (its .git may be stale) names its commit
    (COMPARE_GIT_COMMIT) and that commit's tree (COMPARE_GIT_TREE), which its files must match;
    with the commit alone it is taken on its word (its runs say the tree state is unknown)."""
    if allowed:
        return
    if os.environ.get("COMPARE_GIT_COMMIT", "").strip():
        if environment.copy_dirty():
            raise UsageError("the copied tree's files differ from COMPARE_GIT_TREE (the tree of "
                             "COMPARE_GIT_COMMIT): copy a clean checkout of that commit, or pass --allow-dirty")
        return
    paths = environment.dirty_paths()
    if paths:
        more = f" and {len(paths) - 3} more" if len(paths) > 3 else ""
        raise UsageError(f"the checkout has uncommitted changes ({', '.join(paths[:3])}{more}): a published "
                         "store names the commit that measured it; commit them, or pass --allow-dirty "
                         "(the runs then name the changed paths)")


class Publish(Command):
    """publish: its arguments (``add_arguments``), then its run. It runs no cell itself (each part
    is a suite's own command, in a subprocess), so it shares the driver's claim and lock, not its
    cell sequence."""
    add_arguments = staticmethod(add_arguments)

    def run(self, args: argparse.Namespace, argv: list[str]) -> int:
        outdir.check_output(args.out)
        devices = (options.names(args.devices, backends.DEVICES, "devices") if args.devices is not None
                   else ["cuda"] if environment.gpus() else ["cpu"])
        parts, notes = plan(args.out, devices, args.backends, args.quick, args.timeout)
        chosen = select(parts, args.part)
        log = load_log(Path(args.out))            # a bad log refused before anything is written
        if args.list:
            print_list(parts, chosen, log, args.out, devices, notes)
            return EXIT_OK
        refuse_other_machine(args.out, log)
        refuse_dirty(args.allow_dirty)
        out, lock = claim(args, 0.0, lock_name=LOCK)
        catch_signals()
        with lock:
            return run_parts(chosen, args.part is not None, args.out, out, args.budget,
                             sitting_gate(devices, out, args.allow_noisy_sitting))


def run(args: argparse.Namespace, argv: list[str]) -> int:
    return Publish().run(args, argv)
