"""The quiet sittings of a machine kind, learned from the stored runs (``compare.measuring.sitting``).

Every run entry of a store (``runs`` of DIR/results.json, sweep.json, stress.json, and a merged
entry's ``environments``; the stores of DIR/sittings/<label>/ too) keeps its same-run yardstick
(``hardware``); the runs of one machine kind (the same GPU name on CUDA; on the CPU the same
model, family/model/stepping and core count: one model name, "AMD EPYC", stands for hosts whose
copies differ by 2x, and the multi-threaded copy scales with the cores) are its sittings. The quiet ones are the best quartile
(``QUIET_QUANTILE``) of each figure: the lowest launch floors, the highest copy. A kind with
fewer than ``MIN_RUNS`` stored yardsticks has no quiet reference (only the absolute checks apply).
Runs stamped ``noisy_sitting`` are left out.
"""
from __future__ import annotations

import functools
import json
from pathlib import Path
from typing import Any, Iterable, Iterator, Mapping

import numpy as np

from compare.measuring.sitting import Quiet, SittingCheck

QUIET_QUANTILE = 0.25     # the quiet sittings: the best quarter of the stored runs' figures
MIN_RUNS = 4              # fewer stored yardsticks of the kind: no quiet reference
FILES = ("results.json", "sweep.json", "stress.json")


UNRECORDED = "processor not recorded"


def kind_of(device: str, gpu: object, cpu: object, cpu_id: object, cores: object) -> str:
    """The machine kind a sitting is compared within: the GPU's name on CUDA, else the CPU model,
    its family/model/stepping (runs before 2026-12-02 did not record it: a kind of their own,
    which gets no quiet reference) and its usable cores."""
    return str(gpu) if device == "cuda" else f"{cpu} ({cpu_id or UNRECORDED}; {cores} cores)"


def _runs(env: Mapping[str, Any]) -> Iterator[Mapping[str, Any]]:
    yield env
    for e in env.get("environments") or ():
        if isinstance(e, Mapping):
            yield from _runs(e)


@functools.lru_cache(maxsize=64)
def _file_runs(path: Path, mtime_ns: int, size: int) -> tuple[Any, ...]:
    """A store file's run entries, parsed once per version of the file (its time and size): the
    stores are read whole for a few entries, and one process may check several sittings."""
    return tuple(json.loads(path.read_text()).get("runs") or [])


def stored_runs(folders: Iterable[Path]) -> list[Mapping[str, Any]]:
    """Every run entry of the stores in ``folders`` and of their later sittings
    (``FOLDER/sittings/<label>/``: runs of the same machine kind, kept apart from the report's rows);
    each store file once, each run once (a run kept in two stores counts once); an unreadable one
    skipped."""
    seen: set[Path] = set()
    runs_seen: set[tuple[str, str]] = set()
    out: list[Mapping[str, Any]] = []
    for folder in folders:
        subs = sorted(d for d in (Path(folder) / "sittings").glob("*") if d.is_dir() and not d.is_symlink())
        for where in (Path(folder), *subs):
            for name in FILES:
                f = where / name
                try:
                    key = f.resolve()
                    if key in seen or not f.is_file():
                        continue
                    seen.add(key)
                    st = f.stat()
                    runs = _file_runs(key, st.st_mtime_ns, st.st_size)
                except (OSError, ValueError, AttributeError):
                    continue
                for env in runs:
                    for r in (_runs(env) if isinstance(env, Mapping) else ()):
                        ident = (str(r.get("created")), str(r.get("hostname")))
                        if r.get("created") and ident in runs_seen:
                            continue
                        runs_seen.add(ident)
                        out.append(r)
    return out


def _num(v: object) -> float | None:
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0 else None


def quiet(runs: Iterable[Mapping[str, Any]], device: str, kind: str) -> Quiet | None:
    """The quiet sittings of ``kind`` on ``device`` among ``runs`` (None: fewer than ``MIN_RUNS``,
    or CPU runs that did not record their processor: one CPU name spans hosts whose copies differ
    widely, so no quiet sitting of theirs describes the next)."""
    if device != "cuda" and f"({UNRECORDED};" in kind:
        return None
    figs: dict[str, list[float]] = {"launch_latency_s": [], "launch_pipelined_s": [], "copy_bytes_per_s": []}
    count = 0
    for env in runs:
        hw = (env.get("hardware") or {}).get(device)
        if not isinstance(hw, Mapping) or hw.get("error") or env.get("noisy_sitting"):
            continue
        gpu = hw.get("gpu") or next((g.get("name") for g in env.get("gpus") or [] if isinstance(g, Mapping)), None)
        if kind_of(device, gpu, env.get("cpu"), env.get("cpu_id"), env.get("cores")) != kind:
            continue
        count += 1
        for k, xs in figs.items():
            if (v := _num(hw.get(k))) is not None:
                xs.append(v)
    if count < MIN_RUNS:
        return None

    def best(xs: list[float], high: bool) -> float | None:
        q = 1.0 - QUIET_QUANTILE if high else QUIET_QUANTILE
        return float(np.quantile(xs, q)) if len(xs) >= MIN_RUNS else None
    return Quiet(kind=kind, runs=count, launch_latency_s=best(figs["launch_latency_s"], False),
                 launch_pipelined_s=best(figs["launch_pipelined_s"], False),
                 copy_bytes_per_s=best(figs["copy_bytes_per_s"], True))


def repository_stores() -> list[Path]:
    """The published stores (docs/results/*/): a fresh --out learns its kind's quiet from them."""
    from compare.measuring.environment import ROOT
    return sorted(p for p in (ROOT / "docs" / "results").glob("*") if p.is_dir())


def quiet_for(check: SittingCheck, folders: Iterable[Path]) -> Quiet | None:
    """The quiet reference of ``check``'s machine kind, from the stores in ``folders``."""
    return quiet(stored_runs(folders), check.device, kind_of(check.device, check.gpu, check.cpu, check.cpu_id, check.cores))


__all__ = ["MIN_RUNS", "QUIET_QUANTILE", "UNRECORDED", "kind_of", "quiet", "quiet_for", "repository_stores", "stored_runs"]
