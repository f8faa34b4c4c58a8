"""compare/site/questions.py: the matrix's questions, their order and their pages (fast tier)."""
from __future__ import annotations

from compare.site import questions, topics


def test_rules_are_the_topics_then_those_over_every_scenario():
    keys = [r.key for r in questions.RULES]
    assert keys[:len(topics.RULES)] == [r.key for r in topics.RULES]
    assert keys[len(topics.RULES):] == ["accuracy", "compile", "cpu", "busy"]
    assert len(set(keys)) == len(keys)


def test_every_rule_explains_itself_and_has_a_page():
    for r in questions.RULES:
        assert r.text and r.question, r.key
        assert r.page in questions.PAGES, (r.key, r.page)
    assert {"accuracy", "compile", "cpu", "stability", "machine"} <= set(questions.PAGES)


def test_accuracy_is_deterministic_and_cpu_rows_read_the_cpu():
    rule = {r.key: r for r in questions.RULES}
    assert rule["accuracy"].exact and not rule["compile"].exact
    assert rule["cpu"].device == "cpu" and rule["busy"].device == "cpu"


def test_the_large_rows_never_read_the_default_size():
    """A store whose only cells are at the defaults (the H200's matrix part, no large part or sweep
    yet) leaves the large-array and large-n rows empty instead of answering them with the small
    rows' records; a store with larger cells reads its largest."""
    from pathlib import Path

    from compare.site import data
    rule = {r.key: r for r in questions.RULES}
    results = Path(__file__).resolve().parents[2] / "docs" / "results"
    h200, h100 = data.load([results / "h200"]), data.load([results / "h100"])
    for key, scenario in (("bandwidth", "saxpy"), ("particles-large", "particles")):
        assert rule[key].pick(h200, "cuda") == [], key
        assert [r for r in h200.run if r.scenario == scenario and r.status == "ok"], key
        big = rule[key].pick(h100, "cuda")
        assert big and all(data.beyond_defaults(r) for r in big), key
    assert rule["pipelined"].pick(h200, "cuda")           # the same records serve the small rows
