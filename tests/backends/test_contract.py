"""The contract between the driver and a port, and docs/adding.md's "Adding a backend", proven.

A copy of the repository gets backends written by following README's steps alone:
  * ``tiny``: a correct NumPy port (CPU only; it reports no CUDA) of the four scenarios in 'all'
    and none of the optional measurement scenarios. It must run through ``all``, ``sweep`` and
    ``stress --quick`` with no driver edit, its cells ``ok`` or skipped with the reason;
  * ``liar``: its float32 SAXPY computes and returns float64 — the worker must catch it;
  * ``vague``: its available() omits 'cuda' and its particles kernel returns a misnamed output;
  * ``nameless`` (no name) and ``twin`` (a copy-pasted name) must be listed problems, not crashes.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from conftest import ROOT

pytestmark = pytest.mark.cli

INIT = '''
from ..base import Backend, not_installed


class TinyBackend(Backend):
    name = "{name}"
    package = "numpy"
    gradient_method = "adjoint"

    def available(self):
        return {{"cpu": not_installed("numpy", "numpy"){cuda}}}

    def synchronize(self, device, result):
        pass


BACKEND = TinyBackend()
'''

KERNELS = {
    "saxpy.py": '''
        import numpy as np
        from ..base import ScenarioKernel

        class Kernel(ScenarioKernel):
            def __init__(self, params, inputs, device, precision, variant):
                self.a, self.x, self.y = inputs["a"], inputs["x"], inputs["y"]

            def run(self):
                self.out = self.a * self.x + self.y{cast}

            def outputs(self):
                return {{"out": self.out}}
        ''',
    "sdf.py": '''
        import numpy as np
        from ..base import ScenarioKernel
        from scenarios.base import dtype_of
        from scenarios.sdf import sdf_field

        class Kernel(ScenarioKernel):
            def __init__(self, params, inputs, device, precision, variant):
                self.p, self.dt = params, dtype_of(precision)

            def run(self):
                fx = 2.0 * (np.arange(self.p.width) / (self.p.width - 1)) - 1.0
                fy = 2.0 * (np.arange(self.p.height) / (self.p.height - 1)) - 1.0
                self.image = sdf_field(fx[None, :], fy[:, None]).astype(self.dt)

            def outputs(self):
                return {"image": self.image}
        ''',
    "particles.py": '''
        import numpy as np
        from ..base import ScenarioKernel
        from scenarios.particles import clamp, constants, fly

        class Kernel(ScenarioKernel):
            def __init__(self, params, inputs, device, precision, variant):
                self.p, self.inputs = params, inputs

            def run(self):
                c = constants(self.inputs, self.inputs["x0"].dtype.type)
                x, y, u, v = (self.inputs[k].copy() for k in ("x0", "y0", "vx0", "vy0"))
                frames = [(x, y)]
                for s in range(self.p.steps):
                    x, y, u, v, _ = clamp(*fly(x, y, u, v, c), c)
                    if self.p.record_every and (s + 1) % self.p.record_every == 0:
                        frames.append((x, y))
                self.out = {"{x}": x, "y": y, "vx": u, "vy": v}
                if self.p.record_every:
                    self.out["traj_x"] = np.stack([f[0] for f in frames])
                    self.out["traj_y"] = np.stack([f[1] for f in frames])

            def outputs(self):
                return self.out
        ''',
    "projectile.py": '''
        import numpy as np
        from ..base import ScenarioKernel
        from scenarios.projectile import CONSTANTS
        from scenarios.projectile_adjoint import adjoint, rollout

        class Kernel(ScenarioKernel):
            def __init__(self, params, inputs, device, precision, variant):
                self.p, self.dt = params, inputs["v0"].dtype
                self.c = {k: float(inputs[k]) for k in CONSTANTS}
                self.v0 = inputs["v0"].astype(np.float64)

            def evaluate(self, v):
                (x, y, _, _), tape = rollout(self.c, self.p.contact, self.p.steps, v[0], v[1])
                dx, dy = x - self.c["target_x"], y - self.c["target_y"]
                return dx * dx + dy * dy, np.array(adjoint(self.c, tape, 2 * dx, 2 * dy))

            def run(self):
                v, hist = self.v0.copy(), []
                for k in range(self.p.iters + 1):
                    loss, g = self.evaluate(v)
                    hist.append(loss)
                    if k == 0:
                        self.grad = g
                    if k < self.p.iters:
                        v = v - self.c["lr"] * g
                self.hist, self.v = np.array(hist), v

            def outputs(self):
                return {"loss": self.dt.type(self.hist[0]), "grad": self.grad.astype(self.dt),
                        "loss_history": self.hist.astype(self.dt), "v_final": self.v.astype(self.dt)}
        ''',
}


def write_backend(repo: Path, name: str, cuda: str = ', "cuda": "tiny runs on the CPU only"',
                  cast: str = "", x: str = "x", backend_name: str | None = None) -> None:
    pkg = repo / "backends" / name
    pkg.mkdir()
    (pkg / "__init__.py").write_text(INIT.format(name=backend_name if backend_name is not None else name, cuda=cuda))
    for f, src in KERNELS.items():
        src = textwrap.dedent(src)
        src = src.replace("{cast}", cast) if f == "saxpy.py" else src
        src = src.replace('{"{x}"', '{"' + x + '"') if f == "particles.py" else src
        (pkg / f).write_text(src.replace("{{", "{").replace("}}", "}") if f == "saxpy.py" else src)


@pytest.fixture(scope="module")
def repo(tmp_path_factory) -> Path:
    """A copy of the repository's code (no results, no caches) with the throwaway backends."""
    dst = tmp_path_factory.mktemp("repo")
    for part in ("backends", "scenarios", "compare", "pyproject.toml", "README.md"):
        src = ROOT / part
        if src.is_dir():
            shutil.copytree(src, dst / part, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy(src, dst / part)
    write_backend(dst, "tiny")
    write_backend(dst, "liar", cast=".astype(np.float64)")      # float32 cell, float64 work
    write_backend(dst, "vague", cuda="", x="pos_x")              # no 'cuda' key; misnamed output
    write_backend(dst, "nameless", backend_name="")
    write_backend(dst, "twin", backend_name="tiny")
    return dst


def compare(repo: Path, *args: str, timeout: float = 1200) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "compare", *args], cwd=repo, capture_output=True,
                          text=True, timeout=timeout)


