"""The particles on the site: the particle loop at small and large n."""
from __future__ import annotations

from compare.render import charts
from compare.site import data, fmt, matrix
from compare.site.matrix import Rule, defaults_of, largest_of, rate, regime
from compare.site.questions_pages import Ctx, Page, _bar, _scaling, verdicts
from compare.site.render import Figure, P
from compare.site.topics import scenario_of

SCENARIO = scenario_of(__name__)
SMALL = True

RULES = (
    Rule("particles-small", "Particle loop, small n", SCENARIO, "s", "lower",
         "Particles at the defaults (256 particles × 300 steps), float32: time per whole rollout "
         f"in the throughput regime, {matrix.VARIANT_RULE}.",
         defaults_of(SCENARIO), regime("throughput")),
    Rule("particles-large", "Particle loop, large n", SCENARIO, "1/s", "higher",
         "Particles at the largest n above the default in the records that two or more frameworks ran (run or "
         f"scaling sweep), float32: particle-steps per second in the throughput regime, {matrix.VARIANT_RULE}.",
         largest_of(SCENARIO, (None, "scaling"), data.beyond_defaults), rate),
)


def page(c: Ctx) -> Page:
    blocks: Page = [P("A particle simulation loop: 300 steps of gravity, damping and wall contact. "
                      "At small n the loop's per-step launches dominate; at large n the kernels do.")]
    blocks += verdicts(c.rows_of(SCENARIO))
    small = (matrix.defaults_of(SCENARIO)(c.m, c.device))
    if small:
        png, rel, csv = c.fig("particles-small")
        charts.bars(png, f"Particles at the defaults (256 × 300 steps, {c.device}, float32): per rollout, "
                    "throughput regime", "seconds per rollout (whiskers: quartiles; log scale)",
                    [_bar(r, matrix.regime("throughput")) for r in small], log=True, fmt=fmt.seconds)
        blocks += [Figure(rel, "Every framework and variant at the default size.",
                          c.cmd(f"run {SCENARIO} --devices {c.device} --precision float32 --variants all"), csv)]
    big = (matrix.largest_of(SCENARIO, (None, "scaling"), data.beyond_defaults)(c.m, c.device))
    if big:
        png, rel, csv = c.fig("particles-large")
        charts.bars(png, f"Particles at the largest n ({data.scope(big)}, {c.device}, float32): particle-steps "
                    "per second, throughput regime", "particle-steps per second",
                    [_bar(r, data.item_rate) for r in big], better="higher", fmt=lambda v: fmt.rate(v))
        n = int(data.size(big[0]))
        blocks.append(Figure(rel, "Every framework and variant at the largest n; fastest first.",
                             c.cmd(f"run {SCENARIO} --devices {c.device} --precision float32 --variants all "
                                   f"--set n={n} --check-sample 4096"), csv))
    blocks += _scaling(c, SCENARIO, "particle-steps per second", "n (particles)")
    return blocks


PAGES = {SCENARIO: ("Particle loops", page)}     # its page is named after it
