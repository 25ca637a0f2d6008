"""Tests of direct.crossings: signed crossings, degenerate contacts, invariances, brute force."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import insert_vertex
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import direct
from direct import Component, DegenerateError, Scene
from direct import crossings as crossings_module
from direct.crossings import Crossing, crossings_as_arrays, find_crossings

FAST = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
SEEDS = st.integers(min_value=0, max_value=2**32 - 1)


# -- scene builders ---------------------------------------------------------------------------
def open_comp(deformed, row: int = 0, name: str = "") -> Component:
    """An open component whose reference is a horizontal polyline with unit steps (integer params)."""
    d = np.asarray(deformed, dtype=float)
    ref = np.column_stack([np.arange(len(d)), np.full(len(d), 3.0 * row)])
    return Component(ref, d, False, name)


def closed_comp(deformed, row: int = 0, name: str = "") -> Component:
    """A closed component with an even number of vertices and a unit-step rectangular reference."""
    d = np.asarray(deformed, dtype=float)
    n = len(d)
    assert n % 2 == 0 and n >= 4
    k = n // 2 - 1
    bottom = [[x, 3.0 * row] for x in range(k + 1)]
    top = [[x, 3.0 * row + 1] for x in range(k, -1, -1)]
    return Component(np.array(bottom + top, dtype=float), d, True, name)


def polygon_comp(deformed, row: int = 0, name: str = "") -> Component:
    """A closed component with a regular-polygon reference (any number of vertices)."""
    d = np.asarray(deformed, dtype=float)
    ang = np.linspace(0.0, 2 * np.pi, len(d), endpoint=False)
    ref = np.column_stack([np.cos(ang) + 3.0 * row, np.sin(ang) + 100.0])
    return Component(ref, d, True, name)


def scene(*comps: Component) -> Scene:
    return Scene(tuple(comps))


def random_generic_scene(seed: int, closed=None) -> Scene:
    """Random polylines in general position (float coordinates); some components closed."""
    rng = np.random.default_rng(seed)
    n_comp = int(rng.integers(1, 4))
    comps = []
    for k in range(n_comp):
        is_closed = bool(rng.integers(0, 2)) if closed is None else closed
        n = int(rng.integers(3, 8))
        d = rng.normal(size=(n, 2))
        if is_closed:
            comps.append(polygon_comp(d, k, f"C{k}"))
        else:
            steps = rng.uniform(0.3, 1.5, size=n - 1)
            ref = np.column_stack([np.concatenate([[0.0], np.cumsum(steps)]), np.full(n, 3.0 * k)])
            comps.append(Component(ref, d, False, f"C{k}"))
    return Scene(tuple(comps))


def random_grid_scene(seed: int, closed: bool | None = None, grid: int = 3) -> Scene:
    """Random polylines with small integer deformed vertices: full of degenerate contacts."""
    rng = np.random.default_rng(seed)
    comps = []
    for k in range(int(rng.integers(1, 4))):
        is_closed = bool(rng.integers(0, 2)) if closed is None else closed
        if is_closed:
            n = 2 * int(rng.integers(2, 4))
            comps.append(closed_comp(rng.integers(0, grid, size=(n, 2)), k, f"K{k}"))
        else:
            n = int(rng.integers(2, 6))
            comps.append(open_comp(rng.integers(0, grid, size=(n, 2)), k, f"K{k}"))
    return Scene(tuple(comps))


def replace(sc: Scene, k: int, comp: Component) -> Scene:
    comps = list(sc.components)
    comps[k] = comp
    return Scene(tuple(comps))


def transform(sc: Scene, matrix, shift=(0.0, 0.0)) -> Scene:
    m = np.asarray(matrix, dtype=float)
    return sc.with_deformed([c.deformed @ m.T + np.asarray(shift, dtype=float) for c in sc.components])


def summary(crossings):
    return [(c.components, c.params, c.point, c.sign) for c in crossings]


def assert_same(a, b, tol=1e-12):
    """Same signed crossing sets: components, signs, and params and points up to tol."""
    assert len(a) == len(b), (summary(a), summary(b))
    for x, y in zip(a, b, strict=True):
        assert x.components == y.components, (summary(a), summary(b))
        assert x.sign == y.sign, (summary(a), summary(b))
        np.testing.assert_allclose(x.params, y.params, rtol=0, atol=tol)
        np.testing.assert_allclose(x.point, y.point, rtol=0, atol=tol)


def brute_force(sc: Scene):
    """Independent O(n^2) loop: transversal crossings of the segments interiors, solved pair by pair."""
    segs = []
    for c, comp in enumerate(sc.components):
        ring, par = comp.deformed_ring, comp.params
        for k in range(comp.n_segments):
            segs.append((c, k, ring[k], ring[k + 1], par[k], par[k + 1], comp))
    out = []
    for a in range(len(segs)):
        for b in range(a + 1, len(segs)):
            c1, k1, p0, p1, s0, s1, comp1 = segs[a]
            c2, k2, q0, q1, t0, t1, _ = segs[b]
            if c1 == c2:
                n = comp1.n_segments
                if abs(k1 - k2) == 1 or (comp1.closed and abs(k1 - k2) == n - 1):
                    continue
            m = np.column_stack([p1 - p0, -(q1 - q0)])
            det = m[0, 0] * m[1, 1] - m[0, 1] * m[1, 0]
            if det == 0:
                continue
            lam, mu = np.linalg.solve(m, q0 - p0)
            if 0 < lam < 1 and 0 < mu < 1:
                x1, x2 = s0 + lam * (s1 - s0), t0 + mu * (t1 - t0)
                dp, dq = p1 - p0, q1 - q0
                sign = int(np.sign(dp[0] * dq[1] - dp[1] * dq[0]))
                if c1 == c2 and x1 > x2:
                    x1, x2, sign = x2, x1, -sign
                out.append(((c1, c2), (x1, x2), sign))
    return sorted(out)


def signed_total(crossings, pair):
    return sum(c.sign for c in crossings if c.components == pair)


# -- the built-in scenes ----------------------------------------------------------------------
def test_cross_scene():
    (c,) = find_crossings(direct.scenes.get("cross"))
    assert isinstance(c, Crossing)
    assert c.components == (0, 1)
    assert c.params == pytest.approx((0.5, 0.5), abs=1e-15)
    assert c.point == pytest.approx((0.0, 0.0), abs=1e-15)
    assert c.segments == (0, 0)
    assert c.sign == +1  # first along +x, second along +y
    assert c.exact is True


@pytest.mark.parametrize("angle", [0.2, 1.0, np.pi / 2, 2.0, 3.0, 3.5, 4.4, 5.0, 6.0])
def test_cross_sign_is_det_of_velocities(angle):
    (c,) = find_crossings(direct.scenes.cross(0.3, 0.7, 0.4, 0.6, angle))
    assert c.params == pytest.approx((0.3, 0.4), abs=1e-12)
    assert c.sign == int(np.sign(np.sin(angle)))
    assert c.point == pytest.approx((0.0, 0.0), abs=1e-12)


def test_cross60():
    (c,) = find_crossings(direct.scenes.get("cross60"))
    assert c.params == pytest.approx((1.0, 1.0), abs=1e-12)
    assert c.sign == 1


def test_fig2_two_crossings_of_opposite_signs():
    cs = find_crossings(direct.scenes.get("fig2"))
    assert [c.components for c in cs] == [(0, 1), (0, 1)]
    # I1 runs along y = 0; I2 goes down through x = 0.5 and back up through x = 2.5
    assert cs[0].params == pytest.approx((0.5, 0.5), abs=1e-12)
    assert cs[1].params == pytest.approx((2.5, 2.5), abs=1e-12)
    assert cs[0].point == pytest.approx((0.5, 0.0), abs=1e-12)
    assert [c.sign for c in cs] == [-1, 1]
    assert [c.segments for c in cs] == [(0, 0), (0, 2)]
    assert all(c.exact for c in cs)


def test_to_dict_and_arrays():
    sc = direct.scenes.get("fig2")
    cs = find_crossings(sc)
    d = cs[0].to_dict(sc)
    assert d == {"components": ["I1", "I2"], "params": [0.5, 0.5], "point": [0.5, 0.0], "sign": -1, "exact": True}
    assert cs[0].to_dict()["components"] == [0, 1]
    arr = crossings_as_arrays(cs)
    assert arr["components"].shape == (2, 2) and arr["components"].dtype.kind == "i"
    np.testing.assert_array_equal(arr["sign"], [-1, 1])
    np.testing.assert_allclose(arr["params"], [[0.5, 0.5], [2.5, 2.5]], atol=1e-12)
    np.testing.assert_array_equal(arr["segments"], [[0, 0], [0, 2]])
    assert crossings_as_arrays([])["params"].shape == (0, 2)


# -- self-crossings ---------------------------------------------------------------------------
def test_open_loop_has_one_self_crossing():
    # (0,0) -> (2,0) -> (1,1) -> (1,-1): the third segment crosses the first at (1, 0)
    (c,) = find_crossings(scene(open_comp([[0, 0], [2, 0], [1, 1], [1, -1]])))
    assert c.components == (0, 0)
    assert c.params[0] < c.params[1]
    assert c.params == pytest.approx((0.5, 2.5), abs=1e-12)
    assert c.point == pytest.approx((1.0, 0.0), abs=1e-12)
    # det(phi'(0.5), phi'(2.5)) = det((2,0), (0,-2)) < 0
    assert c.sign == -1
    assert c.segments == (0, 2)


def test_consecutive_segments_do_not_cross_at_their_shared_vertex():
    zigzag = open_comp([[0, 0], [1, 1], [2, 0], [3, 1], [4, 0]])
    square = closed_comp([[0, 5], [1, 5], [1, 6], [0, 6]], row=1)
    sharp = open_comp([[0, 10], [1, 10], [0, 10.001]], row=2)
    assert find_crossings(scene(zigzag, square, sharp)) == []


def test_closed_figure_eight_has_one_self_crossing():
    eight = polygon_comp([[1, 1], [1, -1], [-1, 1], [-1, -1]])
    (c,) = find_crossings(scene(eight))
    assert c.components == (0, 0) and c.params[0] < c.params[1]
    assert c.point == pytest.approx((0.0, 0.0), abs=1e-12)
    assert c.exact


def test_closed_figure_eight_with_vertex_0_at_the_crossing():
    # vertex 0 and vertex 3 are both at the origin: the crossing sits on the closing vertex
    eight = closed_comp([[0, 0], [1, 1], [1, -1], [0, 0], [-1, 1], [-1, -1]])
    (c,) = find_crossings(scene(eight))
    assert c.components == (0, 0)
    assert c.params == (0.0, 3.0)
    assert c.segments == (0, 3)
    assert c.point == (0.0, 0.0)
    assert not c.exact
    # same sign as the smooth figure eight through (1,1),(1,-1),(-1,1),(-1,-1) started at the crossing
    smooth = closed_comp([[0, 0], [1, 1], [1, -1], [1e-3, 0], [-1, 1], [-1, -1]])
    (g,) = find_crossings(scene(smooth))
    assert g.exact and g.sign == c.sign


def test_closed_component_params_in_range():
    for seed in range(20):
        sc = random_generic_scene(seed, closed=True)
        for c in find_crossings(sc):
            for k, x in zip(c.components, c.params, strict=True):
                assert 0 <= x < sc.components[k].length


# -- degenerate contacts ----------------------------------------------------------------------
LINE = [[-2, 0], [2, 0]]  # reference length 1: x = 0 is param 0.5


def test_crossing_at_a_vertex_counts_once():
    for b, sign in [([[0, -1], [0, 0], [1, 1]], 1), ([[0, 1], [0, 0], [-1, -1]], -1), ([[1, -1], [0, 0], [0, 2]], 1)]:
        cs = find_crossings(scene(open_comp(LINE), open_comp(b, 1)))
        assert len(cs) == 1, cs
        (c,) = cs
        assert c.params == (0.5, 1.0)
        assert c.segments == (0, 1)  # the segment starting at the vertex
        assert c.point == (0.0, 0.0)
        assert c.sign == sign
        assert not c.exact


def test_vertex_touching_without_crossing_counts_zero():
    for b in ([[-1, -1], [0, 0], [1, -1]], [[-1, 1], [0, 0], [1, 1]], [[-1, 1], [0, 0], [-1, 2]]):
        assert find_crossings(scene(open_comp(LINE), open_comp(b, 1))) == []
    # a corner touching a corner
    a = open_comp([[-1, 1], [0, 0], [1, 1]])
    assert find_crossings(scene(a, open_comp([[-1, -1], [0, 0], [1, -1]], 1))) == []


def test_vertex_on_vertex():
    a = open_comp([[-2, 0], [0, 0], [2, 1]])
    b = open_comp([[0, -2], [0, 0], [-1, 2]], 1)
    (c,) = find_crossings(scene(a, b))
    assert c.params == (1.0, 1.0) and c.segments == (1, 1) and c.point == (0.0, 0.0)
    # both pass from one side to the other: the sign is that of any nearby generic position
    for shift in ([1e-6, 0], [-1e-6, 1e-7], [0, 1e-6], [0, -1e-6], [1e-6, 1e-6]):
        moved = scene(a, open_comp(np.asarray(b.deformed) + shift, 1))
        assert [g.sign for g in find_crossings(moved)] == [c.sign]
    # touching corners: none
    b2 = open_comp([[0, -2], [0, 0], [1, -2]], 1)
    assert find_crossings(scene(a, b2)) == []


@pytest.mark.parametrize(
    "b, expected",
    [
        ([[-3, 1], [-1, 0], [1, 0], [3, -1]], [-1]),  # along the line, leaves on the other side
        ([[-3, -1], [-1, 0], [1, 0], [3, 1]], [1]),
        ([[-3, 1], [-1, 0], [1, 0], [3, 1]], []),  # leaves on the same side
        ([[-3, -1], [-1, 0], [1, 0], [3, -1]], []),
        ([[-3, 1], [-1, 0], [0, 0], [0.5, 0], [1, 0], [3, -1]], [-1]),  # extra vertices on the overlap
    ],
)
def test_collinear_overlap(b, expected):
    cs = find_crossings(scene(open_comp(LINE), open_comp(b, 1)))
    assert [c.sign for c in cs] == expected
    for c in cs:
        assert not c.exact
        # reported at the end of the shared stretch with the smaller parameter on the first curve
        assert c.point == (-1.0, 0.0) and c.params == (0.25, 1.0)


def test_collinear_overlap_through_vertices_of_both_curves():
    a = open_comp([[-3, 0], [-1, 0], [0, 0], [2, 0], [3, 1]])
    b = open_comp([[-2, 1], [-2, 0], [0, 0], [1, 0], [2, 0], [2, -1]], 1)
    (c,) = find_crossings(scene(a, b))
    assert c.point == (-2.0, 0.0)
    # a runs along +x, b arrives from above and leaves below: det((1,0),(0,-1)) = -1
    assert c.sign == -1
    # overlap with a bend: both turn together at (2, 0)
    a2 = open_comp([[-3, 0], [2, 0], [2, 3]])
    b2 = open_comp([[-2, 1], [-2, 0], [2, 0], [2, 2], [3, 3]], 1)
    (c2,) = find_crossings(scene(a2, b2))
    assert c2.point == (-2.0, 0.0)
    assert c2.sign == -1  # from the left side of a (above) to its right side (x > 2)
    b3 = open_comp([[-2, 1], [-2, 0], [2, 0], [2, 2], [1, 3]], 1)
    assert find_crossings(scene(a2, b3)) == []


def test_overlap_signs_match_nearby_generic_positions():
    """The signed total between two curves is that of any small generic displacement."""
    cases = [
        (LINE, [[-3, 1], [-1, 0], [1, 0], [3, -1]]),
        (LINE, [[-3, 1], [-1, 0], [1, 0], [3, 1]]),
        ([[-3, 0], [-1, 0], [0, 0], [2, 0], [3, 1]], [[-2, 1], [-2, 0], [0, 0], [1, 0], [2, 0], [2, -1]]),
        ([[0, 0], [2, 0], [2, 2], [0, 2]], [[1, -1], [1, 0], [2, 0], [2, 1], [3, 1]]),
        ([[-1, 0], [0, 0], [1, 0]], [[-1, 1], [0, 0], [0, 0], [1, -1]]),  # collapsed segment
    ]
    for a, b in cases:
        sc = scene(open_comp(a), open_comp(b, 1))
        total = signed_total(find_crossings(sc), (0, 1))
        for shift in ([1e-7, 3e-8], [-2e-8, 1e-7], [-1e-7, -3e-8], [2e-8, -1e-7]):
            moved = scene(open_comp(a), open_comp(np.asarray(b, float) + shift, 1))
            assert all(c.exact for c in find_crossings(moved))
            assert signed_total(find_crossings(moved), (0, 1)) == total, (a, b, shift)


def test_collapsed_segment():
    # the second curve stays still at the origin for a whole segment
    cs = find_crossings(scene(open_comp(LINE), open_comp([[0, -1], [0, 0], [0, 0], [0, 1]], 1)))
    assert [(c.sign, c.point) for c in cs] == [(1, (0.0, 0.0))]
    assert cs[0].params == (0.5, 1.0)
    assert find_crossings(scene(open_comp(LINE), open_comp([[0, -1], [0, 0], [0, 0], [1, -1]], 1))) == []


def test_fold_back_is_not_a_crossing():
    # a curve going out and back along itself: the contact reaches the diagonal, no crossing
    assert find_crossings(scene(open_comp([[0, 0], [2, 0], [1, 0], [1, 1]]))) == []
    assert find_crossings(scene(open_comp([[0, 0], [2, 0], [1, 0], [1, -1]]))) == []
    # ... but a real crossing elsewhere on the same curve is still found
    curve = open_comp([[0, 0], [2, 0], [1, 0], [1, 1], [5, 1], [5, -1], [4, -1], [4, 2]])
    (c,) = find_crossings(scene(curve))
    assert c.point == pytest.approx((4.0, 1.0), abs=1e-12)
    assert c.params == pytest.approx((3.75, 6 + 2 / 3), abs=1e-12)
    assert c.sign == 1 and c.exact and c.components == (0, 0)


def test_closed_curves_touching_or_sharing_an_edge():
    sq = closed_comp([[0, 0], [2, 0], [2, 2], [0, 2]])
    for other in (
        [[1, 0], [3, 0], [3, -2], [1, -2]],  # shares part of an edge, outside
        [[2, 2], [3, 2], [3, 3], [2, 3]],  # corner to corner
        [[1, 0], [1.5, 1], [2, 0], [1.5, -1]],  # one vertex on the edge from inside, ... crossing twice
    ):
        cs = find_crossings(scene(sq, closed_comp(other, 1)))
        assert signed_total(cs, (0, 1)) == 0
        assert len(cs) % 2 == 0


def test_vertex_0_of_a_closed_curve_on_another_curve():
    sq = closed_comp([[0, 0], [2, 0], [2, 2], [0, 2]])  # vertex 0 of the square at the origin
    cs = find_crossings(scene(sq, open_comp([[-1, -1], [1, 1]], 1)))  # passes through vertex 0 into the square
    assert [(c.params[0], c.point) for c in cs] == [(0.0, (0.0, 0.0))]
    assert cs[0].segments[0] == 0
    assert find_crossings(scene(sq, open_comp([[-1, 1], [1, -1]], 1))) == []  # touches the corner only


def test_degenerate_error_when_the_rule_cannot_decide(monkeypatch):
    # with u along x, a collapsed segment lying on a horizontal segment of the same curve stays on it
    monkeypatch.setattr(crossings_module, "_U", (1.0, 0.0))
    curve = open_comp([[0, 0], [4, 0], [4, 1], [2, 1], [2, 0], [2, 0], [2, -1]], name="loop")
    with pytest.raises(DegenerateError, match="loop") as err:
        find_crossings(scene(curve))
    assert "move" in str(err.value)
    assert isinstance(err.value, direct.DirectError)


def test_same_scene_without_the_bad_direction_is_decided():
    curve = open_comp([[0, 0], [4, 0], [4, 1], [2, 1], [2, 0], [2, 0], [2, -1]], name="loop")
    (c,) = find_crossings(scene(curve))
    assert c.point == (2.0, 0.0) and c.components == (0, 0) and not c.exact


# -- invariances --------------------------------------------------------------------------------
@FAST
@given(SEEDS, st.data())
def test_insert_vertex_generic(seed, data):
    sc = random_generic_scene(seed)
    base = find_crossings(sc)
    k = data.draw(st.integers(0, len(sc.components) - 1))
    comp = sc.components[k]
    seg = data.draw(st.integers(0, comp.n_segments - 1))
    t = data.draw(st.floats(0.01, 0.99))
    assert_same(find_crossings(replace(sc, k, insert_vertex(comp, seg, t))), base)


@FAST
@given(SEEDS, st.data())
def test_insert_vertex_at_a_crossing(seed, data):
    sc = random_generic_scene(seed)
    base = find_crossings(sc)
    assume(base)
    c = base[data.draw(st.integers(0, len(base) - 1))]
    side = data.draw(st.integers(0, 1))
    k, seg = c.components[side], c.segments[side]
    comp = sc.components[k]
    t = (c.params[side] - comp.params[seg]) / comp.segment_lengths[seg]
    assert_same(find_crossings(replace(sc, k, insert_vertex(comp, seg, t))), base, tol=1e-9)


@settings(max_examples=150, deadline=None)
@given(SEEDS, st.data())
def test_insert_vertex_degenerate_exact(seed, data):
    """Integer scenes full of vertex contacts and overlaps; the inserted vertices are exact."""
    sc = random_grid_scene(seed)
    base = find_crossings(sc)
    k = data.draw(st.integers(0, len(sc.components) - 1))
    comp = sc.components[k]
    seg = data.draw(st.integers(0, comp.n_segments - 1))
    once = replace(sc, k, insert_vertex(comp, seg, 0.5))
    assert_same(find_crossings(once), base)
    # and a vertex at a quarter of another segment
    k2 = data.draw(st.integers(0, len(sc.components) - 1))
    seg2 = data.draw(st.integers(0, once.components[k2].n_segments - 1))
    twice = replace(once, k2, insert_vertex(once.components[k2], seg2, 0.25))
    assert_same(find_crossings(twice), base)


@FAST
@given(SEEDS, st.floats(0, 2 * np.pi), st.floats(-10, 10), st.floats(-10, 10))
def test_rigid_motion_generic(seed, angle, dx, dy):
    sc = random_generic_scene(seed)
    base = find_crossings(sc)
    c, s = math.cos(angle), math.sin(angle)
    moved = find_crossings(transform(sc, [[c, -s], [s, c]], (dx, dy)))
    assert [x.components for x in moved] == [x.components for x in base]
    assert [x.sign for x in moved] == [x.sign for x in base]
    np.testing.assert_allclose([x.params for x in moved], [x.params for x in base], atol=1e-9)
    # a reflection flips every sign
    mirrored = find_crossings(transform(sc, [[-1, 0], [0, 1]]))
    assert [x.sign for x in mirrored] == [-x.sign for x in base]


@settings(max_examples=100, deadline=None)
@given(SEEDS)
def test_rotations_of_degenerate_closed_scenes(seed):
    """Closed integer scenes: every contact is topological, so quarter turns change nothing."""
    sc = random_grid_scene(seed, closed=True)
    base = find_crossings(sc)
    for m, flip in (([[0, -1], [1, 0]], 1), ([[-1, 0], [0, -1]], 1), ([[0, 1], [1, 0]], -1)):
        cs = find_crossings(transform(sc, m))
        assert [(c.components, c.params, flip * c.sign) for c in cs] == [(c.components, c.params, c.sign) for c in base]


@FAST
@given(SEEDS, st.data())
def test_reversal(seed, data):
    sc = random_generic_scene(seed)
    base = find_crossings(sc)
    k = data.draw(st.integers(0, len(sc.components) - 1))
    L = sc.components[k].length
    rev = find_crossings(replace(sc, k, sc.components[k].reversed()))
    expected = []
    for c in base:
        (i, j), (x1, x2) = c.components, c.params
        if i == j == k:  # both velocities flip and the order of the parameters swaps
            expected.append(((i, j), (L - x2, L - x1), -c.sign))
        elif i == k:
            expected.append(((i, j), (L - x1, x2), -c.sign))
        elif j == k:
            expected.append(((i, j), (x1, L - x2), -c.sign))
        else:
            expected.append(((i, j), (x1, x2), c.sign))
    expected.sort()
    got = sorted((c.components, c.params, c.sign) for c in rev)
    assert [(e[0], e[2]) for e in expected] == [(g[0], g[2]) for g in got]
    np.testing.assert_allclose([e[1] for e in expected], [g[1] for g in got], atol=1e-9)


# -- cross-checks -----------------------------------------------------------------------------
@settings(max_examples=60, deadline=None)
@given(SEEDS)
def test_brute_force(seed):
    sc = random_generic_scene(seed)
    got = find_crossings(sc)
    want = brute_force(sc)
    assert [(c.components, c.sign) for c in got] == [(w[0], w[2]) for w in want]
    np.testing.assert_allclose([c.params for c in got], [w[1] for w in want], atol=1e-9)
    for c in got:
        i, j = c.components
        assert c.exact
        assert i < j or c.params[0] < c.params[1]
        np.testing.assert_allclose(sc.components[i].phi(c.params[0]), c.point, atol=1e-9)
        np.testing.assert_allclose(sc.components[j].phi(c.params[1]), c.point, atol=1e-9)
        assert c.segments == (sc.components[i].segment_index(c.params[0]), sc.components[j].segment_index(c.params[1]))
    assert got == sorted(got, key=lambda c: (c.components, c.params))


@FAST
@given(SEEDS)
def test_two_closed_curves_meet_with_zero_total(seed):
    rng = np.random.default_rng(seed)
    n1, n2 = 2 * int(rng.integers(2, 5)), int(rng.integers(3, 9))
    a = closed_comp(rng.normal(size=(n1, 2)), 0, "A")
    b = polygon_comp(rng.normal(size=(n2, 2)) * 0.8 + rng.normal(size=2) * 0.3, 1, "B")
    cs = find_crossings(scene(a, b))
    between = [c for c in cs if c.components == (0, 1)]
    assert len(between) % 2 == 0
    assert sum(c.sign for c in between) == 0


@settings(max_examples=100, deadline=None)
@given(SEEDS)
def test_closed_degenerate_totals_vanish(seed):
    """Between two closed curves the signed total is 0, also with vertex contacts and overlaps."""
    sc = random_grid_scene(seed, closed=True, grid=4)
    cs = find_crossings(sc)
    for i in range(len(sc.components)):
        for j in range(i + 1, len(sc.components)):
            assert signed_total(cs, (i, j)) == 0
    for c in cs:
        np.testing.assert_allclose(sc.components[c.components[0]].phi(c.params[0]), c.point, atol=1e-12)
        np.testing.assert_allclose(sc.components[c.components[1]].phi(c.params[1]), c.point, atol=1e-12)


@settings(max_examples=100, deadline=None)
@given(SEEDS)
def test_grid_scenes_are_well_formed(seed):
    sc = random_grid_scene(seed, grid=3)
    cs = find_crossings(sc)
    keys = [(c.components, c.params) for c in cs]
    assert keys == sorted(keys) and len(set(keys)) == len(keys)
    for c in cs:
        i, j = c.components
        assert i < j or c.params[0] < c.params[1]
        assert c.sign in (-1, 1)
        for k, x, g in zip(c.components, c.params, c.segments, strict=True):
            comp = sc.components[k]
            assert 0 <= x <= comp.length and (x < comp.length or not comp.closed)
            assert g == comp.segment_index(x)
            np.testing.assert_allclose(comp.phi(x), c.point, atol=1e-12)


def test_many_segments_is_fast():
    rng = np.random.default_rng(1)
    comps = []
    for k in range(2):
        n = 3000
        ref = np.column_stack([np.arange(n, dtype=float), np.full(n, 2.0 * k)])
        comps.append(Component(ref, np.cumsum(rng.normal(size=(n, 2)), axis=0), name=f"W{k}"))
    sc = Scene(tuple(comps))
    cs = find_crossings(sc)
    assert len(cs) > 1000
    assert all(c.exact for c in cs)
    # spot-check against the brute force restricted to a few segments: every crossing lies on both curves
    pts = np.array([c.point for c in cs])
    for side in (0, 1):
        phis = np.array([sc.components[c.components[side]].phi(c.params[side]) for c in cs])
        np.testing.assert_allclose(phis, pts, atol=1e-8)
