"""What the tests of Taichi and of Quadrants (Taichi's maintained fork) share: the cells each
framework's tests run through the worker (one conftest.shared_cell group per framework, which
tests/backends/test_taichi_family.py and the framework's own file both read), the parametrization of the
checks that hold for both (tests/backends/test_taichi_family.py) and their scripts. Each framework's own
checks stay in tests/backends/test_taichi.py and tests/backends/test_quadrants.py."""
from __future__ import annotations

import pytest

import backends
from conftest import run_script, shared_cell
from oracle_checks import FD, FRAMES

FRAMEWORKS = ("taichi", "quadrants")
PRECISIONS = ("float64", "float32")
# small cells, each one of the parity suite's cases (tests/backends/test_parity.py): the parity
# suite's worker processes give them (conftest.run_cases), no other process starts for them
SMALL = {"saxpy": {"n": 257, "inputs": "random", "seed": 3}, "sdf": {"width": 2, "height": 3},
         "particles": {"n": 33, "steps": 57, "record_every": 7}, "projectile": {"contact": "soft"}}
# (scenario, precision, device) of the fast-math cells: Taichi's float32 on every device,
# Quadrants' a sample. The flag is the process's init option whatever the precision: Taichi's
# float64 cells (FASTMATH_SLOW, a framework start and four compilations) are the long tier's.
FASTMATH = {"taichi": [(s, "float32", d) for s in SMALL for d in backends.DEVICES],
            "quadrants": [(s, "float32", "cpu") for s in ("sdf", "projectile")]}
FASTMATH_SLOW = {"taichi": [(s, "float64", d) for s in SMALL for d in backends.DEVICES], "quadrants": []}
# (scenario, overrides) of the float32 cells compared with Warp's
VS_WARP = {"taichi": [("saxpy", {}), ("saxpy", {"n": 257, "inputs": "random", "seed": 3}), ("sdf", {}),
                      ("particles", {}), ("particles", {"n": 33, "steps": 57, "record_every": 7}),
                      ("projectile", {"contact": "none"}), ("projectile", {"contact": "hard"}),
                      ("projectile", {"contact": "soft"})],
           "quadrants": [("saxpy", {"n": 257, "inputs": "random", "seed": 3}), ("sdf", {}),
                         ("particles", {"n": 33, "steps": 57, "record_every": 7}),
                         ("projectile", {"contact": "hard"}), ("projectile", {"contact": "soft"})]}
# the cells only tests/backends/test_taichi.py reads: gradients on every device, trajectory frames
OWN_CELLS = {"taichi": [("taichi", "projectile", "float64", o, d, "default") for o in FD for d in backends.DEVICES]
                       + [("taichi", "particles", "float64", FRAMES, "cpu", "default")],
             "quadrants": []}


def cells(framework: str) -> list:
    """Every cell the tests of xdist_group(f"{framework}-cells") run through the worker."""
    return ([(framework, s, p, SMALL[s], d, "fastmath") for s, p, d in FASTMATH[framework]]
            + [(framework, s, p, o, "cpu", "default") for s, o in SMALL.items() for p in PRECISIONS]
            + [(b, s, "float32", o, "cpu", "default") for b in (framework, backends.reference())
               for s, o in VS_WARP[framework]]
            + OWN_CELLS[framework])


def run(framework: str, scenario: str, precision: str, params: dict, device: str = "cpu",
        variant: str = "default", backend: str | None = None) -> tuple[dict, dict]:
    """One cell through the worker path; a framework's cells share a worker process per
    precision and variant (conftest.shared_cell), each test asserts on its own."""
    return shared_cell(f"{framework}-cells", cells(framework), backend or framework, scenario, precision,
                       params, device, variant)


def script(framework: str, body: str, device: str = "cpu", **constants) -> dict:
    """Run ``body`` in a fresh interpreter (its own ti.init / qd.init, which are process-global)
    with FRAMEWORK and ``constants`` defined; it prints RESULT<json>."""
    head = "".join(f"{k} = {v!r}\n" for k, v in {"FRAMEWORK": framework, **constants}.items())
    return run_script(framework, head + body, device)


