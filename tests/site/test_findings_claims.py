"""What docs/findings.md and README.md say of the published stores, computed from the stores with
the site's own code (issue 57, item 5; measurement.md's figures: test_measurement_claims.py,
test_measurement_launch.py, test_doc_claims.py). A figure a finding dates to a run no store keeps
is held here to be dated. Fast tier."""
from __future__ import annotations

import re
from typing import Any, Mapping

import pytest

from compare.running import repeats
from compare.site import data, ranking
from measurement_doc import NAMES, doc_text, machine, said

pytestmark = pytest.mark.xdist_group("measurement-claims")


@pytest.fixture(scope="module")
def findings() -> str:
    return doc_text("docs/findings.md")


def stress_rows(experiment: str) -> list[Mapping[str, Any]]:
    stress = machine("h100").stress
    assert stress is not None
    return [r for r in stress.analysis["rows"] if r["experiment"] == experiment]


def provenance(experiment: str) -> tuple[str, str]:
    """(day, short commit) of the run that made a stress experiment's rows."""
    stress = machine("h100").stress
    assert stress is not None
    run = stress.analysis["provenance"][experiment]
    return str(run["created"])[:10], str(run["git_commit"])[:7]


# ---- 4: the racy control kernel ------------------------------------------------------------------
def test_the_racy_control_on_the_h100(findings: str) -> None:
    """The stress suite's `racy-one-launch` control on CUDA: its two runs differ, both wrong alike."""
    day, commit, differ, first, second, bound = said(
        findings, r"the two runs of the stored experiment \(([\d-]+), commit (\w+)\) differ in (\d+) values and are "
                  r"both wrong: error (\S+) and (\S+) against a bound of (\S+) \(the stability page's")
    (row,) = [r for r in stress_rows("races") if r["device"] == "cuda" and "racy-one-launch" in r["setting"]]
    assert (day, commit) == provenance("races")
    assert row["value"] == int(differ) and row["verdict"].startswith("RACE DETECTED")
    got = re.match(r"error vs oracle (\S+) and (\S+) \(bound ([^)]+)\)", row["detail"])
    assert got and (got[1], got[2]) == (first, second) and float(got[3]) == float(bound), row["detail"]


# ---- 9: Dr.Jit's FastMath --------------------------------------------------------------------------
def drjit_f64(sweep: str | None) -> list[Any]:
    return [r for r in machine("h100").records if r.backend == "drjit" and r.device == "cuda"
            and r.precision == "float64" and data.tag(r, "sweep") == sweep]


def grad_rel(r: Any) -> float:
    v = data.num(r.gradient.vs_oracle_rel) if r.gradient else None
    assert v is not None, (r.backend, r.params)
    return v


def test_what_dr_jit_showed_before_the_workaround_is_dated(findings: str) -> None:
    """The mismatches of 'What we saw' were the records of 2026-11-26, since measured again: the
    store holds no Dr.Jit float64 CUDA mismatch, so the entry says when it saw them."""
    (day,) = said(findings, r"\*\*What we saw\*\* \(([\d-]+), before the workaround; the store now holds the cells "
                            r"measured after it, below\)")
    cells = [r for s in (None, "horizon", "error") for r in drjit_f64(s)]
    assert cells and all(r.status == "ok" for r in cells) and day


def test_dr_jit_float64_after_the_workaround(findings: str) -> None:
    plain, fd = said(findings, r"the projectile's float64 gradient is (\S+) from the float64 oracle \(all three loop "
                               r"variants; (\S+) from float64 finite differences\)")
    loops = [r for r in drjit_f64(None) if r.scenario == "projectile" and r.variant in ("default", "checkpoint", "evaluated")]
    assert len(loops) == 3 and {f"{grad_rel(r):.2g}" for r in loops} == {plain}
    assert {f"{data.num(r.gradient.vs_fd64_rel) or 0:.2g}" for r in loops if r.gradient} == {fd}
    day, commit, again, again_fd = said(findings, r"its plain cells, measured again on ([\d-]+) from commit (\w+), give "
                                                  r"the same (\S+) and ([\d.e-]+)\)")
    assert (again, again_fd) == (plain, fd)
    assert {(str((r.run or {}).get("created"))[:10], str((r.run or {}).get("commit"))[:7]) for r in loops} == {(day, commit)}
    count, mine, warp = said(findings, r"the (\d+) float64 error-sweep cells agree with Warp's to the last digits "
                                       r"\(gradient error <= (\S+) against Warp's (\S+)\)")
    error = drjit_f64("error")
    assert len(error) == int(count) and all(r.status == "ok" for r in error)

    def worst(fw: str) -> str:
        cells = [r for r in machine("h100").sweep if data.tag(r, "sweep") == "error" and r.backend == fw
                 and r.device == "cuda" and r.precision == "float64" and r.scenario == "projectile" and r.status == "ok"]
        return f"{max(grad_rel(r) for r in cells):.2g}"
    assert (mine, warp) == (worst("drjit"), worst("warp"))
    count, at, mine, hand = said(findings, r"the (\d+) float64 horizon cells are within a few times Triton's hand adjoint "
                                           r"\(hard contact at ([\d,]+) steps: (\S+) against (\S+)\)")
    horizon = drjit_f64("horizon")
    assert len(horizon) == int(count) and all(r.status == "ok" for r in horizon)
    steps = int(at.replace(",", ""))

    def hard(fw: str) -> set[str]:
        return {f"{grad_rel(r):.2g}" for r in machine("h100").sweep if data.tag(r, "sweep") == "horizon"
                and r.backend == fw and r.device == "cuda" and r.precision == "float64"
                and (r.params or {}).get("contact") == "hard" and (r.params or {}).get("steps") == steps}
    assert hard("drjit") == {mine} and hard("triton") == {hand}


