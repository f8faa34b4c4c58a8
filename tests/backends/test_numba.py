"""Numba-specific checks beyond the generic parity suite.

1. float32 discipline: the float32 specialisations compile to code without any double arithmetic
   (Python float literals would promote to float64), and agree with Warp's float32 output;
2. the hand-written projectile adjoint against float64 central finite differences, and the
   batched projectile: every row is the single-trajectory run bit for bit, in every variant.
Its CUDA kernels: tests/backends/test_numba_cuda.py.
"""
from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
import pytest

import backends
import scenarios
from conftest import require_device, shared_cell

pytestmark = pytest.mark.numba
pytest.importorskip("numba")

BACKEND = backends.get("numba")
TINY = {"saxpy": {"n": 37}, "sdf": {"width": 11, "height": 7},
        "particles": {"n": 37, "steps": 20, "record_every": 6},
        "projectile": {"contact": "soft", "steps": 80, "iters": 3}}


def build(scenario: str, overrides: dict, precision: str, variant: str = "default",
          inputs: dict | None = None, quick: bool = False):
    sc = scenarios.get(scenario)
    p = sc.params(overrides, quick=quick)
    inputs = sc.inputs(p, precision) if inputs is None else inputs
    k = BACKEND.kernel(scenario)(p, inputs, "cpu", precision, variant)
    k.run()
    return sc, p, inputs, k


# the tests that compile Numba kernels in this process share one xdist worker: Numba keeps no
# compiled code between processes, so each kernel (scenario, precision, fastmath) compiles once
IN_PROCESS = pytest.mark.xdist_group("numba-in-process")


def llvm_ir(kernel, precision: str) -> tuple[str, str]:
    """(signature, LLVM IR) of the kernel's specialisation for ``precision``: the compiled body,
    the parfor gufunc and inlined helpers; without the CPython wrapper, whose unboxing of a
    float32 argument goes through PyFloat_AsDouble, and without declarations."""
    (sig, ir), = [(sig, ir) for sig, ir in kernel.fn.inspect_llvm().items()
                  if ("float32" in str(sig)) == (precision == "float32")]
    bodies = [f for f in ir.split("\ndefine ")[1:] if "@_ZN7cpython" not in f.split("(", 1)[0]]
    return str(sig), "\n".join(f.split("\n}", 1)[0] for f in bodies)


# ---- 1. float32 discipline -----------------------------------------------------------------------
# the fastmath kernels of saxpy, sdf and particles compile for this probe alone: the long tier runs
# them; the fast tier keeps their default kernels (the same source, typed alike: fastmath sets
# LLVM's flags, not types) and the projectile's fastmath one (the batch tests below compile it)
F32_PROBES = [pytest.param(s, v, marks=[pytest.mark.slow] if v == "fastmath" and s != "projectile" else [])
              for s in TINY for v in BACKEND.variants]


@IN_PROCESS
@pytest.mark.parametrize("scenario,variant", F32_PROBES)
def test_float32_has_no_double_arithmetic(scenario: str, variant: str) -> None:
    sig, ir = llvm_ir(build(scenario, TINY[scenario], "float32", variant)[3], "float32")
    assert "float64" not in sig
    assert " double " not in ir, [line for line in ir.splitlines() if " double " in line][:5]


# particles' float64 kernel compiles for this control and the float64 chunks below alone: the long
# tier runs them; the fast tier keeps the control on the projectile's kernel (a parallel loop too)
# and the chunks in float32
@IN_PROCESS
@pytest.mark.parametrize("scenario", [pytest.param(s, marks=[pytest.mark.slow] if s == "particles" else [])
                                      for s in TINY])
def test_float64_ir_probe_sees_doubles(scenario: str) -> None:
    """The probe above is meaningful: the float64 specialisation is full of doubles."""
    assert " double " in llvm_ir(build(scenario, TINY[scenario], "float64")[3], "float64")[1]


# the parity suite's float32 cases: Numba's are run in this xdist group already
F32_VS_WARP = [("saxpy", {}), ("saxpy", {"n": 257, "inputs": "random", "seed": 3}), ("sdf", {}),
               ("particles", {}),       # quick: n = 1000, CPU chunks and a tail
               ("particles", {"n": 33, "steps": 57, "record_every": 7}),       # frames: a chunk per thread
               ("projectile", {"contact": "none"}), ("projectile", {"contact": "hard"}),
               ("projectile", {"contact": "soft"})]
# frames at the quick size need a Numba worker of their own: the long tier runs them; the fast tier
# keeps the quick size's chunks and tail, and frames in chunks (the case above)
F32_VS_WARP_SLOW = [("particles", {"n": 1000, "steps": 300, "record_every": 7})]
MAX_ULP = 2


