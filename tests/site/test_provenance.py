"""compare/site/provenance.py: which runs a row's figures come from, in words (fast tier)."""
from __future__ import annotations

from compare.results.record import Record
from compare.site import provenance


def rec(run=None) -> Record:
    return Record(scenario="saxpy", backend="numpy", device="cpu", precision="float32", status="ok", run=run)


A = {"created": "2026-11-27T10:20:30+00:00", "commit": "abc1234", "dirty": False}
B = {"created": "2026-11-28T08:00:00+00:00", "commit": "def5678", "dirty": True}


def test_label_is_the_minute_commit_and_tree_state():
    assert provenance.label(rec(A)) == "run 2026-11-27 10:20 UTC, commit abc1234"
    assert provenance.label(rec(B)).endswith("commit def5678 (dirty tree)")
    assert provenance.label(rec({"created": "2026-11-27T10:20"})) == \
        "run 2026-11-27 10:20 UTC, commit unknown commit (tree state unknown)"
    assert provenance.label(rec()) == ""


def test_runs_of_are_distinct_in_first_seen_order():
    assert provenance.runs_of([rec(B), rec(A), rec(B), rec()]) == (
        provenance.label(rec(B)), provenance.label(rec(A)), "")


def test_one_run_ranks_several_or_unstamped_do_not():
    one = provenance.runs_of([rec(A), rec(A)])
    assert provenance.one_run(one) and provenance.words(one).startswith("Every figure of this row comes from one run")
    two = provenance.runs_of([rec(A), rec(B)])
    assert not provenance.one_run(two) and "come from 2 run(s)" in provenance.words(two)
    unstamped = provenance.runs_of([rec()])
    assert not provenance.one_run(unstamped)
    assert provenance.UNSTAMPED in provenance.words(unstamped) and "an unknown number of" in provenance.words(unstamped)
    mixed = provenance.words(provenance.runs_of([rec(A), rec()]))
    assert "1 run(s) and " + provenance.UNSTAMPED in mixed and "no best is named" in mixed
    assert provenance.words(()) == "No records."


def test_one_run_of_an_uncommitted_tree_or_an_unknown_one_is_not_ranked():
    for run in (B, {"created": "2026-11-27T10:20", "commit": "abc1234"}):
        runs = provenance.runs_of([rec(run), rec(run)])
        assert len(runs) == 1 and not provenance.one_run(runs) and provenance.uncommitted(runs)
        assert "not a commit someone can check out" in provenance.words(runs)
    assert not any(provenance.uncommitted(provenance.runs_of(x)) for x in ([rec(A)], [rec(A), rec(B)], [rec()]))


def test_the_best_column_says_why_runs_name_no_best():
    assert provenance.mark(provenance.runs_of([rec(A), rec(B)])) == "2 runs"
    assert provenance.mark(provenance.runs_of([rec(A), rec()])) == "not one run"
    assert provenance.mark(provenance.runs_of([rec(B), rec(B)])) == "not a commit"


def test_a_full_commit_hash_is_shortened_on_pages_and_anything_else_kept():
    from compare.site import provenance
    assert provenance.short("0ffd82b02e538da2c427e5697a9f567f429b5845") == "0ffd82b"
    assert provenance.short("ae30861") == "ae30861" and provenance.short("?") == "?"


def test_a_record_stamped_run_unknown_says_so_and_is_never_ranked():
    """A record whose store could not tell its run (compare.results.stamps.unknown_stamp) reads
    "run unknown" on every page, alone or beside a known run, and no row ranks on it."""
    from compare.results.stamps import unknown_stamp
    lost = rec(unknown_stamp("two runs fit"))
    assert provenance.label(lost) == provenance.RUN_UNKNOWN == "run unknown"
    alone = provenance.runs_of([lost, lost])
    assert not provenance.one_run(alone) and not provenance.uncommitted(alone)
    assert "run unknown" in provenance.words(alone) and "no best is named" in provenance.words(alone)
    beside = provenance.runs_of([rec(A), lost])
    assert not provenance.one_run(beside) and "run unknown" in provenance.words(beside)


def test_a_noisy_sitting_is_named_and_the_row_still_ranks():
    noisy = {**A, "noisy_sitting": True}
    assert provenance.label(rec(noisy)) == "run 2026-11-27 10:20 UTC (noisy sitting), commit abc1234"
    runs = provenance.runs_of([rec(noisy)])
    assert provenance.one_run(runs) and "(noisy sitting)" in provenance.words(runs)
    dirty = provenance.runs_of([rec({**B, "noisy_sitting": True})])
    assert provenance.uncommitted(dirty) and "(noisy sitting)" in provenance.words(dirty)


C = {"created": "2026-12-06T21:43:20+00:00", "commit": "f4d8e09", "dirty": False}


def cell(run, backend="numpy", variant="default", status="ok") -> Record:
    return Record(scenario="saxpy", backend=backend, device="cuda", precision="float32", status=status,
                  variant=variant, run=run)


def pick(recs):
    return provenance.one_run_of(recs, lambda r: r.variant != "fastmath", lambda r: 1)


def test_a_row_of_several_runs_reads_the_one_that_measured_every_framework():
    # A: both frameworks, one variant each; C: both, and warp's second variant: C is read alone
    old = [cell(A, "cupy"), cell(A, "warp")]
    new = [cell(C, "cupy"), cell(C, "warp"), cell(C, "warp", "record_cmd")]
    chosen = pick(old + new)
    assert chosen == new and provenance.one_run(provenance.runs_of(chosen))
    # a fast-math cell is not counted toward a run's coverage: the tie goes to the later run
    assert pick([cell(A, "cupy"), cell(A, "warp"), cell(A, "warp", "fastmath"), cell(C, "cupy"),
                 cell(C, "warp")]) == [cell(C, "cupy"), cell(C, "warp")]


def test_a_run_missing_a_framework_or_of_a_dirty_tree_is_never_read_alone():
    partial = [cell(A, "cupy"), cell(A, "warp"), cell(C, "cupy")]
    assert pick(partial) == partial[:2]               # C lacks warp: A, which has both, is read
    assert pick([cell(A, "cupy"), cell(C, "warp")]) == [cell(A, "cupy"), cell(C, "warp")]   # none has both
    assert pick([cell(B, "cupy"), cell(B, "warp"), cell(C, "cupy")]) == \
        [cell(B, "cupy"), cell(B, "warp"), cell(C, "cupy")]     # B covers both but is dirty: all kept
    # another run's skip of a framework the chosen run has nothing of stays (its reason shows)
    skip = cell(A, "numpy", status="skipped")
    assert pick([skip, cell(A, "cupy"), cell(C, "cupy"), cell(C, "warp", "tile")]) == \
        [skip, cell(C, "cupy"), cell(C, "warp", "tile")]
