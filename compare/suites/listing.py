"""``python -m compare list``: the scenarios (their defaults), the backends (their variants and
each device's availability, probed in the backend's own process) and what is missing or broken."""
from __future__ import annotations

import argparse

import backends
import scenarios
from compare.options import EXIT_OK
from compare.running import engine
from compare.suites.driver import Command


def scenario_problems() -> list[str]:
    """Kernel files a backend lacks: required (every scenario in 'all') or optional."""
    out = []
    for name, b in backends.BACKENDS.items():
        if isinstance(b, backends.Broken):
            continue
        where = type(b).__module__.replace(".", "/")
        missing = [sc for sc in scenarios.SCENARIOS.values() if not b.has_kernel(sc.name)]
        req = [sc.name for sc in missing if sc.in_all]
        opt = [sc.name for sc in missing if not sc.in_all]
        if req:
            out.append(f"{name}: missing required {', '.join(f'{where}/{s}.py' for s in req)} (its cells are errors)")
        if opt:
            out.append(f"{name}: no optional {', '.join(f'{where}/{s}.py' for s in opt)} (skipped in the sweeps)")
    return out


class Listing(Command):
    """list: no options; prints what this checkout and machine offer."""
    help = "scenarios, backends, devices (and why one is unavailable)"

    def run(self, args: argparse.Namespace, argv: list[str]) -> int:
        probes = engine.availability(backends.BACKENDS)
        print("scenarios:")
        for sc in scenarios.SCENARIOS.values():
            tag = "" if sc.in_all else " [measurement-only, not in 'all']"
            print(f"  {sc.name:11s} {sc.title}{tag}; defaults: {sc.describe_params()}")
        print("backends (device: available, or why not):")
        width = max(map(len, backends.BACKENDS), default=7)
        for name, b in backends.BACKENDS.items():
            avail = probes[name]["available"]
            devs = "; ".join(f"{d}: {'yes' if avail.get(d) is None else avail.get(d)}" for d in backends.DEVICES)
            ref = " (reference)" if b.is_reference else ""
            print(f"  {name:{width}s}{ref} gradient={b.gradient_method} variants={','.join(b.variants)}"
                  + "".join(f" (+{sc}: {','.join(vs)})" for sc, vs in b.scenario_variants.items()) + f"; {devs}")
        problems = backends.PROBLEMS + scenario_problems()
        if problems:
            print("problems:")
            for line in problems:
                print(f"  {line}")
        return EXIT_OK
