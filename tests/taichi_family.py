"""What the tests of Taichi and of Quadrants (Taichi's maintained fork) share: the cells each
framework's tests run through the worker (one conftest.shared_cell group per framework, which
tests/backends/test_taichi_family.py and the framework's own file both read), the parametrization of the
checks that hold for both (tests/backends/test_taichi_family.py) and their scripts. Each framework's own
checks stay in tests/backends/test_taichi.py and tests/backends/test_quadrants.py."""
from __future__ import annotations

import pytest

import backends
from conftest import run_script, shared_cell
from oracle_checks import FRAMES

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
# the single-trajectory projectile cells whose gradient at v0 (iteration 0's, whatever the iters)
# tests/backends/test_taichi.py checks against finite differences: the parity suite's cases
GRADIENT = [{"contact": c} for c in ("hard", "soft")]
# the cells only tests/backends/test_taichi.py reads: gradients on every device, trajectory frames
OWN_CELLS = {"taichi": [("taichi", "projectile", "float64", o, d, "default")
                        for o in GRADIENT for d in backends.DEVICES]
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


def each(cases: dict[str, list] | None = None, *, group: str | None = None, early: tuple[str, ...] = (),
         slow: bool = False) -> list:
    """A pytest.param per framework (per case of ``cases[framework]``, its values after the
    framework's name), marked with its framework (so `-m taichi` / `-m quadrants` select it), with
    ``group`` the framework's xdist_group f"{framework}-{group}" (its "cells", or the "rollouts"
    script's tests), ``early`` where the framework is listed (Taichi's long script tests start
    first, as they did in its own file), ``slow`` the long tier's."""
    out = []
    for fw in FRAMEWORKS:
        marks = [getattr(pytest.mark, fw)] + [pytest.mark.xdist_group(f"{fw}-{group}")] * bool(group) \
            + [pytest.mark.early] * (fw in early) + [pytest.mark.slow] * slow
        for case in (cases[fw] if cases else [()]):
            out.append(pytest.param(fw, *case, marks=marks, id="-".join(map(str, (fw, *case)))))
    return out


# The projectile's rollout paths in one process per framework, device, precision and CONTACTS (a
# framework start, and the kernels the checks share built once), at 24 steps over 2 s (every
# trajectory reaches the ground) and 3 descent iterations, for each contact of CONTACTS:
# - variants: the named VARIANTS (the framework's, without Taichi's 'checkpoint', its own test)
#   against the default rollout at a batch of 37, built as the driver builds them;
# - paths: the fused backward pass against one launch per step for a single trajectory, at row
#   17's v0 and target;
# - rows (with ROWS; hard and soft contact, which CONTACTS then holds): rows 17 and 36 of the
#   default batch kernel against single-trajectory runs at their v0 and target (row 17's: the
#   paths' fused kernel; row 0, the seed case, is the parity suite's
#   test_batch_row0_is_the_single_trajectory), then set_input: a new v0 for the whole batch, in
#   place, against a kernel built at it (``fresh``, ROWS_OWN's, which with ``own_checks`` and
#   ``own_fresh`` adds a framework's own entries).
ROLLOUTS = """
import importlib
import numpy as np
Kernel = importlib.import_module(f"backends.{FRAMEWORK}.projectile").Kernel
b = backends.get(FRAMEWORK); b.setup(DEVICE, PRECISION, "default")
sc = scenarios.get("projectile")
chosen = Kernel.fused               # the framework's own choice, restored after forcing either path

def launched(k):
    b.synchronize(DEVICE, k.run())
    return k, k.outputs()

def rel(o, ref, names):
    return max(float(np.max(np.abs(o[n] - ref[n]) / np.maximum(np.abs(ref[n]), 1e-300))) for n in names)

out = {"variants": {}, "paths": {}, "rows": {} if ROWS else None}
for contact in CONTACTS:
    p = sc.params({"contact": contact, "steps": 24, "dt": 2.0 / 24, "iters": 3, "batch": 37})
    i = sc.inputs(p, PRECISION)
    oracle = sc.oracle(p, i, PRECISION)
    batch = {}
    for variant in ("default",) + tuple(VARIANTS):
        k, o = batch[variant] = launched(Kernel(p, i, DEVICE, PRECISION, variant))
        info, ref = k.info(), batch["default"][1]
        out["variants"][f"{contact}-{variant}"] = {
            "ok": bool(sc.check(p, i, o, oracle, PRECISION).ok),
            "rollout": info["rollout"], "launches": info["launches_per_iteration"],
            "design_state": info["design_bytes"]["state"],
            "identical": all(np.array_equal(ref[n], o[n]) for n in o), "rel": rel(o, ref, ("loss", "grad"))}

    p1 = sc.params({"contact": contact, "steps": 24, "dt": 2.0 / 24, "iters": 3})
    single = {r: dict(sc.inputs(p1, PRECISION), v0=i["v0"][r].copy(), target=i["target"][r].copy())
              for r in (17, 36)}
    oracle1 = sc.oracle(p1, single[17], PRECISION)
    res = {}
    for fused in (True, False):
        Kernel.fused = fused
        k1, o1 = launched(Kernel(p1, single[17], DEVICE, PRECISION, "default"))
        res[fused] = (k1, o1, bool(sc.check(p1, single[17], o1, oracle1, PRECISION).ok), k1.info())
    Kernel.fused = chosen
    (_, o1, ok, info), (_, o_step, ok_step, info_step) = res[True], res[False]
    out["paths"][f"{PRECISION}-{contact}"] = {
        "ok": [ok, ok_step], "fused_flags": [info["fused_rollout"], info_step["fused_rollout"]],
        "shapes": {n: [list(o1[n].shape), list(o_step[n].shape)] for n in o1},
        "identical": all(np.array_equal(o1[n], o_step[n]) for n in o1), "rel": rel(o1, o_step, ("loss", "grad"))}

    if not ROWS:
        continue
    k, o = batch["default"]
    own = own_checks(contact, p, i, k)      # before set_input changes k
    o36 = launched(Kernel(p1, single[36], DEVICE, PRECISION, "default"))[1]
    rows = {r: all(np.array_equal(o_r[n], o[n][:, r] if n == "loss_history" else o[n][r]) for n in o_r)
            for r, o_r in ((17, o1), (36, o36))}
    v0 = (i["v0"] * 0.9)[::-1].copy()
    k.set_input("v0", v0)
    o_set = launched(k)[1]
    k2, o2 = launched(fresh(k, p, dict(i, v0=v0)))
    try:
        k.set_input("v0", v0[0])
        refused = False
    except ValueError:
        refused = True
    same = all(np.array_equal(o_set[n], o2[n]) for n in o2)
    out["rows"][contact] = {"rows": rows, "distinct": len({float(x) for x in o["loss"]}),
                            "set_input": same, "set_input_changed": not np.array_equal(o_set["grad"], o["grad"]),
                            "wrong_shape_refused": refused, "own": {**own, **own_fresh(k, k2, same)}}
print("RESULT" + json.dumps(out))
"""

ROWS_OWN = {
    # Taichi: a batch past the 32-bit index is refused before any field is allocated (allocation
    # is disabled here, so a missing guard fails the test instead of reserving ~200 GB); the
    # kernel set_input's outputs are compared with is built in the other memory order of the
    # [s, b] fields (the exp store's too, with soft contact), so the comparison also shows that
    # the two orders agree
    "taichi": """
def own_checks(contact, p, i, k):
    import backends.taichi.projectile as tp
    fields, tp._fields = tp._fields, None
    try:
        Kernel(sc.params({"contact": contact, "steps": 200, "iters": 0, "batch": 1 << 24}),
               i, DEVICE, PRECISION, "default")
        too_big_refused = False
    except ValueError as exc:
        too_big_refused = "32-bit" in str(exc)
    except TypeError:                  # reached the allocation
        too_big_refused = False
    finally:
        tp._fields = fields
    return {"too_big_refused": too_big_refused}

def fresh(k, p, i):
    Kernel.layout = {"step-major": "trajectory-major", "trajectory-major": "step-major"}[k.layout]
    try:
        return Kernel(p, i, DEVICE, PRECISION, "default")
    finally:
        Kernel.layout = None

def own_fresh(k, k2, same):
    return {"layouts": sorted([k.layout, k2.layout]), "layout_identical": same}
""",
    "quadrants": """
def own_checks(*_):
    return {}

def fresh(k, p, i):
    return Kernel(p, i, DEVICE, PRECISION, "default")

def own_fresh(*_):
    return {}
"""}
ROWS_OWN_EXPECTED = {"taichi": {"too_big_refused": True, "layouts": ["step-major", "trajectory-major"],
                                "layout_identical": True},
                     "quadrants": {}}
