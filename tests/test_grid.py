"""Metric edge integrals and grid graphs."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import random_crossing_scene
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

import direct
from direct.geodesics import grid_distances
from direct.grid import Domain, _rough_cells, build_graph, stencil
from direct.metric import G, GFamily, get_metric, segment_lengths
from direct.penalty import domains


def _quad_length(metric, comps, P, Q):
    """Independent length: adaptive quadrature of rho * norm, with breakpoints at vertex crossings."""
    ci, cj = comps
    d = Q - P

    def f(t):
        x = P + t * d
        k1 = ci.segment_index(x[0])
        k2 = cj.segment_index(x[1])
        r = ci.phi(x[0]) - cj.phi(x[1])
        a, b = ci.velocities[k1][None], cj.velocities[k2][None]
        return float(metric.weight(np.array(r @ r)) * metric.norm(a, b, d[None])[0])

    pts = []
    for axis, comp in enumerate(comps):
        if d[axis] != 0:
            t = (comp.params - P[axis]) / d[axis]
            pts += [float(v) for v in t if 0 < v < 1]
    return quad(f, 0, 1, points=sorted(pts) or None, limit=200, epsabs=0, epsrel=1e-12)[0]


@pytest.mark.parametrize("metric", ["G", "g", "euclid"])
def test_segment_lengths_match_adaptive_quadrature(metric, rng):
    sc = random_crossing_scene(3, n_vert=7)
    comps = sc.components
    met = get_metric(metric)
    P = rng.uniform(0, 1, size=(20, 2)) * [comps[0].length, comps[1].length]
    Q = rng.uniform(0, 1, size=(20, 2)) * [comps[0].length, comps[1].length]
    got = segment_lengths(met, comps, P, Q)
    want = [_quad_length(met, comps, p, q) for p, q in zip(P, Q)]
    np.testing.assert_allclose(got, want, rtol=1e-9)


def test_segment_lengths_are_symmetric_and_additive(rng):
    sc = random_crossing_scene(4, n_vert=6)
    comps = sc.components
    met = get_metric("G")
    P = rng.uniform(0, 2, size=(30, 2))
    Q = rng.uniform(0, 2, size=(30, 2))
    M = 0.37 * P + 0.63 * Q
    np.testing.assert_allclose(segment_lengths(met, comps, P, Q), segment_lengths(met, comps, Q, P), rtol=1e-12)
    np.testing.assert_allclose(
        segment_lengths(met, comps, P, Q),
        segment_lengths(met, comps, P, M) + segment_lengths(met, comps, M, Q),
        rtol=1e-11,
    )
    # swapping the roles of the two components mirrors the domain
    np.testing.assert_allclose(
        segment_lengths(met, comps, P, Q), segment_lengths(met, comps[::-1], P[:, ::-1], Q[:, ::-1]), rtol=1e-12
    )


def test_G_family_with_callable_h_agrees_with_G():
    sc = direct.scenes.get("fig2")
    fam = GFamily(h=lambda s: s**2, label="s^2")
    P, Q = np.array([[0.1, 0.2], [1.0, 2.0]]), np.array([[2.9, 2.7], [2.0, 0.5]])
    np.testing.assert_allclose(
        segment_lengths(fam, sc.components, P, Q), segment_lengths(G(), sc.components, P, Q), rtol=1e-10
    )


@pytest.mark.parametrize("h, match", [(lambda s: -s, "h must be finite"), (lambda s: s * 0 + 1, r"h\(0\) = 0"),
                                      (lambda s: math.exp(s) - 1, "vectorized"), (3.0, "must be a function")])
def test_G_family_refuses_an_h_outside_section_3_4_1(h, match):
    """A negative h gave a bare KeyError deep in the grid, a math.exp a TypeError, h(0) = 1 a silent number."""
    with pytest.raises(direct.DirectError, match=match):
        GFamily(h=h)


@pytest.mark.parametrize("n,expected", [(4, 2), (8, 4), (16, 8), (32, 16)])
def test_stencil_sizes(n, expected):
    half = stencil(n)
    assert len(half) == expected
    assert len({tuple(v) for v in np.vstack([half, -half])}) == n


@pytest.mark.parametrize("coarsen", [1, 4])
@pytest.mark.parametrize("seed", range(3))
def test_scipy_and_networkx_distances_identical(seed, coarsen):
    sc = random_crossing_scene(seed, n_vert=6, min_crossings=2)
    met = get_metric("G")
    for dom in domains(sc, direct.find_crossings(sc)):
        g = build_graph(dom, met, resolution=32, coarsen=coarsen)
        Ta, route = grid_distances(g, "scipy")
        Tb, _ = grid_distances(g, "networkx")
        np.testing.assert_allclose(Ta, Tb, rtol=1e-12)
        # a route is a real curve: its exact length is its grid distance (the edges are exact)
        for a in range(1, Ta.shape[0]):
            for b in (0, *range(1, Ta.shape[0])):
                if a == b:
                    continue
                poly = route(a, b)
                exact = segment_lengths(met, dom.comps, poly[:-1], poly[1:]).sum()
                assert exact == pytest.approx(Ta[a, b], rel=1e-9)


def test_no_path_runs_through_the_boundary():
    """Two crossing points near the same side: their distance is not a shortcut along the boundary."""
    sc = direct.scenes.get("fig2")
    met = get_metric("G")
    (dom,) = domains(sc, direct.find_crossings(sc))
    g = build_graph(dom, met, resolution=40)
    T, route = grid_distances(g)
    poly = route(1, 2)
    inside = dom.boundary_distance(dom.to_local(poly[1:-1]))
    assert (inside > 0).all()


def test_triangle_domain_has_diagonal_as_boundary():
    comp = direct.Component([[0, 0], [1, 0]], [[0, 0], [1, 0]], name="S")
    dom = Domain((0, 0), (comp, comp), np.array([[0.2, 0.25]]), np.array([1]), np.array([0]))
    t = dom.exit_time(np.array([[0.2, 0.25]]), np.array([[1.0, 0.0]]))
    assert t[0] == pytest.approx(0.05)
    assert dom.boundary_distance(np.array([[0.2, 0.25]]))[0] == pytest.approx(0.05 / np.sqrt(2))


@pytest.mark.parametrize("coarsen", [1, 4])
@pytest.mark.parametrize("seed", range(3))
def test_bounded_searches_keep_every_entry_program_34_can_use(seed, coarsen):
    """Searches stopped at ``bound * (d_a + max d_b)`` lose only pairs dearer than two boundary curves."""
    sc = random_crossing_scene(seed, n_vert=6, min_crossings=3)
    met = get_metric("G")
    for dom in domains(sc, direct.find_crossings(sc)):
        g = build_graph(dom, met, resolution=40, coarsen=coarsen)
        full, _ = grid_distances(g)
        for bound in (1.0, 1.5):
            part, route = grid_distances(g, bound=bound)
            kept = np.isfinite(part)
            np.testing.assert_allclose(part[kept], full[kept], rtol=1e-12)
            d0 = full[1:, 0]
            for a, b in zip(*np.nonzero(~kept)):
                assert a != b and a > 0 and b > 0
                assert full[a, b] >= bound * (d0[a - 1] + d0[b - 1]) * (1 - 1e-12)
            # routes from the boundary search and the bounded ones are real curves of the stated length
            for a in range(1, part.shape[0]):
                poly = route(a, 0)
                assert segment_lengths(met, dom.comps, poly[:-1], poly[1:]).sum() == pytest.approx(part[a, 0], rel=1e-9)

@pytest.mark.parametrize("seed", range(2))
def test_searches_from_chosen_terminals_stop_at_their_limits(seed):
    """``searches={a: limit}`` (the route check's second grid): rows of other terminals stay unknown, the searched
    rows agree with the full search up to their limit, and their routes are real curves of those lengths."""
    sc = random_crossing_scene(seed, n_vert=6, min_crossings=3)
    met = get_metric("G")
    checked = False
    for dom in domains(sc, direct.find_crossings(sc)):
        if len(dom.points) < 3:
            continue
        g = build_graph(dom, met, resolution=40, coarsen=4)
        full, _ = grid_distances(g)
        a, b = 1, full.shape[0] - 1
        limit = float(np.median(full[a, full[a] > 0]))
        part, route = grid_distances(g, searches={a: limit, b: np.inf})
        assert np.isinf(np.delete(part, [a, b], axis=0)).all()
        np.testing.assert_allclose(part[b], full[b], rtol=1e-12)
        inside = full[a] <= limit
        np.testing.assert_allclose(part[a, inside], full[a, inside], rtol=1e-12)
        assert np.isinf(part[a, ~inside]).all() and inside.any() and (~inside).any()
        for t in np.flatnonzero(inside):
            if t != a:
                poly = route(a, t)
                assert segment_lengths(met, dom.comps, poly[:-1], poly[1:]).sum() == pytest.approx(part[a, t], rel=1e-9)
        checked = True
    assert checked



@pytest.mark.parametrize("metric", ["G", "euclid"])
def test_grid_is_uniform_in_deformed_arclength_for_G(metric):
    """A component stretched unevenly gets cells of equal deformed length: the stencil's bias stays isotropic.

    For euclid the axes of the degenerate norm are then the grid's diagonals on every cell.
    """
    a = direct.Component([[0, 0], [1, 0], [2, 0]], [[-1, -1], [-0.9, -0.9], [1, 1]], name="A")  # speeds 0.14, 2.6
    b = direct.Component([[0, 1], [2, 1]], [[-1, 1], [1, -1]], name="B")
    sc = direct.Scene((a, b))
    met = get_metric(metric)
    (dom,) = domains(sc, direct.find_crossings(sc))
    g = build_graph(dom, met, resolution=32)
    grid_nodes = np.setdiff1d(np.arange(g.n_grounds, g.n_nodes), g.crossing_nodes)
    s_nodes = np.unique(np.round(g.coords[grid_nodes, 0], 12))
    sigma = np.interp(s_nodes, a.params, np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(a.deformed, axis=0),
                                                                                       axis=1))]))
    steps = np.diff(np.concatenate([[0.0], sigma, [sigma[-1] + (sigma[1] - sigma[0])]]))
    np.testing.assert_allclose(steps[:-1], steps[0], rtol=1e-9)
    # the metric g is Euclidean in the reference arclength: its grid stays uniform there
    g2 = build_graph(dom, get_metric("g"), resolution=32)
    s2 = np.unique(np.round(g2.coords[np.setdiff1d(np.arange(g2.n_grounds, g2.n_nodes), g2.crossing_nodes), 0], 12))
    np.testing.assert_allclose(np.diff(s2), np.diff(s2)[0], rtol=1e-9)


@pytest.mark.parametrize("scene", ["nested", "fig10", "ring"])
@pytest.mark.parametrize("metric,power", [("G", None), ("g", 3), ("euclid", None), ("G", 3)])
def test_segment_lengths_on_circles_match_adaptive_quadrature(scene, metric, power, rng):
    """Closed components: parameters read modulo the length, segments across the seam and across many cells."""
    sc = direct.scenes.get(scene)
    comps = (sc.components[0], sc.components[-1])
    met = get_metric(metric, power)
    L = np.array([c.length for c in comps])
    P = rng.uniform(-0.3, 1.3, size=(12, 2)) * L
    Q = P + rng.normal(scale=0.15, size=(12, 2)) * L
    Q[:4] = P[:4] + rng.normal(scale=0.01, size=(4, 2)) * L  # short ones, mostly in one cell

    def quad_length(p, q):
        d = q - p

        def f(t):
            x = p + t * d
            k = [c.segment_index(np.mod(xi, c.length) if c.closed else xi) for c, xi in zip(comps, x)]
            r = comps[0].phi(x[0]) - comps[1].phi(x[1])
            a, b = comps[0].velocities[k[0]][None], comps[1].velocities[k[1]][None]
            return float(met.weight(np.array(r @ r)) * met.norm(a, b, d[None])[0])

        pts = set()
        for axis, c in enumerate(comps):
            if d[axis] != 0:
                lo, hi = min(p[axis], q[axis]) / c.length, max(p[axis], q[axis]) / c.length
                shifts = np.arange(np.floor(lo) - 1, np.ceil(hi) + 2)
                vp = (c.params[None, :] + c.length * shifts[:, None]).ravel() if c.closed else c.params
                pts.update(float(v) for v in (vp - p[axis]) / d[axis] if 0 < v < 1)
        return quad(f, 0, 1, points=sorted(pts) or None, limit=500, epsabs=0, epsrel=1e-12)[0]

    got = segment_lengths(met, comps, P, Q)
    want = [quad_length(p, q) for p, q in zip(P, Q)]
    np.testing.assert_allclose(got, want, rtol=1e-9)


@pytest.mark.parametrize("scene", ["random", "nested", "fig10"])
@pytest.mark.parametrize("metric,power", [("G", None), ("g", 3), ("euclid", None)])
def test_segment_length_gradients_match_finite_differences(scene, metric, power, rng):
    """The gradient (Leibniz rule with the jumps at vertex lines) is the derivative of the lengths.

    (Polynomial weights only: otherwise the quadrature is not exact and neither is the rule.)
    """
    sc = random_crossing_scene(1, n_vert=7) if scene == "random" else direct.scenes.get(scene)
    comps = (sc.components[0], sc.components[-1])
    met = get_metric(metric, power)
    L = np.array([c.length for c in comps])
    P = rng.uniform(0.05, 0.95, size=(40, 2)) * L
    Q = P + rng.normal(scale=0.1, size=(40, 2)) * L
    Q[:10] = P[:10] + rng.normal(scale=0.005, size=(10, 2)) * L
    if not comps[0].closed:
        Q = np.clip(Q, 0, L)
    X = np.hstack([P, Q])
    # stay away from the kinks: an end on a vertex line has one-sided derivatives
    far = np.ones(len(X), dtype=bool)
    for col in range(4):
        c = comps[col % 2]
        x = np.mod(X[:, col], c.length) if c.closed else X[:, col]
        far &= np.abs(x[:, None] - c.params[None, :]).min(axis=1) > 1e-4 * c.length
    X = X[far]
    f, g = segment_lengths(met, comps, X[:, :2], X[:, 2:], gradient=True)
    np.testing.assert_allclose(f, segment_lengths(met, comps, X[:, :2], X[:, 2:]), rtol=1e-12)
    h = 1e-6 * L.max()
    for col in range(4):
        Xp, Xm = X.copy(), X.copy()
        Xp[:, col] += h
        Xm[:, col] -= h
        fp, fm = segment_lengths(met, comps, Xp[:, :2], Xp[:, 2:]), segment_lengths(met, comps, Xm[:, :2], Xm[:, 2:])
        fd = (fp - fm) / (2 * h)
        np.testing.assert_allclose(g[:, col], fd, rtol=1e-5, atol=1e-6 * np.abs(g).max())


def test_segment_lengths_in_blocks_are_the_same():
    """Long inputs are processed in blocks: a segment's length does not depend on the others."""
    from direct.metric import _CHUNK

    sc = direct.scenes.get("nested")
    comps = sc.components
    rng = np.random.default_rng(5)
    L = np.array([c.length for c in comps])
    m = 2 * _CHUNK + 17
    P = rng.uniform(-0.2, 1.2, size=(m, 2)) * L
    Q = P + rng.normal(scale=0.02, size=(m, 2)) * L
    met = get_metric("G")
    whole = segment_lengths(met, comps, P, Q)
    parts = np.concatenate([segment_lengths(met, comps, P[i:i + 999], Q[i:i + 999]) for i in range(0, m, 999)])
    np.testing.assert_allclose(whole, parts, rtol=1e-14)
    f, g = segment_lengths(met, comps, P, Q, gradient=True)
    np.testing.assert_allclose(f, whole, rtol=1e-12)
    assert g.shape == (m, 4) and np.isfinite(g).all()


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 30), st.sampled_from([0.05, 0.5, 4.0]))
def test_breaks_are_every_vertex_parameter_strictly_inside_each_segment(seed, m, spread):
    """``metric._breaks``: for each segment ``u0 -> u1``, every vertex parameter strictly between them, in
    order, at ``t = (v - u0) / (u1 - u0)``, as a loop over the segments computes them (both the path for one
    break per segment at most and the expansion of several)."""
    from direct.metric import _breaks

    rng = np.random.default_rng(seed)
    vp = np.sort(rng.uniform(0, 10, rng.integers(0, 8)))
    u0 = rng.uniform(0, 10, m)
    u1 = u0 + rng.normal(0, spread, m)
    edge, t = _breaks(vp, u0, u1)
    want_edge, want_t = [], []
    for k in range(m):
        lo, hi = min(u0[k], u1[k]), max(u0[k], u1[k])
        for v in vp[(vp > lo) & (vp < hi)]:
            want_edge.append(k)
            want_t.append((v - u0[k]) / (u1[k] - u0[k]))
    assert edge.tolist() == want_edge
    assert np.array_equal(t, np.array(want_t, dtype=float))


