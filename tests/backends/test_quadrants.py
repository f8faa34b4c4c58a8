"""Quadrants' own checks beyond the generic parity suite; those it shares with Taichi, of which
it is the maintained fork (variants, precision and the agreement with Warp, the fused rollout
against one launch per step, batch rows and set_input), are in tests/backends/test_taichi_family.py.

1. no steps limit: a long rollout with a contact on every step (the deepest adstacks, sized by
   Quadrants at launch time) stays fused and exact;
2. the guard decisions: the three Taichi 1.7 autodiff bugs the Taichi port guards against
   (docs/findings.md) are absent from the installed Quadrants, which is why this port carries
   none of the guards. The reproducers are the ones docs/findings.md prints, run as they are; if
   a Quadrants upgrade brings a bug back, this test fails before the port's gradients go wrong.
Anything that initialises Quadrants runs in a subprocess or a worker (qd.init is process-global).
"""
from __future__ import annotations

import json
import math
import re
import subprocess
import sys

import pytest

from compare.running import cells
from conftest import ROOT, require_device
from taichi_family import script

pytestmark = pytest.mark.quadrants


# ---- 1. no steps limit --------------------------------------------------------------------------
LONG = """
import numpy as np
from backends.quadrants.projectile import Kernel
b = backends.get("quadrants"); b.setup(DEVICE, "float64", "default")
sc = scenarios.get("projectile")
out = {}
# 5000 steps: beyond Taichi's default 32 entries and past its ad_stack_size of 4096 (CPU) / 1024
# (CUDA); vy0 = 0 with hard contact clamps on every step, soft contact penetrates on every step:
# the deepest adstacks. t_N = 2 s.
for contact, vy0 in (("hard", 0.0), ("hard", 6.5), ("soft", 6.5)):
    p = sc.params({"contact": contact, "steps": 5000, "dt": 2.0 / 5000, "iters": 1, "vy0": vy0,
                   "batch": 3})
    i = sc.inputs(p, "float64")
    if vy0 == 0.0:
        i["v0"][:, 1] = 0.0
    res = []
    for fused in (True, False):
        Kernel.fused = fused
        k = Kernel(p, i, DEVICE, "float64", "default")
        b.synchronize(DEVICE, k.run())
        res.append(k.outputs())
    Kernel.fused = True
    o, o_step = res
    out[f"{contact}-{vy0}"] = {"identical": all(np.array_equal(o[n], o_step[n]) for n in o),
                               "finite": all(bool(np.all(np.isfinite(o[n]))) for n in o),
                               "nonzero_grad": bool(np.all(np.abs(o["grad"][:, 0]) > 0))}
print("RESULT" + json.dumps(out))
"""


def test_no_steps_limit_the_long_rollout_stays_fused_and_exact():
    """No ad_stack_size and no fallback: a 5000-step rollout (Taichi's port would leave the fused
    path past 4094 steps; Taichi's own default overflows past 32) with a contact on every step
    gives the per-step path's outputs bit for bit."""
    r = script("quadrants", LONG)
    for case, v in r.items():
        assert v == {"identical": True, "finite": True, "nonzero_grad": True}, case


# ---- 2. guard decisions: the Taichi 1.7 bugs are absent -----------------------------------------
def _findings_reproducers() -> dict[str, str]:
    """The reproducers docs/findings.md prints: ```python blocks whose first line is
    '# reproducer: NAME'."""
    text = (ROOT / "docs" / "findings.md").read_text()
    blocks = re.findall(r"```python\n(# reproducer: (\S+)\n.*?)```", text, flags=re.S)
    return {name: code for code, name in blocks}


AD_BUGS = ["adstack-overflow", "reassignment-pushes", "exp-backup"]


@pytest.mark.parametrize("name", AD_BUGS)
def test_taichi_autodiff_bug_is_absent_in_quadrants(name, tmp_path):
    """Each reproducer prints one line per case ending in OK (oracle's gradient) or WRONG, or
    fails loudly. Under Quadrants (adstack on, as the backend initialises it) every case is OK:
    the reason this port carries none of the Taichi port's guards."""
    require_device("quadrants", "cpu")
    code = _findings_reproducers()[name]
    path = tmp_path / f"{name}.py"
    path.write_text(code)
    proc = subprocess.run([sys.executable, str(path), "quadrants"], cwd=tmp_path,
                          env=cells.worker_env(), capture_output=True, text=True, timeout=600,
                          stdin=subprocess.DEVNULL)
    verdicts = [ln for ln in proc.stdout.splitlines() if ln.endswith(("OK", "WRONG"))]
    assert proc.returncode == 0 and verdicts, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert all(ln.endswith("OK") for ln in verdicts), "\n".join(verdicts)


def test_adstack_bound_must_be_readable_by_the_sizer(tmp_path):
    """Why the port reads the step count from a field: with the adstack on, a loop bounded by a
    kernel scalar argument is refused at compile time (loudly; Taichi 1.7 compiled it and
    overflowed silently), and the same loop bounded by a 0-d i32 field differentiates exactly.
    (A file, not ``python -c``: Quadrants reads a kernel's source through inspect.)"""
    require_device("quadrants", "cpu")
    script = tmp_path / "bound.py"
    script.write_text('''
import json
import quadrants as qd
qd.init(arch=qd.cpu, default_fp=qd.f64, ad_stack_experimental_enabled=True, offline_cache=False)
x = qd.field(float, (), needs_grad=True)
loss = qd.field(float, (), needs_grad=True)
n_f = qd.field(qd.i32, ())

@qd.kernel
def by_arg(n: qd.i32):
    for _ in range(1):
        y = x[None]
        for s in range(n):
            y = y + 0.1 * qd.sin(y)
        loss[None] = y

@qd.kernel
def by_field():
    for _ in range(1):
        y = x[None]
        for s in range(n_f[None]):
            y = y + 0.1 * qd.sin(y)
        loss[None] = y

out = {}
x[None] = 0.3
n_f[None] = 40
by_arg(40)
loss.grad[None] = 1.0
try:
    by_arg.grad(40)
    out["arg"] = "compiled"
except Exception as exc:
    out["arg"] = str(exc)
x.grad[None] = 0.0
by_field()
loss.grad[None] = 1.0
by_field.grad()
out["field"] = x.grad[None]
print("RESULT" + json.dumps(out))
''')
    proc = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=cells.worker_env(),
                          capture_output=True, text=True, timeout=600, stdin=subprocess.DEVNULL)
    line = next((ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT")), None)
    assert line, proc.stderr[-3000:]
    r = json.loads(line[len("RESULT"):])
    assert "unresolved" in r["arg"], r["arg"]
    y, want = 0.3, 1.0
    for _ in range(40):
        want *= 1.0 + 0.1 * math.cos(y)
        y = y + 0.1 * math.sin(y)
    assert r["field"] == pytest.approx(want, rel=1e-13)
