"""Bouncing particles in PyTorch: the state is four vectors over particles.

Particles are independent, so one step is a handful of elementwise ops over all particles.

"default": the step loop runs on the host, 19 eager kernels per step, all in place into
preallocated buffers, so a run allocates nothing. Each contact rule is a mask
(``torch.lt(..., out=)``) and in-place masked updates: ``where(hit, bound, x, out=x)`` for the
clamped position (not ``masked_fill_``, whose CUDA kernel reads a tensor fill value back to the
host) and a multiply by ``where(hit, factor, 1)`` for the velocity, which equals
``where(hit, factor*v, v)`` exactly (v*1 = v).

"graph" (CUDA only): that eager rollout captured once with ``torch.cuda.graph`` when the kernel
is built (after a warm-up run on a side stream, as the CUDA-graph docs ask) and replayed by every
``run()``: one launch a rollout. It writes the same buffers, so the arithmetic is the default's.

"compile" and "compile_graphs": a rollout of up to ``SEGMENT`` steps (the default's 300) is one
compiled pure function (initial state in, final state and trajectory frames out; no in-place write
inside), one compiled call a run, so reduce-overhead can replay the rollout as CUDA graphs. Its
step loop is a loop over blocks of ``BLOCK`` steps, each block a
``torch.compiler.nested_compile_region``: Inductor compiles a block once (steps fused into a few
kernels) and stamps it out for every block. Unrolling all the steps into one region instead makes
the first call compile-bound and superlinear in the steps. Dynamo still traces every block call
of the compiled function, so a longer rollout (the error and horizon sweeps and the stress
experiments run up to tens of thousands of steps) runs as host calls of compiled segments of at
most ``SEGMENT`` steps, cut at frame boundaries: a few distinct segments (the first, a full one,
the last) compile, whatever the steps. Under "compile_graphs" the returned tensors live in the
CUDA graphs' memory pool, valid until the next run; between segments the state is cloned out of
it, as the CUDA Graph Trees docs ask of an output fed to the next call.

With ``record_every`` > 0 every k-th state's positions are kept (frame 0 the initial state);
without it no trajectory is kept.
"""
from __future__ import annotations

from typing import Any, Callable

import numpy as np

from scenarios.particles import CONSTANTS, INITIAL, STATE, n_frames

from . import check_variant, compiled, download, empty, kernel_info, put
from ..base import ScenarioKernel
from scenarios.particles import ParticlesParams
from ..base import Device
from scenarios.base import Precision

BLOCK = 25       # steps per nested compile region (compiled once, stamped out per block)
SEGMENT = 300    # steps per compiled call at most (whole frame intervals): the default rollout is one call


def advance(x, y, u, v, c, n: int):
    """``n`` steps in the scenario's order, functional; ``c`` = (dt, gdt, radius, lo, hi,
    neg_bounce, damping), 0-d tensors."""
    import torch
    dt, gdt, radius, lo, hi, neg_bounce, damping = c
    for _ in range(n):
        v1 = v + gdt
        x1 = x + u * dt
        y1 = y + v1 * dt
        hit = y1 < radius
        y = torch.where(hit, radius, y1)
        v = torch.where(hit, neg_bounce * v1, v1)
        u1 = torch.where(hit, damping * u, u)
        hit = x1 < lo
        x1 = torch.where(hit, lo, x1)
        u1 = torch.where(hit, neg_bounce * u1, u1)
        hit = x1 > hi
        x = torch.where(hit, hi, x1)
        u = torch.where(hit, neg_bounce * u1, u1)
    return x, y, u, v


