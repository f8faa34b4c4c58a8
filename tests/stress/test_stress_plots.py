"""compare/stress/plots.py: a backend's colour and a device's marker in every stress plot, and a
failing plot that loses nothing (fast tier). Named test_stress_plots: pytest collects test files
by basename, and compare/sweep/ has a plots module too."""
from __future__ import annotations

import backends
from compare.render.colors import backend_color
from compare.stress import plots
from compare.stress.numerics import ORACLE, Experiment


def test_style_is_the_backends_colour_and_the_devices_marker():
    name = next(iter(backends.BACKENDS))
    assert plots._style(f"{name}/cuda") == {"color": backend_color(name), "marker": "^", "markersize": 4}
    assert plots._style(f"{name}/cpu")["marker"] == "o"
    assert plots._colour(ORACLE) == f"C{len(backends.BACKENDS) % 10}" and plots._colour("prediction") == "k"


def test_draw_writes_the_plot_the_experiment_draws(tmp_path):
    seen = {}

    def plot(series, out, style):
        seen["style"] = style("warp/cuda")
        out.write(b"\x89PNG drawn")
    plots.draw(Experiment("e", "t", lambda ctx: ([], {}), plot), {"a": [1]}, tmp_path / "e.png")
    assert (tmp_path / "e.png").read_bytes() == b"\x89PNG drawn" and seen["style"]["marker"] == "^"


def test_nothing_to_draw_and_a_failing_plot_write_nothing_and_warn(tmp_path, capsys):
    plots.draw(Experiment("e", "t", lambda ctx: ([], {})), {"a": [1]}, tmp_path / "none.png")
    plots.draw(Experiment("e", "t", lambda ctx: ([], {}), lambda s, o, st: o.write(b"x")), {}, tmp_path / "empty.png")

    def broken(series, out, style):
        out.write(b"half")
        raise KeyError("lines")
    plots.draw(Experiment("bad", "t", lambda ctx: ([], {}), broken), {"a": [1]}, tmp_path / "bad.png")
    assert not list(tmp_path.iterdir())
    assert "warning: plot bad failed: KeyError" in capsys.readouterr().err
