"""NVIDIA Warp, the reference backend."""
from __future__ import annotations

import functools
from pathlib import Path
from typing import Any, Callable

from ..base import Backend, Precision, not_installed


def wp_device(device: str) -> str:
    return "cuda:0" if device == "cuda" else "cpu"


def wp_scalar(precision: Precision) -> Any:
    """Warp's scalar type of the cell's precision (this backend's one map from Precision)."""
    import warp as wp
    return {Precision.FLOAT32: wp.float32, Precision.FLOAT64: wp.float64}[precision]


# Scenarios whose run() is one fixed launch, so Warp's recorded launch command can replay it.
RECORDABLE = ("saxpy", "sdf", "particles", "launch", "copy")


def launcher(variant: str, kernel: Any, dim: Any, inputs: list, outputs: list,
             device: str) -> Callable[[], Any]:
    """What ``run()`` calls to launch ``kernel``. Variant ``record_cmd``: ``wp.launch(...,
    record_cmd=True)`` once, then its ``wp.Launch`` replayed (Warp's documented lighter launch
    path: the arguments are packed once, not at every call; the same kernel, the same stream).
    Otherwise ``wp.launch`` with the same arguments at every call."""
    import warp as wp
    if variant == "record_cmd":
        return wp.launch(kernel, dim=dim, inputs=inputs, outputs=outputs, device=device,
                         record_cmd=True).launch
    return functools.partial(wp.launch, kernel, dim=dim, inputs=inputs, outputs=outputs,
                             device=device)


class WarpBackend(Backend):
    name = "warp"
    package = "warp-lang"
    gradient_method = "tape"
    is_reference = True
    display_order, color = 0, "C0"
    # projectile (projectile.py): "checkpoint" keeps segment boundaries and re-runs each segment
    # in the backward pass; "tape_zero" clears every gradient with tape.zero() (the default: v's);
    # "unrolled" keeps the state in per-thread locals (the step loop unrolled at compile time)
    # "tile": SAXPY's block-cooperative tile loads (saxpy.py); "record_cmd": see ``launcher``
    comparison_variants = ("tape_zero",)
    scenario_variants = {"projectile": ("checkpoint", "tape_zero", "unrolled"),
                         **{sc: ("record_cmd",) for sc in RECORDABLE},
                         "saxpy": ("tile", "record_cmd")}
    control_variants = {"particles": {
        "racy-one-launch": "the seed's single launch over (step, particle): step s reads what "
                           "step s-1 of the same launch has not yet written"}}

    def cache_environment(self, cache_dir: Path) -> dict[str, str]:
        return {"WARP_CACHE_PATH": str(cache_dir / "warp"),
                "CUDA_CACHE_PATH": str(cache_dir / "cuda-driver-jit")}

    def ensure_context(self, device: str) -> None:
        import warp as wp
        wp.get_device(wp_device(device)).context   # noqa: B018 (creates the CUDA context)

    def capture(self, device: str, run: Any) -> Any:
        """``wp.ScopedCapture`` of one call, replayed with ``wp.capture_launch`` (Warp's documented
        way to remove per-launch CPU overhead); CUDA only."""
        if device != "cuda":
            return None
        import warp as wp
        with wp.ScopedCapture(device=wp_device(device)) as cap:
            run()
        graph = cap.graph
        return lambda: wp.capture_launch(graph)

    def event_timer(self, device: str) -> "WarpEvents | None":
        return WarpEvents(device) if device == "cuda" else None

    def available(self) -> dict[str, str | None]:
        reason = not_installed("warp", self.package)
        if reason:
            return {"cpu": reason, "cuda": reason}
        import warp as wp
        wp.config.quiet = True
        wp.init()
        return {"cpu": None,
                "cuda": None if wp.is_cuda_available() else "no CUDA device visible to Warp"}

    def versions(self) -> dict[str, str]:
        import warp as wp
        return {"warp": wp.config.version}

    def setup(self, device: str, precision: str, variant: str) -> None:
        import warp as wp
        wp.config.quiet = True
        wp.init()

    def synchronize(self, device: str, result: Any) -> None:
        import warp as wp
        wp.synchronize_device(wp_device(device))

    def memory(self, device: str) -> dict[str, Any]:
        """High-water mark of Warp's CUDA memory pool (cudaMallocAsync); nothing on the CPU."""
        if device != "cuda":
            return {}
        import warp as wp
        dev = wp_device(device)
        if not wp.is_mempool_enabled(dev):
            return {"device_memory_source": "warp mempool disabled on this device (see nvml_*)"}
        return {"device_peak_bytes": int(wp.get_mempool_used_mem_high(dev)),
                "device_memory_source": "warp mempool high-water mark"}


class WarpEvents:
    description = "CUDA events (wp.Event on the device's current stream) around run()"

    def __init__(self, device: str) -> None:
        import warp as wp
        self.wp, self.dev = wp, wp_device(device)
        self.a = wp.Event(self.dev, enable_timing=True)
        self.b = wp.Event(self.dev, enable_timing=True)

    def start(self) -> None:
        self.wp.get_stream(self.dev).record_event(self.a)

    def stop(self) -> None:
        self.wp.get_stream(self.dev).record_event(self.b)

    def elapsed_s(self) -> float:
        return self.wp.get_event_elapsed_time(self.a, self.b) * 1e-3   # milliseconds


BACKEND = WarpBackend()
