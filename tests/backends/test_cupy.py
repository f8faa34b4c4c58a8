"""CuPy-specific checks beyond the generic parity suite (which runs CuPy's CUDA cells on a GPU).

CuPy runs on CUDA only, so on a machine without a GPU this file checks what can be checked there:
1. the package imports without CuPy (the driver imports every backend package), the CPU device
   and a missing CuPy give their reasons, and ``compare list`` shows both;
2. the CUDA C sources of the RawKernels compile with NVRTC (which needs no GPU), and the float32
   PTX has no double arithmetic (sinf's own range reduction aside);
3. the same CUDA C sources, compiled for the host by a C++ compiler behind a small shim (blockIdx,
   threadIdx as globals, one call per thread) and driven through the Kernel classes with a stand-in
   for the few cupy calls they make, agree with the float64 oracle within each scenario's derived
   bound: the kernels' logic and their argument order, without a GPU (no FMA contraction there);
4. on a GPU (skipped here): every scenario through the real worker path with graph capture,
   events and the memory figure, batch row 0 against batch = 1, set_input in place, and SAXPY's
   ``vector`` variant against the ElementwiseKernel bit for bit.
"""
from __future__ import annotations

import ctypes
import importlib
import itertools
import re
import shutil
import subprocess
import sys
import types

import numpy as np
import pytest

import backends
import scenarios
from conftest import ROOT, availability
from hand_adjoint import GPU_CASES, assert_gpu_cell_with_events_graph_and_memory, row0_and_replay

pytestmark = pytest.mark.cupy

BACKEND = backends.get("cupy")
RAW = ("sdf", "particles", "projectile")
GPU_SKIP = "CuPy's kernels are tested on the GPU machine (no CUDA device here)"


# ---- 1. import, reasons, listing -------------------------------------------------------------------
def test_package_and_kernel_modules_import_without_cupy() -> None:
    code = ("import sys; sys.modules['cupy'] = None\n"          # `import cupy` now raises ImportError
            "import importlib, json, backends\n"
            "b = backends.get('cupy')\n"
            "for s in ('saxpy', 'sdf', 'particles', 'projectile', 'launch', 'copy'):\n"
            "    importlib.import_module('backends.cupy.' + s)\n"
            "print(json.dumps(b.available()))\n")
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    avail = __import__("json").loads(proc.stdout.strip().splitlines()[-1])
    assert avail["cpu"] == "CuPy runs on CUDA devices only"
    assert avail["cuda"].startswith("cupy-cuda12x not importable")
    assert "pip install -e '.[cupy]'" in avail["cuda"]


def test_backend_facts() -> None:
    assert (BACKEND.name, BACKEND.package, BACKEND.gradient_method) == ("cupy", "cupy-cuda12x", "adjoint")
    others = [b for n, b in backends.BACKENDS.items() if n != "cupy"]
    core = [backends.get(n) for n in ("warp", "taichi", "jax", "numba")]
    assert BACKEND.display_order > max(b.display_order for b in core)
    assert BACKEND.color and BACKEND.color not in {b.color for b in others}
    assert all(BACKEND.has_kernel(s) for s in scenarios.SCENARIOS)
    assert BACKEND.variants_for("saxpy") == ("default", "vector")
    assert BACKEND.available()["cpu"] == "CuPy runs on CUDA devices only"
    # nothing on the CPU: no events, no graph, no memory figure (and no cupy import needed)
    assert BACKEND.event_timer("cpu") is None and BACKEND.capture("cpu", lambda: None) is None
    assert BACKEND.memory("cpu") == {}
    assert set(BACKEND.cache_environment(ROOT)) == {"CUPY_CACHE_DIR", "CUDA_CACHE_PATH"}


def test_compare_list_shows_cupy_and_why(compare_list) -> None:
    proc = compare_list
    line = next(line for line in proc.stdout.splitlines() if line.strip().startswith("cupy "))
    assert "gradient=adjoint" in line and "cpu: CuPy runs on CUDA devices only" in line
    assert re.search(r"cuda: (yes|no CUDA device visible to CuPy|cupy-cuda12x not importable)", line), line


# ---- 2. NVRTC compile check ------------------------------------------------------------------------
def nvrtc_module():
    """CuPy's NVRTC binding with a loadable libnvrtc, or skip with the reason."""
    try:
        from cupy_backends.cuda.libs import nvrtc
        nvrtc.getVersion()
    except Exception as exc:  # no CuPy, or no libnvrtc (the wheel does not bundle it)
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        pytest.skip(f"NVRTC not loadable here ({type(exc).__name__}: {first})")
    return nvrtc