def runs(steps: int, record_every: int, block: int) -> list[tuple[int, bool]]:
    """The rollout as (steps of one block call, whether a frame is kept after it)."""
    interval = record_every or steps
    out: list[tuple[int, bool]] = []
    done = 0
    while done < steps:
        length = min(interval, steps - done)
        done += length
        pieces = [block] * (length // block) + ([length % block] if length % block else [])
        out += [(n, False) for n in pieces[:-1]] + [(pieces[-1], bool(record_every) and length == interval)]
    return out


def segments(plan: list[tuple[int, bool]], steps_at_most: int) -> list[list[tuple[int, bool]]]:
    """``plan`` (``runs``) cut into compiled calls of at most ``steps_at_most`` steps, each whole
    frame intervals (a block is the unit when no frame is kept; an interval longer than the limit
    is one call); a rollout of no steps is one empty call."""
    units: list[list[tuple[int, bool]]] = [[]]
    framed = any(keep for _, keep in plan)
    for entry in plan:
        units[-1].append(entry)
        if entry[1] or not framed:
            units.append([])
    out: list[list[tuple[int, bool]]] = []
    total = 0       # steps of out[-1]
    for unit in filter(None, units):
        steps = sum(n for n, _ in unit)
        if out and total + steps <= steps_at_most:
            out[-1] += unit
            total += steps
        else:
            out.append(unit)
            total = steps
    return out or [[]]


def make_segment(part: list[tuple[int, bool]], initial: bool) -> Callable[..., Any]:
    """(x, y, u, v, c) -> (x, y, u, v[, frames_x, frames_y]) after ``part``'s blocks: ``advance``
    as one nested compile region, called with each block's length (an int: one compiled entry per
    distinct length); frames are the kept states, led by the initial one where ``initial``."""
    import torch
    region = torch.compiler.nested_compile_region(advance)

    def rollout(x, y, u, v, c):
        frames_x, frames_y = ([x], [y]) if initial else ([], [])
        for n, keep in part:
            x, y, u, v = region(x, y, u, v, c, n)
            if keep:
                frames_x.append(x)
                frames_y.append(y)
        if frames_x:
            return x, y, u, v, torch.stack(frames_x), torch.stack(frames_y)
        return x, y, u, v

    return rollout


class Kernel(ScenarioKernel):
    def __init__(self, params: ParticlesParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        import torch
        check_variant(variant, ("graph",))
        self.variant, self.params = variant, params
        n = params.n
        self.state0 = [put(inputs[k], precision, device) for k in INITIAL]
        dt, gravity, damping, bounce, radius = (put(inputs[k], precision, device) for k in CONSTANTS)
        one = put(1.0, precision, device)
        # derived once, rounded in the cell's dtype, as the reference does per launch
        self.c = {"dt": dt, "gdt": gravity * dt, "radius": radius, "lo": -one + radius,
                  "hi": one - radius, "neg_bounce": -bounce, "damping": damping, "one": one}
        self.consts = tuple(self.c[k] for k in ("dt", "gdt", "radius", "lo", "hi", "neg_bounce", "damping"))
        self.parts = segments(runs(params.steps, params.record_every, BLOCK), SEGMENT)
        built: dict[Any, Any] = {}
        self.calls: list[Any] = []
        for i, part in enumerate(self.parts):     # the same segment compiles once
            key = (tuple(part), i == 0 and bool(params.record_every))
            if key not in built:
                built[key] = compiled(make_segment(part, key[1]), variant, static=(*self.state0, *self.consts))
            self.calls.append(built[key])
        self.clone_between = variant == "compile_graphs"    # out of the pool the next replay reuses
        self.out: tuple[Any, ...] = ()
        if self.calls[0] is not None:
            return
        self.state = [empty((n,), precision, device) for _ in range(4)]
        self.traj = [empty((n_frames(params), n), precision, device) for _ in range(2)]
        self.tmp = empty((n,), precision, device)
        self.factor = empty((n,), precision, device)
        self.hit = torch.empty((n,), dtype=torch.bool, device=self.tmp.device)
        self.out = (*self.state, *self.traj) if params.record_every else tuple(self.state)
        self.graph = self._capture() if variant == "graph" else None

    def _capture(self) -> Any:
        import torch
        side = torch.cuda.Stream()
        side.wait_stream(torch.cuda.current_stream())
        with torch.cuda.stream(side):
            self._eager_rollout()
        torch.cuda.current_stream().wait_stream(side)
        graph = torch.cuda.CUDAGraph()
        with torch.cuda.graph(graph):
            self._eager_rollout()
        return graph

    def _eager_step(self) -> None:
        import torch
        x, y, u, v = self.state
        c, t, f, hit = self.c, self.tmp, self.factor, self.hit
        v.add_(c["gdt"])
        x.add_(torch.mul(u, c["dt"], out=t))
        y.add_(torch.mul(v, c["dt"], out=t))
        torch.lt(y, c["radius"], out=hit)
        torch.where(hit, c["radius"], y, out=y)
        v.mul_(torch.where(hit, c["neg_bounce"], c["one"], out=f))
        u.mul_(torch.where(hit, c["damping"], c["one"], out=f))
        torch.lt(x, c["lo"], out=hit)
        torch.where(hit, c["lo"], x, out=x)
        u.mul_(torch.where(hit, c["neg_bounce"], c["one"], out=f))
        torch.gt(x, c["hi"], out=hit)
        torch.where(hit, c["hi"], x, out=x)
        u.mul_(torch.where(hit, c["neg_bounce"], c["one"], out=f))

    def _eager_rollout(self) -> None:
        p = self.params
        for s, s0 in zip(self.state, self.state0):
            s.copy_(s0)
        if p.record_every:
            self.traj[0][0].copy_(self.state[0])
            self.traj[1][0].copy_(self.state[1])
        for s in range(p.steps):
            self._eager_step()
            if p.record_every and (s + 1) % p.record_every == 0:
                f = (s + 1) // p.record_every
                self.traj[0][f].copy_(self.state[0])
                self.traj[1][f].copy_(self.state[1])

    def _segmented(self) -> tuple[Any, ...]:
        import torch
        state, frames, last = tuple(self.state0), [], len(self.calls) - 1
        for i, call in enumerate(self.calls):
            out = call(*state, self.consts)
            if self.clone_between and i < last:
                out = tuple(t.clone() for t in out)
            state = out[:4]
            frames.append(out[4:])
        if not self.params.record_every:
            return state
        return (*state, *(torch.cat([f[k] for f in frames if f]) for k in (0, 1)))

    def run(self) -> Any:
        if self.calls[0] is not None:
            self.out = self.calls[0](*self.state0, self.consts) if len(self.calls) == 1 else self._segmented()
        elif self.graph is not None:
            self.graph.replay()
        else:
            self._eager_rollout()
        return self.out

    def outputs(self) -> dict[str, np.ndarray]:
        names = (*STATE, "traj_x", "traj_y") if self.params.record_every else STATE
        return dict(zip(names, (download(a) for a in self.out)))

    def info(self) -> dict[str, Any]:
        if self.calls[0] is not None:
            blocks = [e for p in self.parts for e in p]
            calls = len(self.calls)
            loop = ("the whole rollout in one compiled call" if calls == 1 else
                    f"host loop over {calls} compiled calls of at most SEGMENT = {SEGMENT} steps "
                    f"({len({id(c) for c in self.calls})} compiled)")
            return kernel_info(self.variant, loop=loop,
                               compiled_unit=f"{len(blocks)} calls of nested compile regions of "
                                             f"{sorted({n for n, _ in blocks})} steps (BLOCK = {BLOCK})")
        return kernel_info(self.variant, loop="host loop over steps, vectorised over particles",
                           kernels_per_step=19, captured=self.graph is not None)
