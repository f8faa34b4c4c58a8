"""A run's environment, as a results file keeps it in ``runs`` (one per invocation that added
records): where and how it ran (``compare.measuring.environment.collect``) and what the suite
added (the backends' probes, the same-run yardstick, the cluster, the time its parts took).

The stored JSON object is this type itself (a ``TypedDict``): written as it is, read as it was,
so a file loaded and saved again is the same bytes (its keys in their order, a key this version
does not name kept). ``environment_of`` types an object as soon as the store has read it, after
``compare.results.records.RUN`` checked every field a reader formats or indexes.
"""
from __future__ import annotations

from collections import Counter
from typing import Any, Mapping, NotRequired, TypedDict, cast


class Gpu(TypedDict):
    """One GPU as ``nvidia-smi`` lists it."""
    name: str
    driver: str
    memory: str          # "81559 MiB"


class Yardstick(TypedDict, total=False):
    """A device's same-run yardstick (``compare.running.hardware.measure``), as a run's environment
    keeps it (``hardware``): the copy bandwidth (and, on CPU, its curve over sizes), the launch cost
    on CUDA, or ``error``."""
    copy_bytes_per_s: float
    copy_bytes: int
    copy_median_s: float
    copy_one_thread_bytes_per_s: float
    copy_threads: int
    copy_how: str
    copy_curve: list[list[float]]          # [bytes per array, bandwidth]
    launch_latency_s: float
    launch_latency_iqr_s: float            # the spread of the synchronised launches (the sitting check)
    launch_pipelined_s: float
    launch_how: str
    gpu: str
    sm_clock_max_hz: float
    nvml_error: str
    peak_flops: dict[str, float | str]     # per precision, and its source
    error: str


class Probe(TypedDict):
    """What probing one backend found (``compare.running.cells.probe``): per device None (usable)
    or why not, and its packages' versions."""
    available: dict[str, str | None]
    versions: dict[str, str]


class Scheduler(TypedDict, total=False):
    """The cluster a run's cells ran on (``--scheduler``): its address and placement
    (``compare.running.scaleout.placement``)."""
    address: str
    workers: int
    gpu_workers: int
    mode: str
    worker_names: list[str]


class Phases(TypedDict, total=False):
    """Where a run's time went (``compare.measuring.phases``): the driver's parts, the cells' parts."""
    run: dict[str, float]
    cells: dict[str, float]


class QuietSittings(TypedDict):
    """The quiet sittings of a machine kind (``compare.measuring.sitting.Quiet``): the best quartile
    of its stored runs' launch floors and copy, and how many runs."""
    kind: str
    runs: int
    launch_latency_s: float | None
    launch_pipelined_s: float | None
    copy_bytes_per_s: float | None


class Sitting(TypedDict, total=False):
    """A run's sitting checks (``compare.running.sitting_run``): each a ``SittingCheck``'s JSON."""
    start: dict[str, Any]
    end: dict[str, Any]
    quiet: QuietSittings | None     # the reference the start was judged against (None: none)


class RunEnvironment(TypedDict, total=False):
    """One entry of a results file's ``runs``. ``collect`` gives the first fields (``git_dirty``
    None: a copied tree, dirtiness not known); a suite adds the rest. A merged report's entry
    (``compare report``) is only ``merged_from`` and the ``environments`` it merged."""
    created: str | None                 # ISO time the run started (UTC)
    hostname: str | None
    os: str | None
    cpu: str | None
    cpu_id: str                         # family, model, stepping ('' where not known)
    cores: int | None                   # usable by this process
    memory_gib: float | None
    gpus: list[Gpu]
    cuda_toolkit: str | None
    python: str | None
    packages: dict[str, str]            # distribution -> version
    git_commit: str | None
    git_dirty: bool | None
    git_dirty_paths: list[str]
    git_note: str | None                # why dirtiness is not known (written by hand)
    command: str | None
    backends: Mapping[str, Probe] | None      # what probing each backend found
    overlap: int                        # cells run ahead (--overlap)
    overlap_beside: bool                # their host work ran beside GPU cells' windows
    processes: int                      # worker processes per cell (--processes)
    sitting_s: float                    # --sitting: rounds past the fewest only within it
    kinds: list[str] | None             # a sweep's kinds
    hardware: dict[str, Yardstick] | None     # device -> its same-run yardstick
    sitting: Sitting                    # the sitting checks at its start and (publish) end
    noisy_sitting: bool                 # publish ran it in a noisy sitting (--allow-noisy-sitting)
    noisy_sitting_reasons: list[str]
    scheduler: Scheduler | None
    phases: Phases
    seed: int
    provenance_note: str
    rerun_of: str
    merged_from: list[str]              # the files a merge read
    environments: list[RunEnvironment] | None     # a merged report's runs


class Host(TypedDict):
    """The machine a publish part ran on (``compare.suites.publish_log``)."""
    hostname: str
    cpu: str
    cpu_id: NotRequired[str]            # family, model, stepping (publish logs since 2026-12-02)
    cores: int
    gpus: list[Gpu]


class PublishEntry(TypedDict):
    """One attempt of a publish part, as DIR/publish.json keeps it (``exit_code`` None: still
    running, or killed); an older entry may lack a key (read with get)."""
    name: str
    argv: list[str]
    started: str
    seconds: float
    exit_code: int | None
    interrupted: bool
    host: Host


class PublishLog(TypedDict):
    """DIR/publish.json (``compare publish``): every attempt of every part, in order."""
    format_version: int
    parts: list[PublishEntry]


def environment_of(obj: Mapping[str, object]) -> RunEnvironment:    # a stored run, checked
    """A stored ``runs`` entry as the environment it is (the object itself: its key order and the
    keys this version does not name kept); the store checked it (``records.RUN``) first."""
    return cast(RunEnvironment, obj)


__all__ = ["Gpu", "Host", "Phases", "Probe", "PublishEntry", "PublishLog", "RunEnvironment", "Scheduler", "Sitting",
           "Yardstick",
           "environment_of", "machine", "same_machine", "tree_state"]


def tree_state(dirty: object) -> str:
    """A run's checkout in words, as every page says it (``git_dirty``): '' for a commit's clean
    tree, else 'dirty tree' (uncommitted changes) or 'tree state unknown' (not recorded, or a
    copied tree whose files were not checked)."""
    if dirty is False:
        return ""
    return "dirty tree" if dirty else "tree state unknown"


def machine(h: Mapping[str, Any]) -> str:
    """A host as the machine kind a store holds: its GPUs' models (with their count) where it
    has GPUs, else its CPU model, with the family, model and stepping where the run recorded them."""
    gpus = Counter(str(g.get("name")) for g in h.get("gpus") or [])
    if gpus:
        return " + ".join(f"{n} x{k}" if k > 1 else n for n, k in sorted(gpus.items()))
    return str(h.get("cpu") or "?") + (f" ({h['cpu_id']})" if h.get("cpu_id") else "")


def same_machine(a: Mapping[str, Any], b: Mapping[str, Any]) -> bool:
    """Whether two hosts are one machine kind: the same ``machine``, or, where one of them did not
    record its processor's family and model (runs before 2026-12-02), the same CPU model name."""
    if machine(a) == machine(b):
        return True
    return not (a.get("cpu_id") and b.get("cpu_id")) and machine({**a, "cpu_id": ""}) == machine({**b, "cpu_id": ""})
