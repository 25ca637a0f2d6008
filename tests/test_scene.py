"""Scenes, the JSON format, and every input check."""

from __future__ import annotations

import json

import numpy as np
import pytest

import direct


def _write(tmp_path, data, raw=False):
    p = tmp_path / "scene.json"
    p.write_text(data if raw else json.dumps(data))
    return p


def test_json_round_trip(tmp_path):
    sc = direct.scenes.get("fig2")
    p = tmp_path / "fig2.json"
    sc.to_json(p)
    back = direct.load_scene(p)
    assert [c.name for c in back.components] == ["I1", "I2"]
    for a, b in zip(sc.components, back.components):
        np.testing.assert_array_equal(a.reference, b.reference)
        np.testing.assert_array_equal(a.deformed, b.deformed)
        assert a.closed == b.closed


def test_params_are_reference_arclength():
    c = direct.Component([[0, 0], [3, 4], [3, 5]], [[0, 0], [1, 0], [1, 7]])
    np.testing.assert_allclose(c.params, [0, 5, 6])
    np.testing.assert_allclose(c.velocities, [[0.2, 0], [0, 7]])
    np.testing.assert_allclose(c.phi([2.5, 5.5]), [[0.5, 0], [1, 3.5]])


def test_closing_vertex_is_dropped():
    c = direct.Component([[0, 0], [1, 0], [0, 1], [0, 0]], [[0, 0], [2, 0], [0, 2], [0, 0]], closed=True)
    assert c.n_vertices == 3 and c.n_segments == 3
    assert c.length == pytest.approx(2 + np.sqrt(2))


@pytest.mark.parametrize("which", ["reference", "deformed"])
def test_a_closing_vertex_repeated_in_one_array_only_is_dropped(which):
    tri, big = [[0, 0], [1, 0], [0, 1]], [[0, 0], [2, 0], [0, 2]]
    arrays = {"reference": tri, "deformed": big}
    arrays[which] = arrays[which] + [arrays[which][0]]
    c = direct.Component(arrays["reference"], arrays["deformed"], closed=True)
    assert c.n_vertices == 3 and c.length == pytest.approx(2 + np.sqrt(2))
    np.testing.assert_allclose(c.phi([0.5]), [[1.0, 0.0]])
    with pytest.raises(direct.SceneError, match="4 reference vertices but 3 deformed"):  # an interval: no closing
        direct.Component(tri + [[0, 0]], big)


def test_reversal_keeps_the_image():
    c = direct.Component([[0, 0], [1, 0], [1, 2]], [[0, 0], [2, 0], [2, 1]])
    r = c.reversed()
    s = np.linspace(0, c.length, 7)
    np.testing.assert_allclose(r.phi(c.length - s), c.phi(s), atol=1e-12)


@pytest.mark.parametrize(
    "kwargs,match",
    [
        (dict(reference=[[0, 0], [np.nan, 1]], deformed=[[0, 0], [1, 1]]), r"reference vertex 1 .*finite"),
        (dict(reference=[[0, 0], [1, 1]], deformed=[[0, 0], [np.inf, 1]]), r"deformed vertex 1 .*finite"),
        # an integer beyond the floats (a JSON file's 10**400) raised OverflowError (a review at stop 48)
        (dict(reference=[[0, 0], [10**400, 0]], deformed=[[0, 0], [1, 0]]), r"reference vertex 1 .*too large"),
        (dict(reference=[[0, 0]], deformed=[[0, 0]]), "at least 2 vertices"),
        (dict(reference=[[0, 0], [1, 0]], deformed=[[0, 0], [1, 0]], closed=True), "at least 3 vertices"),
        (dict(reference=[[0, 0], [1, 0], [2, 0]], deformed=[[0, 0], [1, 0]]), "3 reference vertices but 2 deformed"),
        (dict(reference=[[0, 0], [1, 0], [1, 0]], deformed=[[0, 0], [1, 0], [2, 0]]), "vertices 1 and 2 coincide"),
        (dict(reference=[[0, 0, 0], [1, 0, 0]], deformed=[[0, 0], [1, 0]]), r"shape \(n, 2\)"),
        (dict(reference="abc", deformed=[[0, 0], [1, 0]]), "reference vertices"),
        (dict(reference=[[0, 0], [1, 0]], deformed=[[0, 0], [1, 0]], closed="yes"), "'closed' must be"),
    ],
)
def test_component_checks(kwargs, match):
    with pytest.raises(direct.SceneError, match=match) as info:
        direct.Component(name="K", **kwargs)
    assert "'K'" in str(info.value)


