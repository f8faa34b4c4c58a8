"""The batched differentiable projectile on the site: gradients through a simulation at scale."""
from __future__ import annotations

import functools

from compare.render import charts, figure_check
from compare.results.record import Record
from compare.site import data, matrix, memory_design
from compare.site.matrix import Reference, Rule, largest_of, rate
from compare.sweep.points.projectile import BATCH_SWEEP_PARAMS
from compare.site.questions_pages import Ctx, Page, _longest_loop, _scaling, verdicts
from compare.site.render import Figure, H, P
from compare.site.topics import scenario_of

SCENARIO = scenario_of(__name__)
ADJOINT = "adjoint"          # Backend.gradient_method of a hand-written discrete adjoint


def gradient_method(r: Record) -> str:
    """How a record's gradient was obtained ('tape', 'ad', 'adjoint'): its ``gradient.method``,
    else its backend's declared ``gradient_method``."""
    m = r.gradient.method if r.gradient else None
    if isinstance(m, str) and m:
        return m
    import backends
    b = backends.BACKENDS.get(r.backend)
    return b.gradient_method if b is not None else "-"


def hand_adjoint(r: Record) -> bool:
    return gradient_method(r) == ADJOINT


# Automatic differentiation is ranked among itself; a hand-written discrete adjoint is another
# kind of program (the derivative written by hand, no tape), shown beside it as the ceiling.
HAND_ADJOINTS = Reference(hand_adjoint, "AD", "Hand-written adjoints")

def at_scale(m: data.Machine, device: str) -> list[Record]:
    """The records of the scaling sweep's largest batch: the sweep's own cells, or a run of that
    point's parameters (hard contact, its iterations) timed in several worker processes, which
    then replaces the sweep's one-process cell of the same framework (``matrix.latest``)."""
    def sweep_point(r: Record) -> bool:
        return data.tag(r, "sweep") == "scaling" or all((r.params or {}).get(k) == v
                                                          for k, v in BATCH_SWEEP_PARAMS.items())
    return largest_of(SCENARIO, (None, "scaling"), sweep_point)(m, device)


RULES = (
    Rule("gradients", "Gradients through a simulation at scale: rate", "gradients", "1/s", "higher",
         "The batched differentiable projectile (hard contact, 180 steps, a descent of loss + "
         "gradient evaluations) at the largest batch in the scaling sweep, float32: trajectory-"
         "gradients per second in the throughput regime; where that point was run again in several "
         "worker processes, those figures. Automatic differentiation (tapes and "
         "traced AD) is ranked among itself; hand-written adjoints are shown beside it, as their "
         f"ratio to the best AD figure, and never ranked; {matrix.VARIANT_RULE}.",
         at_scale, rate, reference=HAND_ADJOINTS),
    Rule("gradients-memory", "Gradients through a simulation at scale: device memory", "gradients",
         "B", "lower",
         "The same cells: " + memory_design.WHAT_IS_MEASURED[0].lower() + memory_design.WHAT_IS_MEASURED[1:]
         + " The one memory figure every framework shares; AD ranked among itself, hand-written "
         "adjoints beside it, never ranked; beside each cell, the bytes its port's design predicts.",
         at_scale, data.device_bytes, exact=True, reference=HAND_ADJOINTS),
)


