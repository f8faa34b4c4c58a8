"""compare.render.chart_memo: a chart asked for again with equal arguments is written from memory,
bit for bit; any argument that differs (a value by one ulp, a formatter's captured value) draws it."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from compare.render import chart_memo, charts, report
from test_charts import synthetic_bars

ROOT = Path(__file__).resolve().parents[2]


def test_a_chart_asked_for_again_is_written_from_memory_and_a_changed_one_is_drawn(tmp_path, monkeypatch):
    chart_memo.forget()
    drawn: list[Path] = []
    real = charts.save
    monkeypatch.setattr(charts, "save", lambda fig, path: (drawn.append(Path(path)), real(fig, path)))
    bs = synthetic_bars()
    first, again, other = tmp_path / "a.png", tmp_path / "b.png", tmp_path / "c.png"
    charts.bars(first, "t", "x", bs, fmt=report.fmt_time)
    charts.bars(again, "t", "x", list(bs), fmt=report.fmt_time)          # equal arguments: not drawn
    assert drawn == [first]
    assert again.read_bytes() == first.read_bytes()
    assert again.with_suffix(".csv").read_text() == first.with_suffix(".csv").read_text()
    moved = [bs[0].__class__(bs[0].framework, bs[0].variant, bs[0].value * (1 + 2**-52))] + bs[1:]
    charts.bars(other, "t", "x", moved, fmt=report.fmt_time)            # one value one ulp away: drawn
    scale = 2.0

    def scaled(v: float) -> str:
        return f"{v * scale:g}"
    charts.bars(tmp_path / "d.png", "t", "x", bs, fmt=scaled)
    scale = 3.0                    # the same function, another captured value: drawn again
    charts.bars(tmp_path / "e.png", "t", "x", bs, fmt=scaled)
    assert drawn == [first, other, tmp_path / "d.png", tmp_path / "e.png"]


def test_canonical_forms_tell_equal_from_different_arguments():
    c = chart_memo.canon
    assert c([1.0, "a", None]) == c((1.0, "a", None)) and c(1.0) != c(1.0 + 2**-52)
    assert c(np.arange(4.0)) == c(np.arange(4.0)) and c(np.arange(4.0)) != c(np.arange(4.0) + 1)
    assert c(np.arange(10**5.0)) != c(np.arange(10**5.0) * (1 + 2**-40))   # not a truncated repr
    assert c({"b": 1, "a": 2}) == c({"a": 2, "b": 1})
    assert chart_memo.canon(lambda v: v) != chart_memo.canon(lambda v: v + 1)


def test_an_argument_without_a_canonical_form_is_drawn_every_time(tmp_path, monkeypatch):
    chart_memo.forget()
    drawn: list[Path] = []
    real = charts.save
    monkeypatch.setattr(charts, "save", lambda fig, path: (drawn.append(Path(path)), real(fig, path)))

    class Opaque:
        def __call__(self, v: float) -> str:
            return f"{v:g}"
    for name in ("a.png", "b.png"):
        charts.bars(tmp_path / name, "t", "x", synthetic_bars(), fmt=Opaque())
    assert drawn == [tmp_path / "a.png", tmp_path / "b.png"]


def test_a_plot_that_saves_itself_is_remembered_with_its_result_and_only_what_it_wrote(tmp_path):
    chart_memo.forget()
    calls: list[Path] = []      # (a function capturing this list would key on its contents)

    def plot(records: list[dict], path: Path) -> bool:
        calls.append(path)
        if records:
            path.write_bytes(b"png" + repr(records).encode())
        return bool(records)
    recs = [{"backend": "warp", "value": 1.5}]
    a, b = tmp_path / "a.png", tmp_path / "b.png"
    assert chart_memo.remembered(("plot", recs), [a], lambda: plot(recs, a)) is True
    assert chart_memo.remembered(("plot", [dict(r) for r in recs]), [b], lambda: plot(recs, b)) is True
    assert calls == [a] and b.read_bytes() == a.read_bytes()
    stale = tmp_path / "stale.png"
    stale.write_bytes(b"an older picture")                  # there before; the plot draws nothing
    assert chart_memo.remembered(("plot", []), [stale], lambda: plot([], stale)) is False
    fresh = tmp_path / "fresh.png"
    assert chart_memo.remembered(("plot", []), [fresh], lambda: plot([], fresh)) is False
    assert not fresh.exists()                                  # the older picture was not remembered


SERVED = """
import sys
from pathlib import Path
sys.path.insert(0, "tests/render")
from test_charts import synthetic_bars
from compare.render import charts, report
charts.save = lambda fig, path: sys.exit("drawn")     # drawing here fails: the disk must serve it
charts.bars(Path(sys.argv[1]), "t", "x", synthetic_bars(), fmt=report.fmt_time)
"""


def test_a_chart_drawn_in_one_process_is_written_from_disk_in_another(tmp_path, monkeypatch):
    """COMPARE_CHART_MEMO_DIR (opt-in): another process with the same folder writes the bytes
    drawn here without drawing; off, the same bytes are drawn; a test's stand-in drawing (a few
    bytes for a picture) is not kept, and a damaged file is drawn, not served."""
    memo = tmp_path / "memo"
    memo.mkdir()
    bs = synthetic_bars()
    monkeypatch.setenv(chart_memo.DISK_ENV, str(memo))

    def served(name: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-c", SERVED, str(tmp_path / name)], cwd=ROOT, env=dict(os.environ),
                              capture_output=True, text=True, timeout=300)
    chart_memo.forget()
    monkeypatch.setattr(charts, "save", lambda fig, path: Path(path).write_bytes(b"png"))
    charts.bars(tmp_path / "stub.png", "t", "x", bs, fmt=report.fmt_time)
    assert list(memo.iterdir()) == []
    monkeypatch.undo()
    monkeypatch.setenv(chart_memo.DISK_ENV, str(memo))
    chart_memo.forget()
    charts.bars(tmp_path / "a.png", "t", "x", bs, fmt=report.fmt_time)
    assert len(list(memo.glob("*.json"))) == 1
    p = served("b.png")
    assert p.returncode == 0, p.stderr[-2000:]
    monkeypatch.setenv(chart_memo.DISK_ENV, "")
    chart_memo.forget()
    charts.bars(tmp_path / "c.png", "t", "x", bs, fmt=report.fmt_time)         # off: drawn
    for ext in (".png", ".csv"):
        a = (tmp_path / "a.png").with_suffix(ext).read_bytes()
        assert a == (tmp_path / "b.png").with_suffix(ext).read_bytes() == (tmp_path / "c.png").with_suffix(ext).read_bytes()
    next(memo.glob("*.json")).write_text('{"result": null, "files": ["not base64!"]}')
    monkeypatch.setenv(chart_memo.DISK_ENV, str(memo))
    assert served("d.png").returncode != 0                    # a damaged file: drawn
