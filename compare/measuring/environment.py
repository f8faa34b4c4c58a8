"""What a results file records about where it was made (so numbers can be reproduced)."""
from __future__ import annotations

import datetime
import importlib.metadata
import os
import platform
import shutil
import subprocess
import sys
from pathlib import Path
from typing import NotRequired, TypedDict

from compare.results.environment import Gpu, RunEnvironment

ROOT = Path(__file__).resolve().parents[2]


def usable_cores() -> int:
    """The cores this process may run on (its affinity: fewer than the host's under a core set)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def packages() -> tuple[str, ...]:
    """The distributions whose versions a results file records: this project's own requirements
    (from its installed metadata) and every backend's package."""
    import re

    import backends
    try:
        reqs = importlib.metadata.requires("gpu-python-compare") or []
    except importlib.metadata.PackageNotFoundError:      # run from a tree that was not installed
        reqs = []
    names = [re.split(r"[\s<>=!~;\[(]", r, maxsplit=1)[0] for r in reqs if "extra ==" not in r]
    for b in backends.BACKENDS.values():
        names += [b.package, *b.related_packages]
    return tuple(dict.fromkeys(names))


def _run(cmd: list[str]) -> str:
    try:
        # rstrip only: `git status --porcelain` starts its first line with a space (" M path")
        return subprocess.run(cmd, capture_output=True, text=True, timeout=20, cwd=ROOT).stdout.rstrip()
    except (OSError, subprocess.SubprocessError):
        return ""


def cpuinfo() -> dict[str, str]:
    """The first processor's fields in /proc/cpuinfo (Linux; empty elsewhere)."""
    try:
        first = Path("/proc/cpuinfo").read_text().split("\n\n")[0]
    except OSError:
        return {}
    return {k.strip(): v.strip() for k, _, v in (line.partition(":") for line in first.splitlines()) if _}


def cpu_model() -> str:
    return cpuinfo().get("model name") or platform.processor() or platform.machine()


def cpu_id() -> str:
    """The processor's family, model and stepping (on Arm: implementer, part, variant and
    revision), '' where not known. A virtual machine's model name ("AMD EPYC") can stand for
    several generations of processor."""
    info = cpuinfo()
    for keys in (("cpu family", "model", "stepping"), ("CPU implementer", "CPU part", "CPU variant", "CPU revision")):
        if all(info.get(k) for k in keys):
            return ", ".join(f"{k.split()[-1]} {info[k]}" for k in keys)
    return ""


def gpus() -> list[Gpu]:
    if not shutil.which("nvidia-smi"):
        return []
    out = _run(["nvidia-smi", "--query-gpu=name,driver_version,memory.total", "--format=csv,noheader"])
    rows: list[Gpu] = []
    for line in out.splitlines():
        parts = [p.strip() for p in line.split(",")]
        if len(parts) == 3:
            rows.append(Gpu(name=parts[0], driver=parts[1], memory=parts[2]))
    return rows


def own_repository() -> bool:
    """Whether ROOT is the top level of the git repository git finds from it: this project's
    checkout, not a copy without its .git (``git archive``) inside some other checkout, whose
    HEAD and changes are not this project's."""
    top = _run(["git", "rev-parse", "--show-toplevel"])
    return bool(top) and Path(top).resolve() == ROOT.resolve()


DIRTY_PATHS_KEPT = 20     # a run names at most this many uncommitted paths (and how many more)


def dirty_paths() -> list[str]:
    """The tracked paths with uncommitted changes in this checkout (empty: clean, no git, or not
    this project's own checkout: another's changes are not ours)."""
    if not own_repository():
        return []
    out = _run(["git", "status", "--porcelain", "--untracked-files=no"])
    return [line[3:].split(" -> ")[-1] for line in out.splitlines() if len(line) > 3]


# The files a measurement can run: a copied tree is checked on these alone, so a lent machine's
# copy may leave the stores and docs behind (its transfer limit) and still be the commit's code.
CODE_PATHS = ("backends", "compare", "scenarios", "pyproject.toml")