def records(path: Path) -> list[dict]:
    return json.loads(path.read_text())["records"]


@pytest.fixture(scope="module")
def repo_list(repo, tmp_path_factory) -> subprocess.CompletedProcess:
    """``compare list`` in the copy, with an extra backend folder (COMPARE_BACKENDS_EXTRA, the
    tests' own backends): the tests below read one listing, which probes every backend (seconds)."""
    extra = tmp_path_factory.mktemp("extra")
    shutil.copytree(ROOT / "tests" / "extra_backends" / "faulty", extra / "faulty")
    (extra / "boom").mkdir()
    (extra / "boom" / "__init__.py").write_text("raise RuntimeError('no such framework')\n")
    (extra / "again").mkdir()
    (extra / "again" / "__init__.py").write_text(
        "from backends.numpy import NumpyBackend\nBACKEND = NumpyBackend()\n")
    env = {**os.environ, "PYTHONPATH": str(repo), "COMPARE_BACKENDS_EXTRA": str(extra)}
    p = subprocess.run([sys.executable, "-m", "compare", "list"], cwd=repo, capture_output=True, text=True,
                       env=env, timeout=300)
    p.extra = extra                     # type: ignore[attr-defined]
    return p


@pytest.mark.xdist_group("repo")
def test_list_names_problems_in_one_line_each(repo_list):
    p = repo_list
    assert p.returncode == 0 and "Traceback" not in p.stderr, p.stderr
    problems = p.stdout.split("problems:", 1)[1]
    assert "backends/nameless: BACKEND has no name" in problems
    assert "backends/twin: BACKEND calls itself 'tiny'" in problems
    assert "tiny: no optional" in problems and "launch.py" in problems     # optional: listed
    assert "tiny " in p.stdout.split("problems:")[0]        # the first 'tiny' is the one used