def ptx_of(nvrtc, source: str, name: str) -> str:
    prog = nvrtc.createProgram(source, f"{name}.cu", [], [])
    try:
        nvrtc.compileProgram(prog, ["-arch=compute_90"])     # NVRTC's defaults otherwise, as CuPy
    except Exception as exc:
        raise AssertionError(f"{name}: {exc}\n{nvrtc.getProgramLog(prog)}") from exc
    ptx = nvrtc.getPTX(prog)
    return ptx.decode() if isinstance(ptx, bytes) else ptx


# sinf's slow path (Payne-Hanek reduction of huge arguments) in libdevice multiplies in double
SINF_REDUCTION = {"cvt.rn.f64.s64", "mul.f64", "cvt.rn.f32.f64"}


@pytest.mark.parametrize("precision", ["float32", "float64"])
@pytest.mark.parametrize("scenario", RAW)
def test_cuda_sources_compile_with_nvrtc(scenario: str, precision: str) -> None:
    nvrtc = nvrtc_module()
    mod = importlib.import_module(f"backends.cupy.{scenario}")
    ptx = ptx_of(nvrtc, mod.source(precision), scenario)
    assert f".entry {scenario}(" in ptx
    f64 = [line.split()[0] for line in ptx.splitlines() if ".f64" in line and not line.strip().startswith(".reg")]
    if precision == "float64":
        assert f64, "the float64 probe sees no doubles"
    elif scenario == "sdf":
        assert set(f64) <= SINF_REDUCTION and len(f64) <= 3, f64
    else:
        assert not f64, f64
    assert "fma.rn" in ptx        # NVRTC's default --fmad=true, as Warp's and Numba's defaults


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_saxpy_vector_source_moves_16_bytes_per_access(precision: str) -> None:
    """The ``vector`` variant's loads and stores are 16-byte vector instructions (what it exists
    for), its arithmetic is one FMA per lane, and the float32 kernel has no double arithmetic."""
    from backends.cupy.saxpy import vector_source, vector_width
    ptx = ptx_of(nvrtc_module(), vector_source(precision), "saxpy_vector")
    lanes, t = vector_width(precision), "f32" if precision == "float32" else "f64"
    assert re.search(rf"ld\.global(\.nc)?\.v{lanes}\.{t}", ptx), "no vector load"
    assert re.search(rf"st\.global\.v{lanes}\.{t}", ptx), "no vector store"
    assert ptx.count(f"fma.rn.{t}") >= lanes + 1        # every lane, and the tail
    if precision == "float32":
        assert ".f64" not in ptx.replace(".reg .f64", "")


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_elementwise_kernels_are_typed(precision: str) -> None:
    """CuPy parses the ElementwiseKernels' parameter lists without a GPU: every parameter has the
    cell's dtype (no weakly typed scalar that could promote float32)."""
    pytest.importorskip("cupy", reason="cupy-cuda12x not installed here")
    for scenario in ("saxpy", "copy", "launch"):
        k = importlib.import_module(f"backends.cupy.{scenario}").elementwise(precision)
        assert {p.dtype for p in (*k.in_params, *k.out_params)} == {np.dtype(precision)}, scenario


# ---- 3. the CUDA C on the host -----------------------------------------------------------------------
SHIM = r"""
#include <math.h>
#define __global__
struct emu_dim3 { unsigned int x, y, z; };
static emu_dim3 blockIdx, blockDim, threadIdx;
struct float4 { float x, y, z, w; };
struct double2 { double x, y; };
extern "C" void emu_thread(unsigned bx, unsigned by, unsigned dx, unsigned dy, unsigned tx, unsigned ty) {
    blockIdx.x = bx; blockIdx.y = by; blockDim.x = dx; blockDim.y = dy; threadIdx.x = tx; threadIdx.y = ty;
}
"""
_CTYPES = {np.dtype(np.int32): ctypes.c_int, np.dtype(np.float32): ctypes.c_float,
           np.dtype(np.float64): ctypes.c_double, np.dtype(np.int64): ctypes.c_longlong}


class HostArray(np.ndarray):
    """Stands in for cupy.ndarray: host memory with cupy's get() and set()."""

    def get(self) -> np.ndarray:
        return np.array(self)

    def set(self, value: np.ndarray) -> None:
        self[...] = value

    @property
    def data(self) -> types.SimpleNamespace:      # cupy's MemoryPointer: the address
        return types.SimpleNamespace(ptr=self.ctypes.data)