def each(cases: dict[str, list] | None = None, *, group: bool = False, early: tuple[str, ...] = (),
         slow: bool = False) -> list:
    """A pytest.param per framework (per case of ``cases[framework]``, its values after the
    framework's name), marked with its framework (so `-m taichi` / `-m quadrants` select it), with
    ``group`` its framework's xdist_group of cells, ``early`` where the framework is listed
    (Taichi's long script tests start first, as they did in its own file), ``slow`` the long tier's."""
    out = []
    for fw in FRAMEWORKS:
        marks = [getattr(pytest.mark, fw)] + [pytest.mark.xdist_group(f"{fw}-cells")] * group \
            + [pytest.mark.early] * (fw in early) + [pytest.mark.slow] * slow
        for case in (cases[fw] if cases else [()]):
            out.append(pytest.param(fw, *case, marks=marks, id="-".join(map(str, (fw, *case)))))
    return out


# The fused backward pass against one launch per step, for a single trajectory; a batch's (37
# trajectories, every contact) is VARIANTS' default against its 'per_step' variant.
PATHS = """
import importlib
import numpy as np
Kernel = importlib.import_module(f"backends.{FRAMEWORK}.projectile").Kernel
b = backends.get(FRAMEWORK); b.setup(DEVICE, PRECISION, "default")
sc = scenarios.get("projectile")
chosen = Kernel.fused               # the framework's own choice, restored after forcing either path
out = {}
for contact in ("none", "hard", "soft"):
    for batch in (1,):
        p = sc.params({"contact": contact, "steps": 60, "iters": 3, "batch": batch})
        i = sc.inputs(p, PRECISION)
        res = {}
        for fused in (True, False):
            Kernel.fused = fused
            k = Kernel(p, i, DEVICE, PRECISION, "default")
            b.synchronize(DEVICE, k.run())
            o = k.outputs()
            res[fused] = (o, bool(sc.check(p, i, o, sc.oracle(p, i, PRECISION), PRECISION).ok), k.info())
        Kernel.fused = chosen
        (o, ok, info), (o_step, ok_step, info_step) = res[True], res[False]
        out[f"{PRECISION}-{contact}-{batch}"] = {
            "ok": [ok, ok_step], "fused_flags": [info["fused_rollout"], info_step["fused_rollout"]],
            "shapes": {n: [list(o[n].shape), list(o_step[n].shape)] for n in o},
            "identical": all(np.array_equal(o[n], o_step[n]) for n in o),
            "rel": max(float(np.max(np.abs(o[n] - o_step[n]) / np.maximum(np.abs(o_step[n]), 1e-300)))
                       for n in ("loss", "grad"))}
print("RESULT" + json.dumps(out))
"""

# The projectile's named variants against the default rollout, built as the driver builds them
# (Kernel(..., variant)); VARIANTS: the framework's, without Taichi's 'checkpoint' (its own test).
VARIANTS = """
import importlib
import numpy as np
Kernel = importlib.import_module(f"backends.{FRAMEWORK}.projectile").Kernel
b = backends.get(FRAMEWORK); b.setup(DEVICE, PRECISION, "default")
sc = scenarios.get("projectile")
out = {}
for contact in ("none", "hard", "soft"):
    # 24 steps over 2 s: every trajectory reaches the ground
    p = sc.params({"contact": contact, "steps": 24, "dt": 2.0 / 24, "iters": 3, "batch": 37})
    i = sc.inputs(p, PRECISION)
    res = {}
    for variant in ("default",) + tuple(VARIANTS):
        k = Kernel(p, i, DEVICE, PRECISION, variant)
        b.synchronize(DEVICE, k.run())
        o = k.outputs()
        info = k.info()
        res[variant] = o
        ref = res["default"]
        out[f"{contact}-{variant}"] = {
            "ok": bool(sc.check(p, i, o, sc.oracle(p, i, PRECISION), PRECISION).ok),
            "rollout": info["rollout"], "launches": info["launches_per_iteration"],
            "design_state": info["design_bytes"]["state"],
            "identical": all(np.array_equal(ref[n], o[n]) for n in o),
            "rel": max(float(np.max(np.abs(ref[n] - o[n]) / np.maximum(np.abs(ref[n]), 1e-300)))
                       for n in ("loss", "grad"))}
print("RESULT" + json.dumps(out))
"""

