"""What ``compare all | run`` prints at the end (compare/render/console.py, compare/site/versus.py): a screen.

One quick run of NumPy with six other backends made uninstallable (a package on PYTHONPATH whose
import fails, as on the base install) and no GPU in sight: at most 100 lines in all, the skipped
cells grouped by cause with the one install command, and the closing block against the stored
report. The reference block is then checked against a tiny reference store built in tmp_path
from that run's own records, its per-call times doubled (every ratio 0.50x).
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from compare.render import console
from compare.site import versus
from compare.results.record import Record
from compare.results.store import Store
from conftest import ROOT

pytestmark = pytest.mark.cli

MISSING = ("torch", "cupy", "triton", "quadrants", "drjit", "mlx")


@pytest.fixture(scope="module")
def base_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[subprocess.CompletedProcess, Path]:
    stubs = tmp_path_factory.mktemp("stubs")
    for name in MISSING:        # found before site-packages: the import fails as if not installed
        (stubs / name).mkdir()
        (stubs / name / "__init__.py").write_text(f"raise ImportError(\"No module named '{name}'\")\n")
    out = tmp_path_factory.mktemp("run") / "results"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), str(stubs)]), "CI": "1",
           "CUDA_VISIBLE_DEVICES": ""}
    p = subprocess.run([sys.executable, "-m", "compare", "all", "--quick", "--backends", "numpy," + ",".join(MISSING),
                        "--repeat", "2", "--min-time", "0", "--no-plots", "--out", str(out)],
                       cwd=ROOT, env=env, capture_output=True, text=True, timeout=1200)
    return p, out


@pytest.mark.xdist_group("console")
def test_a_quick_run_fits_a_screen(base_run) -> None:
    p, out = base_run
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-3000:]
    lines = p.stdout.splitlines() + p.stderr.splitlines()
    assert len(lines) <= 100, "\n".join(lines)
    recs = Store.read(out / "results.json", "run").records
    skipped = [r for r in recs if r.status == "skipped"]
    assert len(skipped) >= 40 and sum(r.status == "ok" for r in recs) == 8
    # no skipped cell is a row of the table; every cell that ran is one
    assert not [ln for ln in p.stdout.splitlines() if re.match(r"\S+ (cpu|cuda)\b.* skipped ", ln)]
    assert sum(ln.startswith("numpy cpu f") for ln in p.stdout.splitlines()) == 8
    # skipped cells grouped by cause: one 'not installed' line with every extra in one command;
    # the frameworks that need a GPU say so on the CPU (installing them would not help here)
    head = next(i for i, ln in enumerate(p.stdout.splitlines()) if ln.endswith("cells skipped (each with its reason in results.md):"))
    assert p.stdout.splitlines()[head].startswith(f"{len(skipped)} cells skipped")
    missing = [ln for ln in p.stdout.splitlines() if "not installed" in ln]
    assert len(missing) == 1, missing
    assert missing[0].startswith("  torch, quadrants, drjit, mlx not installed: pip install -e '.[quadrants,drjit,mlx]'; ")
    assert missing[0].endswith("pip install -e '.[torch]'")              # torch's own, whole
    assert "  cupy on cpu (8 cells): CuPy runs on CUDA devices only" in p.stdout.splitlines()
    assert "  triton on cpu (8 cells): Triton compiles for GPUs only" in p.stdout.splitlines()
    assert sum(ln.strip().startswith("cuda: no GPU on this machine") for ln in p.stdout.splitlines()) == 1
    # the order: table, skipped, summary, time, files, reference
    text = p.stdout
    order = [text.index("saxpy ("), text.index("cells skipped"), text.index(f"{len(recs)} cells: "),
             text.index("time: "), text.index("wrote "), text.index("against the CPU report")]
    assert order == sorted(order), order
    # the reference ran the default sizes: a --quick run matches none of its cells, in one line
    ref = [ln for ln in text.splitlines() if "against the CPU report" in ln]
    assert len(ref) == 1 and "--quick never matches" in ref[0]
    # not a terminal: progress in a few lines, not one per cell
    assert 1 <= len(p.stderr.splitlines()) <= 5, p.stderr


def _reference(run: Path, root: Path, scale: float) -> Path:
    """A reference store made of the run's own results.json, every per-call time and the copy
    yardstick's time ``scale`` times the run's (so its bandwidth is 1/scale)."""
    doc = json.loads((run / "results.json").read_text())
    for r in doc["records"]:
        t = r.get("time") or {}
        for part in (t, t.get("latency"), t.get("throughput")):
            if isinstance(part, dict) and isinstance(part.get("median_s"), (int, float)):
                part["median_s"] *= scale
                part["iqr_s"] = 0.0
        t.pop("processes", None)
    for env in doc["runs"]:
        cpu = env["hardware"]["cpu"]
        cpu["copy_bytes_per_s"] /= scale
        env["cores"] = 64
    ref = root / "cpu"
    ref.mkdir(parents=True)
    (ref / "results.json").write_text(json.dumps(doc))
    return ref


@pytest.mark.xdist_group("console")
def test_reference_block_on_a_tiny_store(base_run, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    _, out = base_run
    store = Store.read(out / "results.json", "run")
    records, env = list(store.records), store.runs[0]
    ref = _reference(out, tmp_path / "refs", 2.0)
    monkeypatch.setattr(versus, "REFERENCES", tmp_path / "refs")
    monkeypatch.chdir(tmp_path)
    mine = tmp_path / "mine"
    mine.mkdir()
    lines = versus.block(records, env, mine)
    assert lines[0].startswith("This run against the CPU report (refs/cpu)") and "8 timed cells matched" in lines[0]
    machines = next(i for i, ln in enumerate(lines) if ln.startswith("  the machines:"))
    rows = {ln.split()[0]: ln for ln in lines[2:machines]}
    assert set(rows) == {"saxpy", "sdf", "particles", "projectile"}
    for row in rows.values():        # this run's time / twice it, in every cell
        assert row.split()[1:3] == ["cpu", "0.50×"] and "quartiles 0.50× – 0.50×; 2 cells" in row, row
    hw = " ".join(" ".join(lines[machines:]).split())
    copy_here = env["hardware"]["cpu"]["copy_bytes_per_s"]
    assert f"cpu copy {copy_here * 1e-9:.3g} GB/s here, {copy_here * 0.5e-9:.3g} GB/s there (2.00×)" in hw
    assert f"cores {env['cores']} here, 64 there" in hw
    assert lines[1].endswith("every cell: mine/against.md")
    page = (mine / "against.md").read_text()
    assert page.index("## Summary") < page.index("## Every matched cell") < page.index("## The two environments")
    assert "| cpu | saxpy | numpy | default | float32 |" in page
    # an NVIDIA GPU picks the H100 report (none stored here: one line says so)
    gpu = versus.block(records, {**env, "gpus": [{"name": "NVIDIA H100"}]}, mine)
    assert gpu == [f"against the H100 report ({os.path.join('refs', 'h100')}): no stored report there (no results.json)"]
    # --out is the reference itself; nothing matched; --against none
    assert versus.block(records, env, ref)[0].endswith("this run's --out is that report itself; nothing to compare")
    other = [r.replace(params={**r.params, "seed": 7}) if r.params and "seed" in r.params else r for r in records]
    none = versus.block([r for r in other if r.scenario in ("saxpy", "particles")], env, mine, quick=True)
    assert len(none) == 1 and "no timed cell of this run matches" in none[0] and "--quick" in none[0]
    assert versus.block(records, env, mine, against="none") == []
    named = versus.block(records, env, mine, against=str(ref))
    assert named[0].startswith(f"This run against the report in {ref}")


# ---- the grouping and the verbose listing, on records made here ---------------------------------
def _rec(backend: str, device: str, status: str = "skipped", reason: str = "", scenario: str = "saxpy",
         precision: str = "float32", noisy: bool = False) -> Record:
    t = None
    if status == "ok":
        t = {"median_s": 1e-3, "iqr_s": 1e-5, "repeats": 20,
             "throughput": {"median_s": 1e-3, "iqr_s": 1e-5, "repeats": 5, "k": 10}}
        if noisy:
            t["noise"] = {"noisy": True, "reasons": [{"regime": "", "why": "host busy: 1.2 other cores"}]}
    return Record(scenario=scenario, backend=backend, device=device, precision=precision, status=status,
                  reason=reason, params={"n": 10}, time=t)


def _absent(name: str, hint: str = "") -> str:
    how = hint or f"pip install -e '.[{name}]'"
    return f"{name} not importable: No module named '{name}' (install: {how})"


def test_skipped_cells_grouped_by_cause() -> None:
    recs = [_rec("numpy", "cpu", "ok")]
    for sc in ("saxpy", "sdf"):
        for prec in ("float32", "float64"):
            recs += [_rec("numpy", "cuda", reason="NumPy runs on the CPU only", scenario=sc, precision=prec),
                     _rec("cupy", "cpu", reason="CuPy runs on CUDA devices only", scenario=sc, precision=prec)]
            recs += [_rec(b, d, reason=_absent(b, "pip install x && pip install -e '.[torch]'" if b == "torch" else ""),
                          scenario=sc, precision=prec) for b in ("torch", "mlx") for d in ("cpu", "cuda")]
    lines = console.skip_lines(recs, gpu_here=False)
    assert lines == [
        "24 cells skipped (each with its reason in results.md):",
        "  torch, mlx not installed: pip install -e '.[mlx]'; pip install x && pip install -e '.[torch]'",
        "  cuda: no GPU on this machine (12 cells of 3 frameworks)",
        "  cupy on cpu (4 cells): CuPy runs on CUDA devices only"]
    # with a GPU, each framework's reason for not using it is a cause of its own, its command whole
    gpu = console.skip_lines(recs + [_rec("mlx", "cuda", reason="no CUDA backend (mlx-cpu); install: pip install 'mlx[cuda12]' "
                                      "(CUDA 13: 'mlx[cuda13]')")], gpu_here=True)
    assert "  numpy on cuda (4 cells): NumPy runs on the CPU only" in gpu
    assert "  mlx on cuda (1 cell): no CUDA backend (mlx-cpu): pip install 'mlx[cuda12]' (CUDA 13: 'mlx[cuda13]')" in gpu
    assert all(len(ln) <= console.WIDTH + 2 for ln in gpu)
    # a long reason is cut to one line; the command after it never is
    long = console.skip_lines([_rec("x", "cpu", reason="w " * 100 + "; install: pip install -e '.[a-long-extra]'")], True)
    assert len(long) == 2 and long[1].endswith("…: pip install -e '.[a-long-extra]'") and len(long[1]) <= console.WIDTH + 1
    many = console.skip_lines([_rec(f"b{i}", "cpu", reason=f"cause {i}") for i in range(30)], True)
    assert len(many) == 1 + console.MAX_CAUSES and "19 more causes" in many[-1]


def test_default_end_is_brief_and_verbose_keeps_the_full_listing() -> None:
    recs = [_rec(b, "cpu", "ok", scenario=sc, noisy=True) for b in ("numpy", "numba") for sc in ("saxpy", "sdf")]
    recs += [_rec("torch", d, reason=_absent("torch"), scenario=sc) for d in ("cpu", "cuda") for sc in ("saxpy", "sdf")]
    brief = "\n".join(console.closing(recs, {"gpus": []}, verbose=False, wide=False))
    full = "\n".join(console.closing(recs, {"gpus": []}, verbose=True, wide=False))
    assert "torch cpu" not in brief and "torch cpu" in full           # the skipped rows
    assert brief.count("host busy: 1.2 other cores") == 0 and full.count("host busy: 1.2 other cores") >= 4
    assert "~ 4 of 4 timed cells are noisy: host busy 4 (why: results.md)" in brief
    assert "torch not installed: pip install -e '.[torch]'" in brief
    assert "4 skipped" in brief and "4 skipped" in full                # the summary in both
    assert len(brief.splitlines()) < len(full.splitlines())


def test_install_hint_and_merge() -> None:
    assert console.install_hint(_absent("mlx")) == ("mlx not importable: No module named 'mlx'", "pip install -e '.[mlx]'")
    assert console.install_hint("CuPy runs on CUDA devices only") == ("CuPy runs on CUDA devices only", "")
    assert console.merge_commands(["pip install -e '.[a]'", "pip install -e '.[b,a]'", "make"]) == \
        "pip install -e '.[a,b]'; make"


def test_progress_off_a_terminal_is_a_few_lines(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture) -> None:
    from compare.running import engine
    from compare.results.record import Record
    monkeypatch.setenv("CI", "1")
    ident = {"scenario": "saxpy", "backend": "numpy", "device": "cpu", "precision": "float32", "variant": "default"}
    show = engine.progress(60, every=False)
    for i in range(40):                  # the skipped cells come first, all at once: counted only
        show(i, Record.from_json({**ident, "params": {}, "status": "skipped", "reason": "x"}), None)
    for i in range(40, 60):
        show(i, Record.from_json({**ident, "params": {}, "status": "error" if i == 45 else "ok",
                                  "reason": "boom" if i == 45 else "", "time": None, "error": None}), None)
    lines = capsys.readouterr().err.splitlines()
    assert lines[0] == "  5/20 cells run (40 skipped; last: saxpy/numpy/cpu/float32/default: ok)"
    assert "  [46/60] saxpy/numpy/cpu/float32/default: error boom" in lines      # a failure, always
    assert len(lines) == 5 and lines[-1].startswith("  20/20 cells run")
    show = engine.progress(3, every=True)                                        # --verbose: every cell
    for i in range(3):
        show(i, Record.from_json({**ident, "params": {}, "status": "skipped", "reason": "x"}), None)
    assert capsys.readouterr().err.count("skipped x") == 3