def test_reference_must_be_an_embedding():
    a = direct.Component([[0, 0], [2, 0]], [[0, 0], [2, 0]], name="A")
    b = direct.Component([[1, -1], [1, 1]], [[5, -1], [5, 1]], name="B")
    with pytest.raises(direct.SceneError, match=r"not an embedding.*'A'.*'B'"):
        direct.Scene((a, b))
    loop = direct.Component([[0, 0], [2, 0], [2, 1], [1, -1]], [[0, 0], [2, 0], [2, 1], [1, -1]], name="L")
    with pytest.raises(direct.SceneError, match=r"segment 0 .*segment 2 .*'L'"):
        direct.Scene((loop,))
    back = direct.Component([[0, 0], [2, 0], [1, 0]], [[0, 0], [2, 0], [1, 0]], name="F")
    with pytest.raises(direct.SceneError, match="not an embedding"):
        direct.Scene((back,))


def test_scene_checks():
    a = direct.Component([[0, 0], [1, 0]], [[0, 0], [1, 0]], name="A")
    b = direct.Component([[0, 1], [1, 1]], [[0, 1], [1, 1]], name="A")
    with pytest.raises(direct.SceneError, match="distinct"):
        direct.Scene((a, b))
    with pytest.raises(direct.SceneError, match="no component"):
        direct.Scene(())


@pytest.mark.parametrize(
    "text,match",
    [
        ("{not json", "not valid JSON"),
        ("[]", '"components"'),
        ('{"components": {}}', "must be a list"),
        ('{"components": [3]}', "must be a JSON object"),
        ('{"components": [{"reference": [[0,0],[1,0]]}]}', "deformed"),
        ('{"components": [{"reference": [[0,0],[1,0]], "deformed": [[0,0],[1,0]], "colour": 1}]}', "unknown key"),
        ('{"components": [{"name": 5, "reference": [[0,0],[1,0]], "deformed": [[0,0],[1,0]]}]}', "'name' must"),
        ('{"components": [{"reference": [[0,0],[1,0]], "deformed": [[0,0],[1,0]]}], "metric": "g"}',
         r"not the options \['metric'\]"),
    ],
)
def test_file_checks(tmp_path, text, match):
    with pytest.raises(direct.SceneFileError, match=match):
        direct.load_scene(_write(tmp_path, text, raw=True))


def test_a_scene_given_as_one_component_is_refused():
    c = direct.Component([[0, 0], [1, 0]], [[0, 0], [1, 0]])
    with pytest.raises(direct.SceneError, match=r"Scene\(\(A,\)\)"):
        direct.Scene(c)
    assert direct.Scene([c]).components[0].name == "C0"


def test_missing_file(tmp_path):
    with pytest.raises(direct.SceneFileError, match="cannot read"):
        direct.load_scene(tmp_path / "nope.json")


def test_nan_in_file_names_vertex(tmp_path):
    text = '{"components": [{"name": "X", "reference": [[0,0],[1,0],[2,0]], "deformed": [[0,0],[NaN,0],[2,0]]}]}'
    with pytest.raises(direct.SceneError, match=r"'X'.*deformed vertex 1"):
        direct.load_scene(_write(tmp_path, text, raw=True))


def test_builtin_scenes_and_resolve(tmp_path):
    assert {"cross", "cross60", "fig2"} <= set(direct.scenes.names())
    for name in direct.scenes.names():
        assert isinstance(direct.scenes.get(name), direct.Scene)
    with pytest.raises(direct.SceneError, match="no built-in scene"):
        direct.scenes.get("nope")
    p = tmp_path / "s.json"
    direct.scenes.get("cross").to_json(p)
    assert direct.scenes.resolve(str(p)).components[0].name == "A"
    with pytest.raises(direct.SceneError, match="neither a scene file"):
        direct.scenes.resolve("nope")