@settings(max_examples=300, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 40), st.sampled_from([0.05, 0.5, 3.0]))
def test_pieces_of_segments_crossing_one_line_are_those_of_the_general_construction(seed, m, spread):
    """``metric._Pieces``: the shortcut for segments that each cross one vertex line (``_one_break``) builds,
    bit for bit, the arrays and sums of the general construction (a sort of all break points), and leaves
    any other case to it: ends on lines, segments along a line, corners, several lines."""
    from direct.metric import _Pieces

    rng = np.random.default_rng(seed)
    vps = [np.sort(rng.uniform(0, 10, rng.integers(0, 6))) for _ in range(2)]
    P = rng.uniform(0, 10, (m, 2))
    Q = P + rng.normal(0, spread, (m, 2))
    for axis in (0, 1):  # ends on a line, and segments along one
        if vps[axis].size and rng.random() < 0.5:
            k = rng.integers(0, m, 2)
            P[k[0], axis] = rng.choice(vps[axis])
            P[k[1], axis] = Q[k[1], axis] = rng.choice(vps[axis])
    lo, hi = np.minimum(P, Q), np.maximum(P, Q)
    found, split = [], np.zeros(m, dtype=bool)
    for axis, vp in enumerate(vps):
        if vp.size:
            i0 = np.searchsorted(vp, lo[:, axis], side="right")
            count = np.searchsorted(vp, hi[:, axis], side="left") - i0
            found.append((axis, vp, i0, count))
            split |= count > 0
    assume(split.any())
    fast = _Pieces(split, found, P, Q)
    general = _Pieces.__new__(_Pieces)
    general._one_break = lambda *args: False  # the general construction only
    _Pieces.__init__(general, split, found, P, Q)
    for name in ("pe", "ta", "tb", "next", "starts"):
        a, b = getattr(fast, name), getattr(general, name)
        assert (a is None) == (b is None)
        if a is not None:
            assert a.dtype == b.dtype and np.array_equal(a, b), name
    values = rng.normal(size=(len(fast.pe), 4))
    assert np.array_equal(fast.total(values), general.total(values))