@pytest.mark.xdist_group("numba-cells")        # with the parity suite's numba cells (conftest.run_cases)
@pytest.mark.parametrize("scenario,overrides", F32_VS_WARP + [pytest.param(*c, marks=pytest.mark.slow)
                                                              for c in F32_VS_WARP_SLOW],
                         ids=[f"{s}-{o}" for s, o in F32_VS_WARP + F32_VS_WARP_SLOW])
def test_float32_agrees_with_warp(scenario: str, overrides: dict) -> None:
    """Same algorithm, same operation order: a couple of ulps at most (bitwise on x86 CPUs).

    For the projectile only loss and gradient at v0 are compared ulp-wise: the soft contact's
    gradient-descent history amplifies one-ulp differences enormously (see projectile.py).
    """
    require_device("numba", "cpu")
    require_device(backends.reference(), "cpu")
    outs = {}
    shared = F32_VS_WARP if (scenario, overrides) in F32_VS_WARP else [(scenario, overrides)]
    every = [(b, s, "float32", o, "cpu", "default") for b in ("numba", backends.reference()) for s, o in shared]
    for name in ("numba", backends.reference()):
        record, outs[name] = shared_cell("numba-cells", every, name, scenario, "float32", overrides)
        assert record["status"] == "ok", record.get("reason")
    ours, ref = outs["numba"], outs[backends.reference()]
    keys = ("loss", "grad") if scenario == "projectile" else ref.keys()
    for key in keys:
        assert ours[key].dtype == np.float32, key
        np.testing.assert_array_max_ulp(ours[key], ref[key], maxulp=MAX_ULP, dtype=np.float32)


