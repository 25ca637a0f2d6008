"""Figures of :mod:`direct.plot`."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import direct  # noqa: E402
from direct.plot import plot_domain, plot_penalty, plot_scene  # noqa: E402


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


@pytest.fixture(scope="module")
def fig2():
    scene = direct.scenes.get("fig2")
    return scene, direct.penalty(scene, resolution=32)


def test_plot_penalty_fig2(fig2, tmp_path):
    scene, result = fig2
    domains = {tuple(sorted(c.components)) for c in result.crossings}
    assert domains == {(0, 1)}
    path = tmp_path / "fig2.png"
    fig = plot_penalty(result, scene, path=path)
    assert isinstance(fig, matplotlib.figure.Figure)
    assert len(fig.axes) == 1 + len(domains)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert f"{result.value:.7g}" in fig._suptitle.get_text()
    scene_ax, domain_ax = fig.axes
    assert scene_ax.get_aspect() == 1.0
    assert domain_ax.get_xlabel() == "x1 on I1"
    assert domain_ax.get_ylabel() == "x2 on I2"


def test_plot_penalty_without_crossings():
    comps = [
        direct.Component([[0, 0], [1, 0]], [[0, 0], [1, 0]], name="A"),
        direct.Component([[0, 1], [1, 1]], [[0, 0.5], [1, 0.5]], name="B"),
    ]
    scene = direct.Scene(tuple(comps), name="apart")
    result = direct.penalty(scene)
    assert result.crossings == [] and result.value == 0
    fig = plot_penalty(result, scene)
    assert len(fig.axes) == 1
    assert "no crossing" in fig._suptitle.get_text()


def test_plot_scene_marks_signed_crossings(fig2):
    scene, result = fig2
    fig, ax = plt.subplots()
    artists = plot_scene(scene, result.crossings, ax=ax)
    assert artists
    offsets = np.vstack([c.get_offsets() for c in ax.collections])
    expected = np.array([c.point for c in result.crossings])
    assert offsets.shape == expected.shape
    assert np.allclose(np.sort(offsets, axis=0), np.sort(expected, axis=0))
    assert ax.get_legend() is not None


def test_plot_domain_draws_the_curves(fig2):
    scene, result = fig2
    fig, ax = plt.subplots()
    plot_domain(result, scene, ("I1", "I2"), ax=ax, background=False)
    drawn = [line.get_xydata() for line in ax.get_lines()]
    half = [p for p in result.pairs if p.components == ("I1", "I2")]
    assert half
    for p in half:
        assert any(d.shape == p.path.shape and np.allclose(d, p.path) for d in drawn)
    assert ax.get_xlim()[1] > scene.components[0].length


def test_plot_penalty_circle_without_crossings():
    # a circle may need curves gamma without any crossing point: their domain is drawn too
    scene = direct.scenes.get("ring")
    result = direct.penalty(scene, resolution=16)
    index = {c.name: k for k, c in enumerate(scene.components)}
    domains = {tuple(sorted(int(v) for v in c.components)) for c in result.crossings}
    domains |= {tuple(sorted(index[n] for n in p.components)) for p in result.pairs}
    fig = plot_penalty(result, scene)
    assert len(fig.axes) == 1 + len(domains)
    for ax in fig.axes[1:]:
        labels = [t.get_text() for t in ax.get_legend().get_texts()]
        assert "seam (sides identified)" in labels  # the circle's two sides are identified


@pytest.mark.parametrize("pair", [(0, 5), (-1, 0), (True, 0), ("A",), ("I1", "nope")])
def test_plot_domain_refuses_a_pair_the_scene_does_not_have(pair):
    res = direct.penalty("fig2", refine=False)
    with pytest.raises(direct.SceneError):
        plot_domain(res, "fig2", pair)


def test_plot_refuses_a_result_of_another_scene():
    with pytest.raises(direct.SceneError, match="does not belong to scene 'loop'"):
        plot_penalty(direct.penalty("fig2", refine=False), "loop")


def test_plot_command_prints_the_file_it_wrote(tmp_path, capsys):
    from direct.cli import main

    assert main(["plot", "cross", "-o", str(tmp_path / "noext")]) == 0
    assert capsys.readouterr().out.strip() == str(tmp_path / "noext.png")
    assert (tmp_path / "noext.png").is_file()
    assert main(["plot", "cross", "-o", str(tmp_path / "dot.")]) == 0
    assert capsys.readouterr().out.strip() == str(tmp_path / "dot.png")
    assert (tmp_path / "dot.png").is_file()
    assert main(["plot", "cross", "-o", str(tmp_path)]) == 2
    assert "it is a folder" in capsys.readouterr().err