@pytest.mark.xdist_group("repo")
def test_extra_backend_folders_are_discovered_and_their_problems_listed(repo_list, compare_list):
    """COMPARE_BACKENDS_EXTRA (the tests' own backends): a package there is a backend like any
    other; one that fails to import or takes a taken name is a listed problem, not a crash."""
    p, extra = repo_list, repo_list.extra
    assert p.returncode == 0 and "Traceback" not in p.stderr, p.stderr
    listed, problems = p.stdout.split("problems:", 1)
    assert "\n  faulty " in listed
    assert "boom" in problems and "RuntimeError: no such framework" in problems
    assert f"{extra / 'again'}: BACKEND calls itself 'numpy'" in problems
    plain = compare_list                                       # the same command without the variable
    assert plain.returncode == 0 and "faulty" not in plain.stdout   # only where the tests install it


@pytest.mark.xdist_group("repo")
def test_liar_vague_and_twin_are_caught(repo, tmp_path):
    p = compare(repo, "run", "saxpy", "particles", "--quick", "--backends", "liar,vague,twin",
                "--repeat", "1", "--min-time", "0", "--out", str(tmp_path), "--no-plots")
    assert p.returncode == 1 and "Traceback" not in p.stderr, p.stderr
    recs = {(r["backend"], r["scenario"], r["device"], r["precision"]): r for r in records(tmp_path / "results.json")}
    liar = recs[("liar", "saxpy", "cpu", "float32")]
    assert liar["status"] == "error" and "dtype float64" in liar["reason"] and "float32" in liar["reason"]
    assert recs[("liar", "saxpy", "cpu", "float64")]["status"] == "ok"
    assert all(r["status"] == "skipped" and "does not report 'cuda'" in r["reason"]
               for k, r in recs.items() if k[0] == "vague" and k[2] == "cuda")
    bad = recs[("vague", "particles", "cpu", "float32")]
    assert bad["status"] == "error" and "no 'x'" in bad["reason"], bad["reason"]
    assert recs[("vague", "saxpy", "cpu", "float64")]["status"] == "ok"
    assert all(r["status"] == "skipped" and "calls itself 'tiny'" in r["reason"]
               for k, r in recs.items() if k[0] == "twin")


@pytest.mark.slow
@pytest.mark.xdist_group("repo")
def test_new_backend_runs_through_all_sweep_and_stress(repo, tmp_path):
    p = compare(repo, "all", "--quick", "--backends", "tiny", "--repeat", "1", "--out", str(tmp_path / "all"))
    assert p.returncode == 0, p.stdout[-2000:] + p.stderr[-2000:]
    recs = records(tmp_path / "all" / "results.json")
    assert {r["scenario"] for r in recs if r["status"] == "ok"} == {"saxpy", "sdf", "particles", "projectile"}
    assert all(r["status"] == "skipped" for r in recs if r["device"] == "cuda")
    p = compare(repo, "sweep", "bandwidth", "--quick", "--backends", "tiny", "--devices", "cpu",
                "--out", str(tmp_path / "sweep"))
    assert p.returncode == 0, p.stderr[-2000:]
    sw = records(tmp_path / "sweep" / "sweep.json")
    assert any(r["status"] == "ok" for r in sw)
    assert all(r["status"] in ("ok", "skipped") for r in sw)
    assert any(r["status"] == "skipped" and "optional" in r["reason"] for r in sw)   # no launch.py
    p = compare(repo, "stress", "--quick", "--backends", "tiny", "--devices", "cpu",
                "--only", "particles-dt,projectile-gradient,ulps,races", "--out", str(tmp_path / "stress"))
    assert p.returncode == 0, p.stderr[-3000:]
    assert (tmp_path / "stress" / "stress.md").exists()


def test_without_nvml_the_gpu_hint_counts_the_drivers_gpus(monkeypatch):
    """NVML's binding is in the cuda extras: on a base install the driver's own listing still
    tells a GPU machine to install them (a framework's CPU-only build names the extra)."""
    from backends import base
    monkeypatch.setitem(sys.modules, "pynvml", None)             # not installed
    monkeypatch.setattr(base.os, "listdir", lambda path: ["0000:01:00.0", "0000:02:00.0"]
                        if path == "/proc/driver/nvidia/gpus" else [])
    assert base.visible_gpus() == 2
    assert "2 NVIDIA GPU(s)" in base.cuda_build_hint("no GPU") and "'.[cuda]'" in base.cuda_build_hint("no GPU")

    def no_driver(path):
        raise FileNotFoundError(path)
    monkeypatch.setattr(base.os, "listdir", no_driver)
    assert base.visible_gpus() == 0 and base.cuda_build_hint("no GPU") == "no GPU"
