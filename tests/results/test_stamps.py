"""compare/results/stamps.py: which records name a run of their store (fast tier)."""
from __future__ import annotations

from compare.results.record import Record
from compare.results.stamps import flat_runs, is_unknown, names_a_run, unknown_stamp, unstamped

A = {"created": "2026-11-27T10:20:30+00:00", "git_commit": "abc1234", "git_dirty": False}
B = {"created": "2026-11-28T08:00:00+00:00", "git_commit": "def5678", "git_dirty": True}
MERGED = {**B, "merged_from": ["x", "y"], "environments": [A, B]}


def rec(run=None, n: int = 1) -> Record:
    return Record(scenario="saxpy", backend="numpy", device="cpu", precision="float32", status="ok",
                  params={"n": n}, run=run)


def test_a_stamp_names_a_run_by_its_start_and_commit_inside_a_merged_entry_too():
    assert flat_runs([MERGED]) == [A, B] and flat_runs([A]) == [A]
    assert names_a_run(rec({"created": A["created"], "commit": "abc1234", "dirty": False}), [MERGED])
    assert names_a_run(rec({"created": A["created"], "commit": None, "dirty": None}), [A])      # commit unknown
    assert not names_a_run(rec({"created": A["created"], "commit": "other", "dirty": False}), [A])
    assert not names_a_run(rec({"created": "2026-01-01T00:00:00+00:00"}), [A]) and not names_a_run(rec(), [A])


def test_unstamped_lists_records_that_name_no_run_and_do_not_say_it_is_unknown():
    lost = rec(unknown_stamp("two runs fit"), n=2)
    assert is_unknown(lost.run) and lost.run["note"] == "run unknown: two runs fit" and not is_unknown(None)
    assert not names_a_run(lost, [A])
    good, bare, stale = rec({"created": A["created"]}, 3), rec(n=4), rec({"created": "gone"}, 5)
    assert unstamped([good, lost, bare, stale], [A]) == [bare.key, stale.key]
