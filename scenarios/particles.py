"""Bouncing particles in a box (the seed's physics), integrated with semi-implicit Euler.

One step, per particle, in this exact order (every backend does the same):
    v += gravity*dt;  x += u*dt;  y += v*dt
    if y < radius:          y = radius;        v = -bounce*v;  u = damping*u
    if x < -1 + radius:     x = -1 + radius;   u = -bounce*u
    if x >  1 - radius:     x =  1 - radius;   u = -bounce*u
Particles are independent, so a thread per particle may loop over all steps; what is forbidden is
the seed's single launch over (step, particle), where step s reads what step s-1 has not yet
written.

Initial state (deterministic): particle i of n sits on the circle of radius 0.5 centred at (0, 1),
at angle 2*pi*i/n; velocities come from numpy's default_rng(seed): u ~ U(-1, 1), v ~ U(0, 2).
The physical constants are rounded to the cell's precision and passed as inputs, so the float64
oracle solves exactly the problem the port solves and the measured error is arithmetic alone.

Error check. Contacts make the final state discontinuous in the data: a particle that reaches a
wall within rounding distance of the threshold may bounce one step earlier or later in another
precision, which changes its state by O(|v| dt). The oracle therefore carries, per particle, a
first-order running bound on the rounding error of each coordinate (every operation adds u times
the size of its operands; a floor clamp resets the position error to 0, a wall clamp to the
rounding of +-1 -/+ radius, and clamps scale velocity error by the restitution factor)
and the smallest distance to a contact threshold seen during the run.
The float64 oracle itself obeys the same bound with u64, so the bound is computed with u + u64.
A particle is *well-conditioned* if that distance always exceeds the position error bound at the
time: then every port that rounds no worse than the bound takes the same branches, and its final
state must lie within the bound. Ill-conditioned particles are counted and reported, not checked.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from .base import Check, Precision, Sample, Scenario, UNIT_ROUNDOFF, dtype_of, require

# The input and output names every port uses, in kernel-argument order (one list for all ports).
CONSTANTS = ("dt", "gravity", "damping", "bounce", "radius")
INITIAL = ("x0", "y0", "vx0", "vy0")
STATE = ("x", "y", "vx", "vy")
BIG_N = 1 << 22      # from here a cell is first timed in miniature (compare.planning.calibrate)
# particles checked against the oracle unless told otherwise: above this many, a seeded sample
# (its float64 rollout is one NumPy pass per step; all 2^24 particles took 14 minutes of a cell)
PARTICLES_CHECKED = 1 << 16


@dataclasses.dataclass(frozen=True)
class ParticlesParams:
    n: int = 256
    steps: int = 300
    dt: float = 0.01
    gravity: float = -9.8
    damping: float = 0.985
    bounce: float = 0.82
    radius: float = 0.03
    seed: int = 0
    record_every: int = 0      # 0: final state only; k > 0: also keep every k-th state

    def validate(self) -> None:
        require(1 <= self.n <= 2**31 - 1, f"n must be in [1, 2^31-1], got {self.n}")
        require(0 <= self.steps <= 10**9, f"steps must be in [0, 1e9], got {self.steps}")
        require(math.isfinite(self.dt) and 0.0 < self.dt <= 1.0,
                f"dt must be finite and in (0, 1], got {self.dt}")
        require(math.isfinite(self.gravity) and abs(self.gravity) <= 1e6,
                f"gravity must be finite with |gravity| <= 1e6, got {self.gravity}")
        require(math.isfinite(self.damping) and 0.0 <= self.damping <= 10.0,
                f"damping must be in [0, 10], got {self.damping}")
        require(math.isfinite(self.bounce) and 0.0 <= self.bounce <= 10.0,
                f"bounce must be in [0, 10], got {self.bounce}")
        require(math.isfinite(self.radius) and 0.0 < self.radius < 0.5,
                f"radius must be in (0, 0.5), got {self.radius}")
        require(self.seed >= 0, f"seed must be >= 0, got {self.seed}")
        require(self.record_every >= 0, f"record_every must be >= 0, got {self.record_every}")
        if self.record_every:
            frames = self.steps // self.record_every + 1
            require(frames * self.n <= 2**31 - 1,
                    f"record_every={self.record_every} keeps {frames} frames of {self.n} particles; "
                    "that is over 2^31 values, raise record_every")


def initial_state(params: ParticlesParams) -> dict[str, np.ndarray]:
    theta = 2.0 * np.pi * np.arange(params.n) / params.n
    rng = np.random.default_rng(params.seed)
    return {"x0": 0.5 * np.cos(theta), "y0": 1.0 + 0.5 * np.sin(theta),
            "vx0": rng.uniform(-1.0, 1.0, params.n), "vy0": rng.uniform(0.0, 2.0, params.n)}


def n_frames(params: ParticlesParams) -> int:
    """Trajectory frames kept (frame 0 the initial state); 0 when ``record_every`` is 0."""
    return params.steps // params.record_every + 1 if params.record_every else 0


# ---- the one NumPy stepper (oracle, converged references, stress emulation all use it) --------
def constants(inputs: dict[str, np.ndarray], dtype: type[np.floating] = np.float64) -> dict[str, np.floating]:
    """The physical constants of ``inputs`` as ``dtype`` scalars, plus the derived ones a port
    computes once per launch: lo = -1 + radius, hi = 1 - radius, gdt = gravity * dt (each rounded
    in ``dtype``, as the port rounds them)."""
    c = {k: dtype(inputs[k]) for k in CONSTANTS}
    one = dtype(1.0)
    c.update(lo=-one + c["radius"], hi=one - c["radius"], gdt=c["gravity"] * c["dt"])
    return c


def step_constants(inputs: dict[str, np.ndarray], dtype: type[np.floating]) -> dict[str, np.floating]:
    """What a whole-array port's step reads (NumPy, MLX): dt, gdt, damping, radius, lo, hi of
    ``constants`` and nbounce = -bounce, negated once since -bounce*v == (-bounce)*v exactly."""
    c = constants(inputs, dtype)
    return {"dt": c["dt"], "gdt": c["gdt"], "damping": c["damping"], "nbounce": -c["bounce"],
            "radius": c["radius"], "lo": c["lo"], "hi": c["hi"]}


def fly(x, y, u, v, c):
    """Free flight of one step (semi-implicit Euler): v += g dt; x += u dt; y += v dt."""
    v = v + c["gdt"]
    return x + u * c["dt"], y + v * c["dt"], u, v


def clamp(x, y, u, v, c):
    """The contact rule after free flight: floor, then left wall, then right wall.
    Returns the clamped state and the three hit masks."""
    floor = y < c["radius"]
    y = np.where(floor, c["radius"], y); v = np.where(floor, -c["bounce"] * v, v)
    u = np.where(floor, c["damping"] * u, u)
    left = x < c["lo"]
    x = np.where(left, c["lo"], x); u = np.where(left, -c["bounce"] * u, u)
    right = x > c["hi"]
    x = np.where(right, c["hi"], x); u = np.where(right, -c["bounce"] * u, u)
    return x.astype(u.dtype, copy=False), y.astype(u.dtype, copy=False), u, v, (floor, left, right)


def simulate(inputs: dict[str, np.ndarray], steps: int, dtype: type[np.floating] = np.float64,
             until_nonfinite: bool = False):
    """The scenario's step in NumPy at ``dtype``, operation by operation (no FMA), from the
    initial state in ``inputs``. Returns ((x, y, u, v), steps taken); with ``until_nonfinite``
    it stops after the first step that leaves some state value non-finite."""
    c = constants(inputs, dtype)
    x, y, u, v = (np.asarray(inputs[k]).astype(dtype) for k in INITIAL)
    with np.errstate(all="ignore"):
        for s in range(1, steps + 1):
            x, y, u, v = fly(x, y, u, v, c)
            x, y, u, v, _ = clamp(x, y, u, v, c)
            if until_nonfinite and not all(np.all(np.isfinite(a)) for a in (x, y, u, v)):
                return (x, y, u, v), s
    return (x, y, u, v), steps


def energy(x, y, u, v, gravity: float, radius: float) -> np.ndarray:
    """Per-particle mechanical energy per unit mass, 0 at rest on the floor (float64)."""
    f = lambda a: np.asarray(a, np.float64)  # noqa: E731
    with np.errstate(over="ignore", invalid="ignore"):
        return 0.5 * (f(u) ** 2 + f(v) ** 2) + abs(gravity) * (f(y) - radius)


def energy_bound(inputs: dict[str, np.ndarray]) -> np.ndarray:
    """Per-particle energy bound of the exact scheme for bounce < 1, damping <= 1 (docs/stress.md):
    horizontal energy never grows; free flight loses g^2 dt^2/2 per step; a floor contact leaves
    vertical energy <= max(before, E_floor), E_floor = (b |g| dt/(1-b))^2 / 2."""
    c = {k: float(inputs[k]) for k in ("dt", "gravity", "bounce", "radius")}
    b = c["bounce"]
    e_floor = 0.5 * (b * abs(c["gravity"]) * c["dt"] / (1.0 - b)) ** 2
    u0 = inputs["vx0"].astype(np.float64)
    ev0 = 0.5 * inputs["vy0"].astype(np.float64) ** 2 + abs(c["gravity"]) * (inputs["y0"] - c["radius"])
    return 0.5 * u0 ** 2 + np.maximum(ev0, e_floor)


class Particles(Scenario):
    name = "particles"
    title = "Bouncing particles"
    Params = ParticlesParams
    quick = {"n": 1000, "steps": 300}     # n not a multiple of any block size
    outputs = STATE
    item = "particles"

    def inputs(self, params: ParticlesParams, precision: str) -> dict[str, np.ndarray]:
        dt = dtype_of(precision)
        out = {k: v.astype(dt) for k, v in initial_state(params).items()}
        out.update({k: np.array(getattr(params, k), dtype=dt) for k in CONSTANTS})
        return out

    def output_shapes(self, params: ParticlesParams) -> dict[str, tuple[int, ...]]:
        shapes: dict[str, tuple[int, ...]] = {k: (params.n,) for k in self.outputs}
        if params.record_every:      # trajectory frames only when asked for (no history otherwise)
            shapes.update(traj_x=(n_frames(params), params.n), traj_y=(n_frames(params), params.n))
        return shapes

    def oracle(self, params: ParticlesParams, inputs, precision: Precision):
        """Float64 rollout, plus the running error bound for the cell's precision and margins."""
        # the port's rounding (u) plus the float64 oracle's own (u64): the bound is linear in u
        u = UNIT_ROUNDOFF[precision] + UNIT_ROUNDOFF[Precision.FLOAT64]
        c = constants(inputs, np.float64)
        dt, gdt, damp, bounce, rad, lo, hi = (c[k] for k in ("dt", "gdt", "damping", "bounce", "radius", "lo", "hi"))
        x, y = inputs["x0"].astype(np.float64), inputs["y0"].astype(np.float64)
        vx, vy = inputs["vx0"].astype(np.float64), inputs["vy0"].astype(np.float64)
        ex = np.zeros_like(x); ey = np.zeros_like(x); eu = np.zeros_like(x); ev = np.zeros_like(x)
        margin = np.full(x.shape, np.inf); ill = np.zeros(x.shape, dtype=bool)
        frames, frame_bounds = [], []
        if params.record_every:
            frames.append((x.copy(), y.copy())); frame_bounds.append(np.maximum(ex, ey))
        for s in range(params.steps):
            # rounding of the free flight, from the operands before it (bound update first)
            ev = ev + u * (np.abs(vy + gdt) + 2.0 * abs(gdt))
            ex = ex + dt * eu + u * (np.abs(x + vx * dt) + 2.0 * np.abs(vx * dt))
            ey = ey + dt * ev + u * (np.abs(y + (vy + gdt) * dt) + 2.0 * np.abs((vy + gdt) * dt))
            x, y, vx, vy = fly(x, y, vx, vy, c)
            # contact thresholds: record the closest approach and whether it was within the bound
            for dist, err in ((np.abs(y - rad), ey), (np.abs(x - lo), ex), (np.abs(x - hi), ex)):
                margin = np.minimum(margin, dist)
                ill |= dist <= err
            vx_free = vx
            x, y, vx, vy, (floor, left, right) = clamp(x, y, vx, vy, c)
            ey = np.where(floor, 0.0, ey)
            ev = np.where(floor, bounce * ev + u * np.abs(vy), ev)
            vx_now = np.where(floor, damp * vx_free, vx_free)      # vx after each clamp in turn
            eu = np.where(floor, damp * eu + u * np.abs(vx_now), eu)
            # a wall clamp leaves the rounding of -1 + radius (resp. 1 - radius) the port computes
            for hit, wall in ((left, lo), (right, hi)):
                vx_now = np.where(hit, -bounce * vx_now, vx_now)
                ex = np.where(hit, u * abs(wall), ex)
                eu = np.where(hit, bounce * eu + u * np.abs(vx_now), eu)
            if params.record_every and (s + 1) % params.record_every == 0:
                frames.append((x.copy(), y.copy())); frame_bounds.append(np.maximum(ex, ey))
        out = {"x": x, "y": y, "vx": vx, "vy": vy,
               "error_bound": np.maximum.reduce([ex, ey, eu, ev]), "margin": margin,
               "ill_conditioned": ill}
        if params.record_every:
            out["traj_x"] = np.stack([f[0] for f in frames])
            out["traj_y"] = np.stack([f[1] for f in frames])
            out["traj_bound"] = np.stack(frame_bounds)
        return out

    @staticmethod
    def state_error(outputs, other) -> np.ndarray:
        """Per particle, the largest difference of any state component (x, y, vx, vy)."""
        return np.max([np.abs(np.asarray(outputs[k], np.float64) - np.asarray(other[k], np.float64))
                       for k in STATE], axis=0)

    def check(self, params, inputs, outputs, reference, precision) -> Check:
        err = self.state_error(outputs, reference)
        bound = reference["error_bound"]
        ill = reference["ill_conditioned"]
        good = ~ill
        finite = bool(np.all(np.isfinite(err)))
        ok = finite and bool(np.all(err[good] <= bound[good]))
        worst = float(err[good].max()) if good.any() else 0.0
        tol = float(bound[good].max()) if good.any() else 0.0
        details = {
            "metric": "max |state - ref| over well-conditioned particles (bound per particle)",
            "well_conditioned": int(good.sum()), "ill_conditioned": int(ill.sum()),
            "ill_conditioned_deviating": int(np.sum(err[ill] > bound[ill])),
            "max_error_all_particles": float(err.max()) if err.size else 0.0,
            "worst_error_over_bound": float(np.max(err[good] / np.maximum(bound[good], 1e-300)))
            if good.any() else 0.0,
        }
        if params.record_every:
            # every recorded frame of every well-conditioned particle within its bound at that time
            shape = (n_frames(params), params.n)
            tx, ty = (np.asarray(outputs.get(k, np.empty(0)), np.float64) for k in ("traj_x", "traj_y"))
            if tx.shape != shape or ty.shape != shape:
                details["trajectory"] = f"shape {tx.shape}/{ty.shape}, expected {shape}"
                ok = False
            else:
                terr = np.maximum(np.abs(tx - reference["traj_x"]), np.abs(ty - reference["traj_y"]))
                tok = bool(np.all(terr[:, good] <= reference["traj_bound"][:, good]))
                details["trajectory_max_error"] = float(terr[:, good].max()) if good.any() else 0.0
                ok = ok and tok
        return Check(worst if finite else math.inf, tol, ok, details)

    def distance(self, params, inputs, outputs, other) -> float:
        err = self.state_error(outputs, other)
        return float(err.max()) if np.all(np.isfinite(err)) else math.inf

    def sample(self, params: ParticlesParams, inputs: dict[str, np.ndarray], outputs: dict[str, np.ndarray],
               k: int) -> Sample | None:
        """The per-item sample (``Scenario.sample``) of k particles, PARTICLES_CHECKED when k is 0;
        a cell that keeps trajectory frames is checked whole."""
        return super().sample(params, inputs, outputs, k or PARTICLES_CHECKED)

    def scaled(self, params: ParticlesParams, factor: int) -> ParticlesParams | None:
        return dataclasses.replace(params, n=max(1, params.n // factor)) if params.n >= BIG_N else None

    def footprint(self, params: ParticlesParams, precision: str, device: str = "cpu") -> float:
        # state, the oracle's float64 rollout with its running bounds and margins (of every particle:
        # an upper bound above PARTICLES_CHECKED, where the check runs a sample), and with
        # record_every the kept frames (the port's and the oracle's, with bounds). Measured on
        # CPU (all four backends): at most 304 B/particle at n = 2^20 (JAX adds ~50 MB at any
        # size) and 92 B/particle-frame with 101 frames; bound ~1.4x that (docs/reliability.md)
        frames = n_frames(params)
        return 64.0 * 2**20 + params.n * 400.0 + frames * params.n * 128.0

    def work(self, params: ParticlesParams, precision: str) -> dict[str, float]:
        itemsize = 4 if precision == "float32" else 8
        # 5 FLOP per particle-step: v += g dt (1), x += u dt and y += v dt (an FMA each, 2 + 2);
        # the three compares and clamps are not counted, so the FLOP floor is a lower bound
        return {"items": float(params.n) * params.steps, "bytes": 8.0 * params.n * itemsize,
                "flops": 5.0 * params.n * params.steps}
