"""compare/render/colors.py: a backend's colour and the matrix's bands (fast tier)."""
from __future__ import annotations

import re

import backends
from compare.render import colors


def test_a_backend_keeps_its_own_colour_and_an_unknown_one_is_grey():
    named = [b for b in backends.BACKENDS.values() if b.color]
    assert named, "no backend declares a colour"
    for b in named:
        assert colors.backend_color(b.name) == b.color
    assert colors.backend_color("no-such-framework") == "0.4"


def test_a_backend_without_a_colour_gets_its_registry_place(monkeypatch):
    import dataclasses
    names = list(backends.BACKENDS)
    name = names[-1]
    b = backends.BACKENDS[name]
    try:
        plain = dataclasses.replace(b, color="")
    except TypeError:                     # not a dataclass: a copy without its colour
        import copy
        plain = copy.copy(b)
        plain.color = ""
    monkeypatch.setitem(backends.BACKENDS, name, plain)
    assert colors.backend_color(name) == f"C{names.index(name) % 10}"


def test_bands_are_unique_and_ordered_by_bound():
    names = [b.name for b in colors.BANDS]
    assert names == ["best", "near", "far", "poor", "ref", "none"]
    assert len({b.emoji for b in colors.BANDS}) == len(colors.BANDS)
    bounds = [b.bound for b in colors.BANDS if b.bound is not None]
    assert bounds == sorted(bounds) == [2.0, 5.0]
    assert colors.BAND["near"] is colors.BANDS[1]


def test_band_words_read_the_bounds():
    assert colors.band_words(colors.BAND["near"]) == "within 2× of the leader"
    assert colors.band_words(colors.BAND["far"]) == "within 5×"
    assert colors.band_words(colors.BAND["poor"]) == "beyond 5×"       # the last bound


def test_band_css_has_one_class_per_band_and_bolds_the_best():
    css = colors.band_css()
    for b in colors.BANDS:
        assert f".{b.name}{{background:{b.background};color:{b.text}" in css
    assert re.findall(r"font-weight:600", css) == ["font-weight:600"]
    assert ".best{background:#1a7f37;color:#ffffff;font-weight:600}" in css