@pytest.mark.parametrize("scene", ["random", "nested", "fig11"])
def test_locally_refined_grid_is_fine_around_crossings_and_coarse_elsewhere(scene):
    """``coarsen=4``: the fine lattice near each crossing point and where rho is rough, every 4th node elsewhere.

    Far fewer nodes than the uniform grid, and the distances, being lengths of real curves of the same plane,
    close to the uniform grid's.
    """
    sc = random_crossing_scene(5, n_vert=6, min_crossings=3) if scene == "random" else direct.scenes.get(scene)
    met = get_metric("G")
    reach = 2 * 4  # patch=2 coarse cells of 4
    for dom in domains(sc, direct.find_crossings(sc)):
        fine = build_graph(dom, met, resolution=128)
        local = build_graph(dom, met, resolution=128, coarsen=4)
        assert local.coarsen == 4 and all(n % 4 == 0 for n in local.shape)
        grid = lambda g: np.setdiff1d(np.arange(g.n_grounds, g.n_nodes), g.crossing_nodes)  # noqa: E731
        # each node sits on the fine lattice: at (ticks[0][i], ticks[1][j])
        X = local.coords[grid(local)]
        idx = np.column_stack([np.searchsorted(local.ticks[k], X[:, k] - 1e-12) for k in (0, 1)])
        for k in (0, 1):
            np.testing.assert_allclose(local.ticks[k][idx[:, k]], X[:, k], atol=1e-12)
        if len(dom.points) == 0:
            continue
        assert len(grid(local)) < 0.6 * len(grid(fine))
        # a node off the coarse lattice lies within the patch of a crossing point or on a cell where rho is rough
        def at(a, b, g=local):
            return np.column_stack([g.ticks[0][np.mod(a, g.shape[0])], g.ticks[1][np.mod(b, g.shape[1])]])

        rough = _rough_cells(dom, met, at, 4, *local.shape, *dom.periodic, 4.0)
        pts = dom.to_local(dom.points)
        cell = np.column_stack([np.searchsorted(local.ticks[k], pts[:, k], side="right") - 1 for k in (0, 1)])
        n = np.array(local.shape)
        gap = np.abs(idx[:, None, :] - cell[None, :, :])
        for k in (0, 1):
            if dom.periodic[k]:
                gap[..., k] = np.minimum(gap[..., k], n[k] - gap[..., k])
        near = (gap <= reach + 1).all(axis=2).any(axis=1)
        on_coarse = (idx % 4 == 0).all(axis=1)
        assert (near | on_coarse | rough[idx[:, 0], idx[:, 1]]).all() and (~on_coarse).any()
        # grid distances from each point to the boundary: real curves, a few % apart
        if dom.kind == "torus":
            continue
        Tf, _ = grid_distances(fine)
        Tl, _ = grid_distances(local)
        ng = dom.n_grounds
        d_f, d_l = Tf[ng:, :ng].min(axis=1), Tl[ng:, :ng].min(axis=1)
        np.testing.assert_allclose(d_l, d_f, rtol=0.05)