class HostRawKernel:
    """Stands in for cupy.RawKernel: the CUDA C source compiled for the host behind SHIM and
    launched one thread at a time (blocks and threads in order)."""

    def __init__(self, tmp_path, source: str, name: str) -> None:
        src = tmp_path / f"{name}-{abs(hash(source))}.cpp"
        lib = src.with_suffix(".so")
        src.write_text(SHIM + source)
        # no contraction: the host's arithmetic is the IEEE operation order the sources write
        subprocess.run(["g++", "-O1", "-shared", "-fPIC", "-ffp-contract=off", str(src), "-o", str(lib)],
                       check=True, capture_output=True, text=True)
        self.lib = ctypes.CDLL(str(lib))
        self.fn = getattr(self.lib, name)

    def __call__(self, grid, block, args) -> None:
        cargs = [ctypes.c_void_p(a.ctypes.data) if isinstance(a, np.ndarray) else _CTYPES[np.dtype(type(a))](a)
                 for a in args]
        grid, block = (tuple(grid) + (1,))[:2], (tuple(block) + (1,))[:2]
        for by, bx, ty, tx in itertools.product(range(grid[1]), range(grid[0]), range(block[1]), range(block[0])):
            self.lib.emu_thread(bx, by, block[0], block[1], tx, ty)
            self.fn(*cargs)


@pytest.fixture
def host_cupy(tmp_path, monkeypatch):
    """The kernel modules' cupy calls (asarray, empty, RawKernel) on the host; their kernel caches
    emptied before and after, so no host kernel outlives the test."""
    if shutil.which("g++") is None:
        pytest.skip("no g++ to compile the CUDA C sources for the host")
    fake = types.ModuleType("cupy")
    fake.asarray = lambda a: np.array(a).view(HostArray)
    fake.empty = lambda shape, dtype: np.zeros(shape, dtype).view(HostArray)
    fake.RawKernel = lambda source, name: HostRawKernel(tmp_path, source, name)
    monkeypatch.setitem(sys.modules, "cupy", fake)
    caches = [importlib.import_module(f"backends.cupy.{s}").compiled for s in RAW]
    caches.append(importlib.import_module("backends.cupy.saxpy").compiled_vector)
    for c in caches:
        c.cache_clear()
    yield
    for c in caches:
        c.cache_clear()


HOST_CASES = [("sdf", {}), ("sdf", {"width": 2, "height": 3}), ("particles", {"n": 200}),
              ("particles", {"n": 33, "steps": 57, "record_every": 7}),
              ("projectile", {"contact": "none"}), ("projectile", {"contact": "hard"}),
              ("projectile", {"contact": "soft"}), ("projectile", {"steps": 7, "iters": 0}),
              ("projectile", {"contact": "hard", "batch": 37, "iters": 5}),
              ("projectile", {"contact": "soft", "batch": 37, "iters": 5})]


def host_run(scenario: str, overrides: dict, precision: str, inputs: dict | None = None,
             variant: str = "default"):
    sc = scenarios.get(scenario)
    p = sc.params(overrides, quick=True)
    inputs = sc.inputs(p, precision) if inputs is None else inputs
    k = BACKEND.kernel(scenario)(p, inputs, "cuda", precision, variant)
    k.run()
    return sc, p, inputs, k


@pytest.mark.parametrize("precision", ["float64", "float32"])
@pytest.mark.parametrize("scenario,overrides", HOST_CASES, ids=[f"{s}-{o}" for s, o in HOST_CASES])
def test_cuda_sources_on_the_host_match_the_oracle(host_cupy, scenario, overrides, precision) -> None:
    sc, p, inputs, k = host_run(scenario, overrides, precision)
    out = {n: np.asarray(a) for n, a in k.outputs().items()}
    shapes = sc.output_shapes(p)
    assert {n: (a.shape, a.dtype) for n, a in out.items()} == {n: (tuple(s), np.dtype(precision)) for n, s in shapes.items()}
    check = sc.check(p, inputs, out, sc.oracle(p, inputs, precision), precision)
    assert check.ok, (check.error, check.tolerance, check.details)


@pytest.mark.parametrize("precision", ["float64", "float32"])
@pytest.mark.parametrize("n", [1, 3, 4, 5, 257, 100_003])
def test_host_saxpy_vector_covers_every_element(host_cupy, n, precision) -> None:
    """Vectors and the n % W tail together write every element once, each a * x + y in the
    cell's precision (the host does not contract, so NumPy's two roundings are exact here)."""
    sc, p, inputs, k = host_run("saxpy", {"n": n, "inputs": "random", "seed": 5}, precision,
                                variant="vector")
    S = np.dtype(precision).type
    want = S(inputs["a"]) * inputs["x"].astype(S) + inputs["y"].astype(S)
    np.testing.assert_array_equal(np.asarray(k.outputs()["out"]), want)