def page(c: Ctx) -> Page:
    blocks: Page = [P("Gradients through a simulation: a batch of projectiles, each descending on its "
                      "own loss through 180 steps with contact. The rate counts trajectory-gradients "
                      "per second; memory is what the gradient keeps on the device (a tape, adstacks, "
                      "or the one value and flag per step of a hand adjoint).")]
    hand = sorted({r.backend for r in c.m.records if r.scenario == SCENARIO and r.device == c.device
                   and hand_adjoint(r)})
    blocks.append(P("Like with like: automatic differentiation (a tape or traced AD: the framework "
                    "derives the gradient) is ranked among itself. A hand-written discrete adjoint "
                    "(the reverse sweep written by hand, no tape) is another program, and the "
                    "reference AD is measured against: its cells are shown beside the AD figures, "
                    "marked ✎, as their ratio to the best AD figure, and never named best."
                    + (f" Hand-written adjoints here: {', '.join(hand)}." if hand else "")))
    blocks += verdicts(c.rows_of("gradients"))
    blocks += memory_design.table(at_scale(c.m, c.device), hand_adjoint)
    blocks += _scaling(c, SCENARIO, "trajectory-gradients per second", "batch (trajectories)", memory=True,
                       compact=True)
    hz = [r for r in c.m.sweep if data.tag(r, "sweep") == "horizon" and r.device == c.device]
    if hz:
        from compare.sweep import horizon as sweep_horizon, plots as sweep_plots
        from compare.sweep.horizon_panels import LOOK
        cmd = c.cmd(f"sweep horizon --devices {c.device}")
        figs: list[Figure] = []
        for part, name in (("memory", "gradients-horizon"), ("time", "gradients-horizon-time"),
                           ("quality", "gradients-horizon-quality")):
            png, rel, csv = c.fig(name)
            if figure_check.checked(functools.partial(sweep_plots.plot_horizon, list(hz), c.device, png,
                                                      SCENARIO, part), png,
                                    key=(sweep_plots.plot_horizon, list(hz), c.device, SCENARIO, part)):
                figs.append(Figure(rel, LOOK[part], "" if figs else cmd, csv))
                charts.write_csv(png.with_suffix(".csv"), ("framework", "variant", "precision", "contact", "steps",
                                                           "device bytes", "time per call s", "gradient fd agreement",
                                                           "status"),
                                 [(r.backend, r.variant, r.precision, (r.params or {}).get("contact"),
                                   (r.params or {}).get("steps"), data.device_bytes(r),
                                   t.median if (t := data.per_call(r, "throughput")) else None, r.fd_agreement,
                                   r.status) for r in sweep_horizon.gradient_cells(hz, c.device, SCENARIO)])
        if figs:
            blocks += [H("Memory, time and gradient quality against the horizon"), *figs]
            blocks += [P(t) for t in outside_bound(hz)]
        blocks += _longest_loop(hz)
    return blocks


def outside_bound(hz: list[Record]) -> list[str]:
    """Per horizon point (contact, precision, steps) where some framework's error exceeds the derived
    bound: who, by how much, and whether the ratio is the same in all of them (then it is the
    precision's arithmetic on that trajectory, not a port: ports that differ would not agree)."""
    groups: dict[tuple[str, str, int], list[Record]] = {}
    for r in hz:
        if r.status in ("ok", "mismatch") and r.error is not None:
            p = r.params or {}
            groups.setdefault((str(p.get("contact")), str(r.precision), int(p.get("steps") or 0)), []).append(r)
    out = []
    for (contact, prec, steps), recs in sorted(groups.items(), key=lambda kv: kv[0]):
        bad = [r for r in recs if r.status == "mismatch"]
        ratios = [v for r in bad if r.error and isinstance(v := data.num(r.error.vs_oracle), float)]
        if not bad or not ratios:
            continue
        names = sorted({r.backend for r in bad})
        within = sorted({f"{r.backend}{'' if r.variant == 'default' else '/' + r.variant} "
                         f"({data.num(r.error.vs_oracle) or 0:.2g})" for r in recs
                         if r.status == "ok" and r.error})
        same = max(ratios) <= min(ratios) * (1 + 1e-5)
        where = next((r.error.details.get("worst_trajectory") for r in bad if r.error), None)
        text = (f"Outside the derived bound: {contact} contact, {prec}, {steps} steps. "
                f"{len(names)} framework{'s' if len(names) > 1 else ''} ({', '.join(names)}) exceed"
                f"{'' if len(names) > 1 else 's'} the first-order rounding bound, error/bound "
                + (f"{min(ratios):.5g} in every one, the same to 5 digits"
                   + (f" (checked trajectory {where})" if where is not None else "")
                   + f": not a port's defect, since one {prec} arithmetic gives it everywhere, but "
                   f"{prec} outrunning the bound's first-order analysis on that trajectory"
                   if same else f"{min(ratios):.3g} to {max(ratios):.3g}")
                + (f". Within it: {', '.join(within)}." if within else ".")
                + " Their gradients count in the figure's agreement band; its data lists them with "
                "status 'mismatch' (docs/measurement.md, 'AD memory and gradient quality against the "
                "horizon').")
        out.append(text)
    return out


PAGES = {"gradients": ("Gradients at scale", page)}
