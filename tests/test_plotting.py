"""kinodyn.plotting: the plotting building blocks write PNG and SVG in one style."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest

from kinodyn import contacts
from kinodyn.data import library
from kinodyn.errors import ParameterError
from kinodyn import plotting as plots
from kinodyn.plotting import style

pytest.importorskip("matplotlib")


def written(paths) -> None:
    for p in paths:
        assert p.stat().st_size > 1000, p
        if p.suffix == ".svg":
            ET.parse(p)  # well-formed XML
        else:
            assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_phase_timeline_png_and_svg(tmp_path):
    fig = plots.phase_timeline([("a", [(0, 0.5, "DS"), (0.5, 1.2, "LS")]), ("b", [(0, 1.0, "reach")])],
                               events=[(0.7, "impact")], title="t")
    paths = plots.save(fig, tmp_path / "timeline")
    assert [p.name for p in paths] == ["timeline.png", "timeline.svg"]
    written(paths)
    ax = fig.axes[0]
    assert [t.get_text() for t in ax.get_yticklabels()] == ["b", "a"]  # first track on top
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert legend == ["DS", "LS", "reach"]
    colours = {p.get_label(): p.get_facecolor() for p in ax.get_legend().get_patches()}
    assert np.allclose(colours["DS"][:3], style.rgb(style.PHASE_COLORS["DS"]))


def test_support_bars_from_contacts(tmp_path):
    walk = library.load("walk")
    fig = plots.support_bars({"walk": contacts.detect(walk).as_array()}, walk.fps)
    written(plots.save(fig, tmp_path / "support.svg"))
    assert not (tmp_path / "support.png").exists()


def test_error_surface_marks_the_minimum(tmp_path):
    x = np.linspace(-1, 1, 21)
    y = np.linspace(0, 2, 11)
    z = (x[None] - 0.3) ** 2 + (y[:, None] - 1.2) ** 2 + 0.05
    fig = plots.error_surface(x, y, z, xlabel="dt", ylabel="h", log=True)
    written(plots.save(fig, tmp_path / "surface"))
    from matplotlib.collections import PathCollection

    marks = [c for c in fig.axes[0].collections if isinstance(c, PathCollection)]
    assert np.allclose(marks[0].get_offsets()[0], [0.3, 1.2])
    with pytest.raises(ParameterError, match=r"shape \(len\(y\), len\(x\)\)"):
        plots.error_surface(x, y, z.T)


def test_scatter_map_highlights(tmp_path, rng):
    p = rng.normal(size=(30, 2))
    fig = plots.scatter_map(p, values=rng.random(30), highlight=[4, 9], labels=[f"s{i}" for i in range(30)])
    written(plots.save(fig, tmp_path / "map"))
    texts = [t.get_text() for t in fig.axes[0].texts]
    assert texts == ["s4", "s9"]
    fig = plots.scatter_map(p, categories=["a", "b", "c"] * 10)
    assert [t.get_text() for t in fig.axes[0].get_legend().get_texts()] == ["a", "b", "c"]
    with pytest.raises(ParameterError, match="highlight indices"):
        plots.scatter_map(p, highlight=[30])
    with pytest.raises(ParameterError, match=r"shape \(N, 2\)"):
        plots.scatter_map(p[:, :1])


def test_time_series_and_bad_formats(tmp_path):
    t = np.arange(50) / 10
    fig = plots.time_series(t, {"a": np.sin(t), "b": np.cos(t)}, spans=[(1, 2, "DS")], ylabel="m")
    written(plots.save(fig, tmp_path / "ts"))
    with pytest.raises(ParameterError, match="plot formats"):
        plots.save(fig, tmp_path / "ts", formats=("jpg",))
    with pytest.raises(ParameterError, match="series 'x' must have shape"):
        plots.time_series(t, {"x": t[:3]})


def test_style_colours():
    assert style.color("C1") == style.PALETTE[1]
    assert style.color((1, 0, 0)) == "#ff0000"
    assert style.color("#ABCDEF") == "#abcdef"
    with pytest.raises(ParameterError, match="colour must be"):
        style.color("reddish")
    assert style.character_colors(3, [None, "#000000", None]) == [style.PALETTE[0], "#000000", style.PALETTE[2]]


def test_write_figure_uses_the_savefig_settings_given(tmp_path):
    plt = plots.pyplot()
    fig, ax = plt.subplots(figsize=(2, 1))
    ax.plot([0, 1], [0, 1])
    small = plots.write_figure(fig, tmp_path / "a.png", dpi=50)
    big = plots.write_figure(fig, tmp_path / "b.png", dpi=200)
    plt.close(fig)
    assert small.read_bytes()[:8] == big.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert big.stat().st_size > 2 * small.stat().st_size
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png", "b.png"]  # no temporary left behind