@pytest.mark.parametrize("seed,kind", [(33, "triangle"), (1, "rect")])
def test_the_valleys_of_rho_are_refined(seed, kind):
    """Geodesics follow the valleys of rho (along the diagonal of a triangle, where it vanishes, and elsewhere),
    some narrower than a coarse cell.  Patches around the crossing points alone
    made a point's curve to the boundary 48 % (triangle) and 30 % (rectangle) longer than on the uniform grid;
    refining where rho is rough keeps every entry program (34) can use within 1 %."""
    sc = random_crossing_scene(seed, n_vert=6, min_crossings=2)
    met = get_metric("G")
    dom = [d for d in domains(sc, direct.find_crossings(sc)) if d.kind == kind and len(d.points)][0]
    fine, _ = grid_distances(build_graph(dom, met, resolution=128))
    local, _ = grid_distances(build_graph(dom, met, resolution=128, coarsen=4))
    patches_only, _ = grid_distances(build_graph(dom, met, resolution=128, coarsen=4, ratio=np.inf))
    useful = np.isfinite(fine) & (fine > 0) & (fine < fine[:, :1] + fine[:1, :])  # cheaper than two boundary curves
    useful[0, 0] = False
    assert (patches_only[useful] / fine[useful]).max() > 1.25
    assert (local[useful] / fine[useful]).max() <= 1.01