def test_host_batch_row0_is_the_single_trajectory(host_cupy) -> None:
    for contact in ("none", "hard", "soft"):
        _, _, _, single = host_run("projectile", {"contact": contact, "iters": 4}, "float32")
        _, _, _, batch = host_run("projectile", {"contact": contact, "iters": 4, "batch": 5}, "float32")
        a, b = single.outputs(), batch.outputs()
        for name in a:
            got = np.asarray(b[name])[:, 0] if name == "loss_history" else np.asarray(b[name])[0]
            np.testing.assert_array_equal(got, a[name], err_msg=f"{contact}: {name}")


def test_host_set_input_reruns_at_the_new_inputs(host_cupy) -> None:
    sc, p, inputs, k = host_run("projectile", {"contact": "hard", "batch": 4, "iters": 3}, "float64")
    new = {**inputs, "v0": inputs["v0"] * 1.1, "target": inputs["target"][::-1].copy()}
    k.set_input("v0", new["v0"])
    k.set_input("target", new["target"])
    k.run()
    fresh = host_run("projectile", {"contact": "hard", "batch": 4, "iters": 3}, "float64", new)[3]
    for name, value in fresh.outputs().items():
        np.testing.assert_array_equal(k.outputs()[name], value, err_msg=name)
    with pytest.raises(NotImplementedError):
        k.set_input("lr", np.array(0.1))


# ---- 4. on a GPU ---------------------------------------------------------------------------------------
def require_gpu() -> None:
    why = availability("cupy").get("cuda")
    if why:
        pytest.skip(GPU_SKIP if "no CUDA device" in why else f"{GPU_SKIP}; {why}")


@pytest.mark.parametrize("precision", ["float64", "float32"])
@pytest.mark.parametrize("scenario,overrides", GPU_CASES, ids=[f"{s}-{o}" for s, o in GPU_CASES])
def test_gpu_cell_with_events_graph_and_memory(scenario, overrides, precision) -> None:
    require_gpu()
    assert_gpu_cell_with_events_graph_and_memory("cupy", scenario, overrides, precision)


VECTOR_SCRIPT = r"""
import json, sys
import numpy as np
import backends, scenarios
b = backends.get("cupy"); b.setup("cuda", "float32", "default"); b.ensure_context("cuda")
sc = scenarios.get("saxpy")
differ = []
for precision in ("float32", "float64"):
    for n in (1, 3, 4, 5, 257, 100_003, 2**20 + 3):
        p = sc.params({"n": n, "inputs": "random", "seed": 5}); inputs = sc.inputs(p, precision)
        out = {}
        for variant in ("default", "vector"):
            k = b.kernel("saxpy")(p, inputs, "cuda", precision, variant)
            k.out.fill(np.nan); k.run(); b.synchronize("cuda", None)
            out[variant] = k.outputs()["out"]
        if out["default"].tobytes() != out["vector"].tobytes() or not np.isfinite(out["vector"]).all():
            differ.append([precision, n])
print("RESULT" + json.dumps(differ))
"""


def test_gpu_saxpy_vector_is_the_elementwise_kernel_bit_for_bit() -> None:
    """On the GPU (where NVRTC contracts both kernels' ``a * x + y`` to one FMA) the ``vector``
    variant writes the ElementwiseKernel's output bit for bit, for lengths that leave a tail of
    0 to 3 elements; outputs start as NaN, so an element neither kernel writes fails."""
    require_gpu()
    proc = subprocess.run([sys.executable, "-c", VECTOR_SCRIPT], cwd=ROOT, capture_output=True,
                          text=True, timeout=600)
    line = next((x for x in proc.stdout.splitlines() if x.startswith("RESULT")), None)
    assert line, proc.stderr[-3000:]
    assert __import__("json").loads(line[6:]) == []


GPU_SCRIPT = "import json, sys\nimport numpy as np\nimport backends, scenarios\n" + row0_and_replay("cupy", 37)


def test_gpu_batch_row0_set_input_and_graph_replay() -> None:
    require_gpu()
    proc = subprocess.run([sys.executable, "-c", GPU_SCRIPT], cwd=ROOT, capture_output=True, text=True, timeout=600)
    line = next((x for x in proc.stdout.splitlines() if x.startswith("RESULT")), None)
    assert line, proc.stderr[-3000:]
    res = __import__("json").loads(line[6:])
    assert all(res.values()), res
