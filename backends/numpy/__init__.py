"""NumPy: vectorised array code on the CPU, the seeds' baseline ("compare the timing to NumPy").

Each scenario is written the way one writes NumPy for speed, not as a loop over items: whole-array
ufuncs over the items (a Python loop over time steps is inherent to the time-stepping scenarios),
buffers allocated once in the constructor and reused through ``out=``/``where=``, so ``run()``
allocates nothing that grows with the problem. Every operation is Warp's, in Warp's order (NumPy
never contracts a*x + y into an FMA), and every constant is a scalar of the cell's dtype: under
NEP 50 a float32 array stays float32 with a float32 scalar, and ``out=`` would otherwise hide a
float64 computation behind a same-kind cast. NumPy runs one thread per ufunc and computes eagerly,
so ``synchronize`` has nothing to wait for. The package is named like the framework; every module
in it imports NumPy absolutely (``import numpy as np``), which never finds this package.
"""
from __future__ import annotations

import importlib.metadata
from typing import Any

from scenarios.base import dtype_of

from ..base import Backend, not_installed


def scalar_type(precision: str):
    """The NumPy scalar type of the cell's precision (np.float32 or np.float64)."""
    return dtype_of(precision)


def kernel_info(**extra: Any) -> dict[str, Any]:
    """What ``ScenarioKernel.info`` reports: single-threaded vectorised ufuncs."""
    return {"vectorised": "numpy ufuncs over the items, preallocated out= buffers", "threads": 1,
            **extra}


class NumpyBackend(Backend):
    name = "numpy"
    title = "NumPy"
    package = "numpy"
    is_cpu_baseline = True
    gradient_method = "adjoint"          # hand-written discrete adjoint: NumPy has no autodiff
    # The baseline comes last in tables (after warp 0 ... numba 3 and the newer ports at 4 and up),
    # in grey (tab10 C7): no other backend's hue, told apart by lightness alone, so it stays
    # readable for colour-blind readers among eight backends.
    display_order, color = 9, "C7"

    def available(self) -> dict[str, str | None]:
        reason = not_installed("numpy", self.package)
        return {"cpu": reason, "cuda": reason or "NumPy runs on the CPU only"}

    def versions(self) -> dict[str, str]:
        try:
            return {"numpy": importlib.metadata.version("numpy")}
        except importlib.metadata.PackageNotFoundError:
            import numpy as np
            return {"numpy": np.__version__}

    def synchronize(self, device: str, result: Any) -> None:
        """Nothing to wait for: every ufunc has finished when it returns."""


BACKEND = NumpyBackend()
