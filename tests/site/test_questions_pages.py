"""The gradients page answers "which framework differentiates a long loop fastest, and at what
memory" from the horizon sweep (compare/site/questions_pages._longest_loop), checked on the
committed H100 and Xeon stores."""
from __future__ import annotations

import pytest
from conftest import ROOT

from compare.site import data, ranking
from compare.site import questions_pages as qp


@pytest.mark.parametrize("store,device", [("h100", "cuda"), ("xeon", "cpu")])
def test_the_long_loop_verdict_names_the_fastest_and_the_smallest_at_the_longest_shared_horizon(store, device):
    m = data.load([ROOT / "docs" / "results" / store])
    hz = [r for r in m.sweep if data.tag(r, "sweep") == "horizon" and r.device == device]
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
    smallest = at[mems.index(min(m for m in mems if m is not None))] if any(m is not None for m in mems) else None
    label = lambda r: r.backend + ("" if r.variant == "default" else f" {r.variant}")  # noqa: E731
    # one-process figures: a best only where 1.6x ahead of the next (compare.site.ranking), else a tie
    near = sorted((t, label(r)) for t, r in zip(times, at) if t < ranking.ONE_PROCESS_GAP * min(times))
    if len(near) == 1:
        assert f"Fastest: {label(fastest)} (" in verdict.text
    else:
        assert f"Fastest: a tie of {', '.join(n for _, n in near)} (figures without a 95 % interval within" in verdict.text
    assert (f"least device memory: {label(smallest)} (" in verdict.text) if smallest else "memory" not in verdict.text
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