def files_digest(commit: str | None = None) -> str:
    """A digest of a tree's code files (``CODE_PATHS``), path and content (not modes: a copy may
    drop an executable bit): of ``commit``'s tree, or (None) of this checkout's files as they are, tracked and
    untracked by .gitignore's rules, through a throwaway index, which needs no current .git
    history, so a copied tree whose .git is stale can be checked against the commit it claims
    (``python -m compare.measuring.environment COMMIT`` prints the commit's). A copy without its
    own .git (``own_repository``) is hashed through a throwaway repository: another checkout
    around it lends no paths, rules or object store. Empty: git cannot tell."""
    import hashlib
    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "GIT_INDEX_FILE": str(Path(tmp) / "index")}
        git = ["git", "-c", "safe.directory=*"]      # a copy may belong to another user (root on a lent machine)
        steps = ([[*git, "ls-tree", "-r", "-z", commit]] if commit else
                 [[*git, "add", "-A", "."], [*git, "ls-files", "-s", "-z"]])
        if not commit and not own_repository():
            git += [f"--git-dir={tmp}/repo/.git", f"--work-tree={ROOT}"]
            steps = [["git", "init", "-q", f"{tmp}/repo"], [*git, "add", "-A", "."], [*git, "ls-files", "-s", "-z"]]
        try:
            for cmd in steps:
                done = subprocess.run(cmd, capture_output=True, text=True, timeout=120, cwd=ROOT, env=env)
                if done.returncode != 0:
                    return ""
        except (OSError, subprocess.SubprocessError):
            return ""
    # ls-tree: "<mode> blob <hash>\t<path>"; ls-files -s: "<mode> <hash> <stage>\t<path>"
    rows = sorted(f"{meta.split()[2] if commit else meta.split()[1]} {path}"
                  for meta, _, path in (e.partition("\t") for e in done.stdout.split("\0") if e)
                  if (not commit or meta.split()[1] == "blob") and path.split("/")[0] in CODE_PATHS)
    return hashlib.sha256("\n".join(rows).encode()).hexdigest() if rows else ""


def copy_dirty() -> bool | None:
    """A copied tree's state: COMPARE_GIT_TREE (``files_digest`` of the claimed commit, made where
    that commit lives) against the copy's own files: False (the commit's files exactly), True
    (they differ), None (none named, or git cannot tell)."""
    want = os.environ.get("COMPARE_GIT_TREE", "").strip()
    if not want:
        return None
    have = files_digest()
    return None if not have else have != want


def collect(argv: list[str] | None = None) -> RunEnvironment:
    """This run's environment (a results file's ``runs`` entry): the machine, packages, commit, command."""
    versions: dict[str, str] = {}
    for pkg in packages():
        try:
            versions[pkg] = importlib.metadata.version(pkg)
        except importlib.metadata.PackageNotFoundError:
            pass
    cores = usable_cores()
    import psutil
    cuda = _run(["nvcc", "--version"]).splitlines()[-1:] if shutil.which("nvcc") else []
    commit = os.environ.get("COMPARE_GIT_COMMIT", "").strip()
    own = not commit and own_repository()      # else another checkout's HEAD, or none: unknown
    dirty = dirty_paths() if own else []
    env: RunEnvironment = {
        "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "hostname": platform.node(),
        "os": platform.platform(),
        "cpu": cpu_model(), "cpu_id": cpu_id(), "cores": cores,
        "memory_gib": round(psutil.virtual_memory().total / 2**30, 1),
        "gpus": gpus(), "cuda_toolkit": cuda[0] if cuda else "",
        "python": sys.version.split()[0],
        "packages": versions,
        # A copied tree (e.g. on a lent GPU machine) may carry a stale or no .git: the caller then
        # names the commit it copied in COMPARE_GIT_COMMIT, and its tree in COMPARE_GIT_TREE,
        # against which the copy's files are checked (without it, dirtiness is unknown: None).
        # Neither named nor this project's own checkout: commit unknown (''), tree state None.
        "git_commit": commit or (_run(["git", "rev-parse", "--short", "HEAD"]) if own else ""),
        "git_dirty": copy_dirty() if commit else (bool(dirty) if own else None),
    }
    if dirty:
        env["git_dirty_paths"] = dirty[:DIRTY_PATHS_KEPT] + ([f"... and {len(dirty) - DIRTY_PATHS_KEPT} more"]
                                                             if len(dirty) > DIRTY_PATHS_KEPT else [])
    env["command"] = " ".join(["python -m compare"] + (argv if argv is not None else sys.argv[1:]))
    return env


class RunStamp(TypedDict):
    """A record's ``run``: when its run started, the commit, whether the tree was dirty."""
    created: str
    commit: str | None
    dirty: bool | None
    noisy_sitting: NotRequired[bool]     # publish let a noisy sitting through (compare.running.sitting_run)


def run_stamp(env: RunEnvironment) -> RunStamp:
    """What a record keeps of the run that measured it (``Record.run``): when it started, the
    commit, whether the tree was dirty (None: unknown, a copied tree) and a noisy sitting."""
    stamp = RunStamp(created=str(env.get("created", "")), commit=env.get("git_commit") or None,
                     dirty=env.get("git_dirty"))
    if env.get("noisy_sitting"):
        stamp["noisy_sitting"] = True
    return stamp


if __name__ == "__main__":      # the digest a copied tree is checked against (COMPARE_GIT_TREE)
    print(files_digest(sys.argv[1] if len(sys.argv) > 1 else "HEAD"))
