"""The gradients page answers "which framework differentiates a long loop fastest, and at what
memory" from the horizon sweep (compare/site/questions_pages._longest_loop), checked on the
committed H100 store."""
from __future__ import annotations

from conftest import ROOT

from compare.site import data
from compare.site import questions_pages as qp


def test_the_long_loop_verdict_names_the_fastest_and_the_smallest_at_the_longest_shared_horizon():
    m = data.load([ROOT / "docs" / "results" / "h100"])
    hz = [r for r in m.sweep if data.tag(r, "sweep") == "horizon" and r.device == "cuda"]
    head, verdict, table = qp._longest_loop(hz)
    ok = [r for r in hz if r.status == "ok" and r.precision == "float32" and r.params["contact"] == "hard"]
    longest = max(n for n in {r.params["steps"] for r in ok}
                  if len({r.backend for r in ok if r.params["steps"] == n}) >= 2)
    assert f"({longest} steps)" in head.text
    at = [r for r in ok if r.params["steps"] == longest]
    assert len(table.rows) == len(at)
    times = [(data.per_call(r, "throughput") or data.timing(r, "latency")).median for r in at]
    fastest = at[times.index(min(times))]
    mems = [data.device_bytes(r) for r in at]
    smallest = at[mems.index(min(m for m in mems if m is not None))]
    label = lambda r: r.backend + ("" if r.variant == "default" else f" {r.variant}")  # noqa: E731
    assert f"Fastest: {label(fastest)} (" in verdict.text
    assert f"least device memory: {label(smallest)} (" in verdict.text
    assert table.rows[0][:2] == (fastest.backend, fastest.variant)      # sorted fastest first


def test_no_long_loop_section_without_two_frameworks_at_one_horizon():
    assert qp._longest_loop([]) == []


def test_a_figures_command_measures_again_as_published_into_a_new_folder(tmp_path):
    """Not ``--resume`` into the store, which holds every cell and so would remeasure nothing:
    the published protocol (several processes, set-ups side by side, one sitting) into NEW, its site, and
    ``compare agree`` against the store; a stress figure has no processes and no agreement."""
    c = qp.Ctx(data.load([]), [], tmp_path / "site", "docs/results/h100")
    timed = c.cmd("run saxpy --devices cuda").splitlines()
    assert timed == ["python -m compare run saxpy --devices cuda --processes auto --overlap auto --sitting 1500 --out NEW",
                     "python -m compare site NEW --out NEW/report",
                     "python -m compare agree docs/results/h100 NEW"]
    assert "--resume" not in c.cmd("sweep error")
    assert c.cmd("stress --only ulps", timed=False).splitlines() == [
        "python -m compare stress --only ulps --out NEW", "python -m compare site NEW --out NEW/report"]