# Each batch row against its own single-trajectory run, and set_input; ``own_checks`` (ROWS_OWN)
# adds a framework's own entries, on the batch kernel before set_input changes it.
ROWS = """
import importlib
import numpy as np
Kernel = importlib.import_module(f"backends.{FRAMEWORK}.projectile").Kernel
b = backends.get(FRAMEWORK); b.setup(DEVICE, "float64", "default")
sc = scenarios.get("projectile")
out = {}
for contact in ("hard", "soft"):
    p = sc.params({"contact": contact, "steps": 60, "iters": 3, "batch": 37})
    i = sc.inputs(p, "float64")
    k = Kernel(p, i, DEVICE, "float64", "default")
    b.synchronize(DEVICE, k.run())
    o = k.outputs()
    own = own_checks(contact, p, i, k, o)
    # each row against a single-trajectory kernel at that row's v0 and target; row 0, the seed
    # case, is the parity suite's (test_batch_row0_is_the_single_trajectory)
    p1 = sc.params({"contact": contact, "steps": 60, "iters": 3})
    rows = {}
    for row in (17, 36):
        i1 = dict(sc.inputs(p1, "float64"), v0=i["v0"][row].copy(), target=i["target"][row].copy())
        k1 = Kernel(p1, i1, DEVICE, "float64", "default")
        b.synchronize(DEVICE, k1.run())
        o1 = k1.outputs()
        rows[row] = all(np.array_equal(o1[n], o[n][:, row] if n == "loss_history" else o[n][row])
                        for n in o1)
    # set_input: new v0 for the whole batch, in place; equals a fresh kernel built at it
    v0 = (i["v0"] * 0.9)[::-1].copy()
    k.set_input("v0", v0)
    b.synchronize(DEVICE, k.run())
    o_set = k.outputs()
    k2 = Kernel(p, dict(i, v0=v0), DEVICE, "float64", "default")
    b.synchronize(DEVICE, k2.run())
    o2 = k2.outputs()
    try:
        k.set_input("v0", v0[0])
        refused = False
    except ValueError:
        refused = True
    out[contact] = {"rows": rows, "distinct": len({float(x) for x in o["loss"]}),
                    "set_input": all(np.array_equal(o_set[n], o2[n]) for n in o2),
                    "set_input_changed": not np.array_equal(o_set["grad"], o["grad"]),
                    "wrong_shape_refused": refused, "own": own}
print("RESULT" + json.dumps(out))
"""

ROWS_OWN = {
    # Taichi: its two memory orders of the [s, b] fields agree, and a batch past the 32-bit
    # index is refused before any field is allocated (allocation is disabled here, so a missing
    # guard fails the test instead of reserving ~200 GB)
    "taichi": """
def own_checks(contact, p, i, k, o):
    Kernel.layout = {"step-major": "trajectory-major", "trajectory-major": "step-major"}[k.layout]
    k_other = Kernel(p, i, DEVICE, "float64", "default")
    Kernel.layout = None
    b.synchronize(DEVICE, k_other.run())
    o_other = k_other.outputs()
    import backends.taichi.projectile as tp
    fields, tp._fields = tp._fields, None
    try:
        Kernel(sc.params({"contact": contact, "steps": 200, "iters": 0, "batch": 1 << 24}),
               i, DEVICE, "float64", "default")
        too_big_refused = False
    except ValueError as exc:
        too_big_refused = "32-bit" in str(exc)
    except TypeError:                  # reached the allocation
        too_big_refused = False
    finally:
        tp._fields = fields
    return {"too_big_refused": too_big_refused, "layouts": sorted([k.layout, k_other.layout]),
            "layout_identical": all(np.array_equal(o[n], o_other[n]) for n in o)}
""",
    "quadrants": """
def own_checks(*_):
    return {}
"""}
ROWS_OWN_EXPECTED = {"taichi": {"too_big_refused": True, "layouts": ["step-major", "trajectory-major"],
                                "layout_identical": True},
                     "quadrants": {}}