def test_a_crossing_point_keeps_its_window_whatever_the_patch():
    """With ``patch=0`` (and no rough cells) the patch still holds the crossing point's window of grid nodes."""
    sc = direct.scenes.get("cross60")
    met = get_metric("G")
    (dom,) = domains(sc, direct.find_crossings(sc))
    uniform = build_graph(dom, met, resolution=64)
    bare = build_graph(dom, met, resolution=64, coarsen=4, patch=0, ratio=np.inf)

    def grid_edges(g, node):
        ends = np.concatenate([g.cols[g.rows == node], g.rows[g.cols == node]])
        return int((ends >= g.n_grounds).sum())

    for a, b in zip(uniform.crossing_nodes, bare.crossing_nodes):
        assert grid_edges(bare, b) == grid_edges(uniform, a) > 0


def test_valley_rays_bend_on_vertex_lines_and_weigh_their_exact_length():
    """The valleys of ``rho`` out of a crossing point, followed in deformed arclength (``_valley_rays``): a
    polyline from the point to the boundary, straight in each cell, whose diagonals in ``sigma`` hold
    ``d sigma1 = +-d sigma2``; its weight is its exact length, and a chosen bent exit gives its bends to the
    route."""
    from direct.grid import _valley_rays

    # one crossing 0.024 from a side of A, whose first piece is 40 times slower than the rest
    a, b, c, d, alpha = 0.024, 0.74, 0.032, 1.84, 3.04
    e = np.array([np.cos(alpha), np.sin(alpha)])
    A = direct.Component([[0, 0], [0.38, 0], [0.76, 0]], [[-a, 0], [-a + 0.023 * (a + b), 0], [b, 0]], name="A")
    B = direct.Component([[0, 5], [(c + d) / 2, 5], [c + d, 5]], [-c * e, (-c + 0.27 * (c + d)) * e, d * e], name="B")
    scene = direct.Scene((A, B))
    dom = domains(scene, direct.find_crossings(scene))[0]
    metric = G()
    owner, exits, bends, weights = _valley_rays(dom, metric, dom.points)
    assert len(owner) >= 1 and all(len(bk) >= 1 for bk in bends)
    sigma = []
    for comp in dom.comps:
        speed = np.linalg.norm(comp.velocities, axis=1)
        sigma.append(np.concatenate([[0.0], np.cumsum(speed * np.diff(comp.params))]))
    S, V = dom.local_lengths
    for k in range(len(owner)):
        poly = np.vstack([dom.points[owner[k]], bends[k], exits[k]])
        # on the boundary at the end, inside before it
        assert min(poly[-1, 0], S - poly[-1, 0], poly[-1, 1], V - poly[-1, 1]) <= 1e-12
        # a diagonal of the deformed arclengths
        s = np.column_stack([np.interp(poly[:, j], dom.comps[j].params, sigma[j]) for j in (0, 1)])
        steps = np.diff(s, axis=0)
        assert np.allclose(np.abs(steps[:, 0]), np.abs(steps[:, 1]), rtol=1e-9, atol=1e-15)
        # every bend on a vertex line of either component
        for bend in bends[k]:
            assert min(np.abs(dom.comps[0].params - bend[0]).min(), np.abs(dom.comps[1].params - bend[1]).min()) < 1e-12
        assert weights[k] == pytest.approx(segment_lengths(metric, dom.comps, poly[:-1], poly[1:]).sum(), rel=1e-12)
    graph = build_graph(dom, metric, resolution=128, coarsen=4)
    assert graph.exit_bends  # the cheapest way out of the point is a bent valley
    (g, node), pts = next(iter(graph.exit_bends.items()))
    path = graph.node_path([node, g])
    assert np.allclose(path[1:-1], pts) and np.allclose(path[-1], graph.exit_points[g, node])
    assert np.allclose(graph.node_path([g, node]), path[::-1])