@functools.cache
def serial_rollout(S: type[np.floating]) -> Callable[..., np.ndarray]:
    """One particle after another through the port's step, every step in order (compiled once per
    precision, for every n of the test below)."""
    from numba import njit
    from backends.numba import particles as port
    step = njit(port.step_function(S))

    @njit
    def serial(steps, every, dt, g, damping, bounce, radius, x0, y0, vx0, vy0, tx, ty):
        out = np.empty((4, x0.shape[0]), x0.dtype)
        lo, hi = S(-1.0) + radius, S(1.0) - radius
        for q in range(x0.shape[0]):
            x, y, u, v = x0[q], y0[q], vx0[q], vy0[q]
            tx[0, q], ty[0, q] = x, y
            for s in range(steps):
                x, y, u, v = step(x, y, u, v, g * dt, dt, damping, bounce, radius, lo, hi)
                if (s + 1) % every == 0:
                    tx[(s + 1) // every, q], ty[(s + 1) // every, q] = x, y
            out[0, q], out[1, q], out[2, q], out[3, q] = x, y, u, v
        return out
    return serial


# float64: the long tier (its kernel compiles for it alone, as for test_float64_ir_probe_sees_doubles);
# the fast tier keeps every chunk and tail in float32
@IN_PROCESS
@pytest.mark.parametrize("precision", ("float32", pytest.param("float64", marks=pytest.mark.slow)))
@pytest.mark.parametrize("n", (1, 3, 300, 1000))
def test_particles_cpu_chunks_are_the_per_particle_rollout_bit_for_bit(n: int, precision: str) -> None:
    """The CPU kernel runs steps outside and a chunk of particles inside (for SIMD); it must write
    what one serial rollout per particle writes, trajectory frames included, for every chunk and
    tail (chunks of up to CHUNK particles, fewer when n is small)."""
    from backends.numba import particles as port
    sc, p, inputs, k = build("particles", {"n": n, "steps": 203, "record_every": 5}, precision)
    assert k.args[2] == port.cpu_chunk(n) and (n < 300 or -(-n // k.args[2]) > 1)
    S = np.dtype(precision).type
    frames = np.empty((2, p.steps // p.record_every + 1, n), S)
    want = serial_rollout(S)(p.steps, p.record_every, *(S(inputs[c]) for c in port.CONSTANTS),
                             *(inputs[c] for c in ("x0", "y0", "vx0", "vy0")), frames[0], frames[1])
    got = k.outputs()
    for i, name in enumerate(port.STATE):
        assert got[name].tobytes() == want[i].tobytes(), name
    assert got["traj_x"].tobytes() == frames[0].tobytes() and got["traj_y"].tobytes() == frames[1].tobytes()


# ---- 2. the hand-written adjoint -----------------------------------------------------------------
@IN_PROCESS
@pytest.mark.parametrize("contact", ("none", "hard", "soft"))
@pytest.mark.parametrize("v0", ((2.0, 6.5), (1.3, 8.1)))
def test_adjoint_matches_central_differences(contact: str, v0: tuple[float, float]) -> None:
    overrides = {"contact": contact, "iters": 0, "vx0": v0[0], "vy0": v0[1]}
    sc, p, inputs, k = build("projectile", overrides, "float64")
    grad = k.outputs()["grad"]
    if contact == "hard":
        assert k.arrays["hit"].any(), "the contact must fire for the test to mean anything"
    if contact == "soft":
        assert (k.arrays["ys"] < 0).any(), "the projectile must penetrate the soft ground"

    def loss(v: np.ndarray) -> float:
        return float(build("projectile", overrides, "float64", inputs={**inputs, "v0": v})[3]
                     .outputs()["loss"])

    h = 1e-6
    fd = np.array([(loss(inputs["v0"] + h * e) - loss(inputs["v0"] - h * e)) / (2 * h)
                   for e in np.eye(2)])
    np.testing.assert_allclose(grad, fd, rtol=1e-6, atol=1e-6 * np.abs(grad).max())
    # and the scenario's float64 reference (closed form / python adjoint), to rounding
    np.testing.assert_allclose(grad, sc.oracle(p, inputs, "float64")["grad"], rtol=1e-12, atol=1e-12)


BATCH = {"batch": 6, "steps": 80, "iters": 3}


# the projectile's float64 fastmath kernel compiles for these alone: the long tier runs them; the
# fast tier keeps fastmath in float32 and float64 in the default variant
BATCH_CASES = [pytest.param(c, p, v, id=f"{c}-{p}-{v}",
                            marks=[pytest.mark.slow] if (p, v) == ("float64", "fastmath") else [])
               for c in ("hard", "soft") for p in ("float64", "float32") for v in BACKEND.variants]


@IN_PROCESS
@pytest.mark.parametrize("contact,precision,variant", BATCH_CASES)
def test_batch_rows_are_single_trajectories(contact: str, precision: str, variant: str) -> None:
    """Every row b of a batch equals the single-trajectory kernel run at (v0[b], target[b]) bit for
    bit: the prange indexes each trajectory's inputs, tape and outputs correctly, and its
    arithmetic does not depend on B (the parity suite checks row 0 in the default variant)."""
    overrides = {"contact": contact, **BATCH}
    sc, p, inputs, k = build("projectile", overrides, precision, variant)
    out = k.outputs()
    assert {n: (a.shape, a.dtype) for n, a in out.items()} == \
        {n: (shape, np.dtype(precision)) for n, shape in sc.output_shapes(p).items()}
    assert len({tuple(r) for r in out["grad"]}) == p.batch      # distinct trajectories
    for b in range(p.batch):
        one = build("projectile", {**overrides, "batch": 1}, precision, variant,
                    inputs={**inputs, "v0": inputs["v0"][b], "target": inputs["target"][b]})[3]
        for name, a in one.outputs().items():
            row = out[name][:, b] if name == "loss_history" else out[name][b]
            assert row.tobytes() == a.tobytes(), (b, name, row, a)
        if contact == "hard":
            assert one.arrays["hit"].any(), "the contact must fire for the test to mean anything"


@IN_PROCESS
def test_batch_set_input_moves_every_trajectory() -> None:
    """set_input('v0', (B, 2)) reruns the compiled kernel at the new points: same outputs as a
    kernel built there; and the single case keeps its (2,) shape."""
    overrides = {"contact": "soft", **BATCH}
    sc, p, inputs, k = build("projectile", overrides, "float64")
    moved = inputs["v0"] * np.array([1.1, 0.9]) + 0.05
    k.set_input("v0", moved)
    k.run()
    fresh = build("projectile", overrides, "float64", inputs={**inputs, "v0": moved})[3]
    for name, a in fresh.outputs().items():
        assert k.outputs()[name].tobytes() == a.tobytes(), name
    single = build("projectile", {**overrides, "batch": 1}, "float64",
                   inputs={**inputs, "v0": inputs["v0"][3], "target": inputs["target"][3]})[3]
    single.set_input("v0", moved[3])
    single.run()
    assert single.outputs()["grad"].tobytes() == k.outputs()["grad"][3].tobytes()


@IN_PROCESS
def test_cpu_projectile_is_a_parallel_loop() -> None:
    """The CPU path is a prange over trajectories: Numba turned it into a parfor gufunc."""
    k = build("projectile", {"contact": "soft", **BATCH}, "float32")[3]
    assert "__numba_parfor_gufunc" in llvm_ir(k, "float32")[1]
    info = k.info()
    assert info["parallel"] and info["threads"] >= 1 and info["tape_layout"] == "(batch, steps)"
