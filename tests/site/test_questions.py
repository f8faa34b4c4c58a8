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