@pytest.mark.parametrize("neighbours", [8, 16, 32])
def test_annulus_grid_moves_are_the_stencil_of_the_parameters(neighbours):
    """The grid of a circle with itself is uniform in ``(s, v)``, ``(x1, x2) = s (1, 1) + v (0, 1)``: its edges
    between grid nodes must be the stencil's moves in the parameters ``(x1, x2)``, not in ``(s, v)``. In ``(s, v)``
    the 16 moves left gaps of 45 degrees in the parameters (a bias of up to 8.2 %): a figure eight's grid picked a
    local geodesic 6.7 % longer than the shortest (``test_figure_eight_crossing_on_vertices_in_every_listing``)."""
    sc = direct.scenes.get("fig10")
    (dom,) = [d for d in domains(sc, direct.find_crossings(sc)) if d.kind == "annulus"]
    g = build_graph(dom, get_metric("G"), resolution=24, neighbours=neighbours)
    grid = (g.rows >= dom.n_grounds) & (g.cols >= dom.n_grounds)
    grid &= (g.rows < len(g.coords) - len(dom.points)) & (g.cols < len(g.coords) - len(dom.points))
    local = g.coords[g.cols[grid]] - g.coords[g.rows[grid]] + g.winds[grid] * np.array(dom.local_lengths)
    moves = np.rint((local @ dom.basis.T) / g.h).astype(int)  # in the parameters, in cells
    np.testing.assert_allclose(moves * g.h, local @ dom.basis.T, atol=1e-9)
    half = stencil(neighbours)
    assert {tuple(m) for m in moves} | {tuple(-m) for m in moves} == {tuple(m) for m in np.vstack([half, -half])}