def test_errors_are_one_family():
    for cls in (direct.SceneError, direct.SceneFileError, direct.DegenerateError, direct.NotSupportedError,
                direct.ConvergenceError):
        assert issubclass(cls, direct.DirectError)


@pytest.mark.parametrize("vertices,bad", [([["0", "0"], ["1", "0"]], 0), ([[0, 0], [True, False]], 1),
                                          ([[0, 0], None], 1), ([[0, 0], [1]], 1), ([[0, 0], [None, 1]], 1)])
def test_vertices_must_be_pairs_of_numbers(vertices, bad):
    """numpy would read strings and booleans as numbers; each is refused with the vertex at fault."""
    with pytest.raises(direct.SceneError, match=rf"component 'A': reference vertex {bad} is .* pair \[x, y\]"):
        direct.Component(vertices, [[0, 0], [1, 1]], name="A")


def test_any_real_numbers_are_coordinates():
    from fractions import Fraction

    comp = direct.Component([[Fraction(1, 2), 0], [1, np.float64(0)]], [[0, np.array(0.0)], [1, 1]], name=None)
    assert comp.reference[0, 0] == 0.5
    assert direct.Scene((comp,)).components[0].name == "C0"


def test_component_name_must_be_a_string():
    with pytest.raises(direct.SceneError, match="name must be a string"):
        direct.Component([[0, 0], [1, 0]], [[0, 0], [1, 0]], name=5)


def test_default_names_avoid_the_given_ones():
    a = direct.Component([[0, 0], [1, 0]], [[0, 0], [1, 0]], name="C1")
    b = direct.Component([[0, 1], [1, 1]], [[0, 1], [1, 1]])
    assert [c.name for c in direct.Scene((a, b)).components] == ["C1", "C1'"]
    data = {"components": [{"name": "C1", "reference": [[0, 0], [1, 0]], "deformed": [[0, 0], [1, 0]]},
                           {"reference": [[0, 1], [1, 1]], "deformed": [[0, 1], [1, 1]]}]}
    assert [c.name for c in direct.Scene.from_dict(data).components] == ["C1", "C1'"]


def test_reference_vertices_too_close_for_floating_point():
    with pytest.raises(direct.SceneError, match=r"reference vertices 0 and 1 are 1e-170 apart"):
        direct.Component([[0, 0], [1e-170, 0], [1, 0]], [[0, 0], [1, 0], [2, 0]], name="A")


def test_with_deformed_wants_one_polyline_per_component():
    sc = direct.scenes.get("fig2")
    moved = sc.with_deformed([c.deformed + 1.0 for c in sc.components])
    assert [c.name for c in moved.components] == ["I1", "I2"]
    np.testing.assert_array_equal(moved.components[1].deformed, sc.components[1].deformed + 1.0)
    with pytest.raises(direct.SceneError, match="1 deformed polylines for the 2 components"):
        sc.with_deformed([sc.components[0].deformed])


def test_a_reparametrized_component_is_the_same_curve_in_another_parameter():
    """``Component.reparametrized``: segment k spans ``widths[k]``; the vertices map to the same points, the
    parameter maps back to the reference arclength affinely on each segment (periodically on a circle), and
    widths that are not one positive number per segment are refused."""
    c = direct.Component([[0, 0], [1, 0], [1, 3], [0, 3]], [[0, 0], [2, 0], [2, 1], [0, 2]], closed=True, name="q")
    r = c.reparametrized([2.0, 1.0, 2.0, 4.0])
    np.testing.assert_allclose(r.params, [0, 2, 3, 5, 9])
    np.testing.assert_allclose(r.phi(r.params), c.phi(c.params))
    np.testing.assert_allclose(r.j(r.params), c.j(c.params))
    np.testing.assert_allclose(r.reference_arclength(r.params), c.params)
    # halfway along a segment, and a turn and a half on
    np.testing.assert_allclose(r.reference_arclength([1.0, 9 + 4.0]), [0.5, 8 + 4.5])
    np.testing.assert_allclose(r.phi(4.0), c.phi(4.5))
    for bad in ([1.0, 1.0, 1.0], [1.0, 0.0, 1.0, 1.0], [1.0, np.nan, 1.0, 1.0]):
        with pytest.raises(direct.SceneError, match="'q': widths must be 4 positive"):
            c.reparametrized(bad)