def test_the_gradient_quality_experiment_of_the_stability_suite(findings: str) -> None:
    commit, day, figure = said(findings, r"The stability suite's gradient-quality experiment, rerun on the H100 from "
                                         r"commit (\w+) \(([\d-]+)\), puts the float64 soft-contact gradient (\S+) from "
                                         r"the float64 adjoint, within the derived bound")
    assert provenance("projectile-gradient") == (day, commit)
    (row,) = [r for r in stress_rows("projectile-gradient") if r["backend"] == "drjit" and r["device"] == "cuda"
              and r["precision"] == "float64" and r["setting"].startswith("contact=soft")
              and r["figure"] == "gradient rel. error vs adjoint64"]
    assert f"{row['value']:.2g}" == figure and row["verdict"] == "within derived bound"


# ---- README ------------------------------------------------------------------------------------
def test_readme_names_the_frameworks_every_report_measures() -> None:
    """'written in eleven Python frameworks: Warp, ...': the backends, each with records in the
    three machine stores."""
    readme = doc_text("README.md")
    count, listed = said(readme, r"written in (\w+) Python frameworks: (.+?)\. Every result")
    words = re.split(r", | and ", listed)
    import backends
    assert sorted(NAMES[w] for w in words) == sorted(backends.BACKENDS)
    assert "zero one two three four five six seven eight nine ten eleven twelve".split().index(count) == len(words)
    for key in ("h100", "cpu", "xeon"):
        assert set(machine(key).frameworks) >= set(backends.BACKENDS), key


def test_readme_says_what_a_best_needs_as_the_ranking_does() -> None:
    """'*Under 6 processes*: no 95 % interval, so a best needs a 1.6× lead': the fewest processes with
    a 95 % interval and the gap a figure without one needs (compare.running.repeats, site.ranking)."""
    readme = doc_text("README.md")
    fewest, gap = said(readme, r"\*Under (\d+) processes\*: no 95 % interval, so a best needs a ([\d.]+)× lead")
    assert int(fewest) == repeats.AUTO_MIN and float(gap) == ranking.ONE_PROCESS_GAP
    assert repeats.interval(list(range(repeats.AUTO_MIN)))[2] >= repeats.CONFIDENCE
    assert repeats.interval(list(range(repeats.AUTO_MIN - 1)))[2] < repeats.CONFIDENCE



def test_readme_run_times_are_the_ones_install_md_dates() -> None:
    """README's run times are past runs: each end of its ranges is a dated row of docs/install.md's
    run-time tables, the source README names beside them."""
    readme, install = doc_text("README.md"), doc_text("docs/install.md")
    assert "([docs/install.md](docs/install.md): extras, run times, test tiers)" in readme
    lo, hi, h100 = said(readme, r"The first takes (\d+)-(\d+) s on a 2-core VM .*?, (\d+) minutes on an H100 with every "
                                r"framework")
    assert all(re.search(rf"\| 2026-[\d-]+ \| {s}\.\d s", install) for s in (lo, hi)), (lo, hi)
    assert f"(176 cells) it takes about {h100} minutes" in install
    fast, slow, before, after = said(readme, r"\(3 min (\d+)-(\d+) s on the same idle VM, (\d:\d+) to "
                                             r"(\d:\d+) before its tests shared their runs\)")
    times = [f"3 min {fast} s", f"3 min {slow} s", *("{} min {} s".format(*x.split(":")) for x in (before, after))]
    assert all(x in install for x in times), times
