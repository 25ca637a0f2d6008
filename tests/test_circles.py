"""Circles in M: the annulus (Prop. 11, eq. (10)), cylinders and tori (section 3.3.4)."""

from __future__ import annotations

import itertools
import sys
import warnings

import numpy as np
import pytest
from conftest import RTOL, polygon_pair, rigid

import direct
from direct.geodesics import grid_distances
from direct.grid import build_graph
from direct.matching import solve_flow
from direct.metric import get_metric
from direct.penalty import boundary_conditions, domains
from direct.topology import turning_number, winding_number


def eight(n: int = 96) -> direct.Scene:
    """The figure eight (cos t, sin 2t) of Fig. 10, coarser than the built-in scene to keep tests fast."""
    return direct.scenes.circle_scene(lambda t: np.column_stack([np.cos(t), np.sin(2 * t)]), n=n, name="eight")


def reversed_circle(R: float, n: int = 400) -> direct.Scene:
    return direct.scenes.circle_scene(lambda t: R * np.column_stack([np.cos(-t), np.sin(-t)]), n=n, radius=R)


@pytest.mark.parametrize("R", [0.7, 1.3])
def test_reversed_circle_closed_form_G(R):
    """Two geodesics across the annulus, each 2 sqrt(2) pi R^3 (the polygon is within (pi/n)^2 of the circle)."""
    res = direct.penalty(reversed_circle(R), "G")
    assert res.crossings == []
    assert res.value == pytest.approx(4 * np.sqrt(2) * np.pi * R**3, rel=1e-3)
    assert len(res.pairs) == 2 and all(p.start is None and p.end is None for p in res.pairs)


def test_reversed_circle_closed_form_g():
    # |r|^4 = 16 R^4 sin^4(u / 2R) along u = x2 - x1, crossed at 45 degrees: 6 sqrt(2) pi R^5 per curve
    R = 0.8
    res = direct.penalty(reversed_circle(R), "g")
    assert res.value == pytest.approx(12 * np.sqrt(2) * np.pi * R**5, rel=1e-3)


def star(rng, n=160, k=4, amp=0.25):
    t = 2 * np.pi * np.arange(n) / n
    coef = rng.uniform(-1, 1, size=(k, 2)) * amp / np.arange(1, k + 1)[:, None]
    r = 1 + sum(c[0] * np.cos((i + 1) * t) + c[1] * np.sin((i + 1) * t) for i, c in enumerate(coef))
    return np.column_stack([r * np.cos(t), r * np.sin(t)])


@pytest.mark.parametrize("seed", range(4))
def test_admissible_closed_curves_have_zero_penalty(seed):
    rng = np.random.default_rng(seed)
    t = 2 * np.pi * np.arange(160) / 160
    circ = np.column_stack([np.cos(t), np.sin(t)])
    comps = [direct.Component(circ, star(rng) + rng.normal(size=2), closed=True, name="S")]
    # an interval far away, moved rigidly
    comps.append(direct.Component([[5, 0], [6, 0]], [[8, 1], [8, 2]], name="I"))
    scene = direct.Scene(tuple(comps))
    for metric in ("G", "g"):
        res = direct.penalty(scene, metric)
        assert res.value == 0.0 and res.pairs == []


@pytest.mark.parametrize("k,phase", [(2, 0.0), (2, 0.7), (3, 0.3)])
def test_every_self_crossing_of_a_circle_is_penalized(k, phase):
    """Lissajous-like closed curves (cos t, sin(k t + phase)) cross themselves transversally."""
    sc = direct.scenes.circle_scene(lambda t: np.column_stack([np.cos(t), np.sin(k * t + phase)]), n=121)
    cr = direct.find_crossings(sc)
    assert len(cr) >= 1
    for metric in ("G", "g"):
        assert direct.penalty(sc, metric).value > 0


def test_figure_eight_turning_number_condition():
    sc = eight()
    comp = sc.components[0]
    assert turning_number(comp.deformed) == 0 and turning_number(comp.reference) == 1
    (dom,) = domains(sc, direct.find_crossings(sc))
    assert dom.kind == "annulus"
    assert boundary_conditions(dom) == {"flux": 1}  # #j - #phi
    res = direct.penalty(sc)
    assert len(res.crossings) == 1 and res.value > 0
    assert sum(p.length for p in res.pairs) == pytest.approx(res.value, rel=1e-12)


def test_reversing_a_circle_keeps_J_and_reversing_only_phi_changes_it():
    sc = eight()
    comp = sc.components[0]
    base = direct.penalty(sc).value
    both = direct.penalty(direct.Scene((comp.reversed(),))).value
    assert both == pytest.approx(base, rel=RTOL)
    # reversing only the deformation: turning number 0 stays 0 for the figure eight, but a circle flips
    circle = direct.scenes.circle_scene(lambda t: np.column_stack([np.cos(t), np.sin(t)]) * 1.2)
    assert direct.penalty(circle).value == 0.0
    c = circle.components[0]
    flipped = direct.Component(c.reference, np.vstack([c.deformed[:1], c.deformed[:0:-1]]), closed=True)
    assert direct.penalty(direct.Scene((flipped,))).value > 0


def test_cyclic_relabelling_of_a_circle_changes_nothing():
    """Same curve, another first vertex.

    Known limitation (issue 3): on the annulus the geodesics to the diagonal
    have several local minima within the grid's bias, and the refinement may
    settle in different ones (about 1 % apart on this scene); the tolerance
    here is the issue's acceptance level, not the refinement's ``tol``.
    """
    sc = eight()
    c = sc.components[0]
    k = 37
    rolled = direct.Component(np.roll(c.reference, -k, axis=0), np.roll(c.deformed, -k, axis=0), closed=True)
    assert direct.penalty(direct.Scene((rolled,))).value == pytest.approx(direct.penalty(sc).value, rel=2e-2)


def test_rigid_motion_of_a_circle_scene():
    sc = eight()
    moved = rigid(sc, 1.1, (0.3, -4.0))
    assert direct.penalty(moved).value == pytest.approx(direct.penalty(sc).value, rel=RTOL)


@pytest.mark.parametrize("scale", [1e-3, 1e-6])
def test_small_circle_scenes_keep_their_curves(scale):
    """``J^G`` scales as the cube of the deformation: on a scene 1e-3 across, HiGHS's absolute tolerances
    took any feasible choice (the bow twice its value, two polygons 8 times theirs) until the costs were scaled."""
    t = np.linspace(0, 2 * np.pi, 4, endpoint=False)
    bow = direct.Scene((direct.Component(np.column_stack([np.cos(t), np.sin(t)]),
                                         [[0, 0], [1, 1], [1, 0], [0, 1]], closed=True, name="bow"),))
    for sc in (bow, polygon_pair(16, 1.0)):
        base = direct.penalty(sc)
        small = direct.penalty(rigid(sc, 0.0, (0.0, 0.0), scale=scale))
        assert small.value / scale**3 == pytest.approx(base.value, abs=base.error_estimate + small.error_estimate
                                                       / scale**3 + 1e-12 * base.value)
        assert len(small.pairs) == len(base.pairs)


@pytest.mark.slow
def test_nested_circles_need_a_closed_curve():
    """Section 3.3.4: no crossing, but the small circle jumped inside the big one."""
    sc = direct.scenes.get("nested")
    (dom,) = [d for d in domains(sc, []) if d.kind == "torus"]
    K = boundary_conditions(dom)["winds"]
    assert sorted(map(abs, K)) == [0, 1]
    for metric in ("G", "g"):
        res = direct.penalty(sc, metric)
        assert res.crossings == [] and res.value > 0
        assert all(p.closed for p in res.pairs)


def test_reversed_polygon_agrees_across_grids_within_its_estimates():
    """A grid aligned with the 128-gon's vertices laid the route on a symmetry line, a critical point.

    At 128 cells the single start settled 2.7e-7 above the value from 150 cells with an estimate of 3e-14;
    the shifted starts leave the symmetry line.
    """
    sc = reversed_circle(1.0, n=128)
    a, b = (direct.penalty(sc, tol=1e-5, resolution=r, second_pass=False) for r in (128, 150))
    assert abs(a.value - b.value) <= a.error_estimate + b.error_estimate
    assert a.error_estimate < 1e-5 * a.value and b.error_estimate < 1e-5 * b.value


def test_nested_circles_agree_across_grids_within_their_estimates():
    """Two regular 128-gons: shifted copies of the closed geodesic compete, nearly tied (1.4e-5 relative).

    From one start the refinement settled 1.1e-4 above the value from another grid with an estimate of
    2.8e-5; each closed curve is now refined from several starts and the spread enters the estimate.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", direct.ToleranceWarning)
        a, b = (direct.penalty("nested", resolution=r) for r in (96, 128))
    assert abs(a.value - b.value) <= a.error_estimate + b.error_estimate
    assert a.error_estimate < 1e-4 * a.value and b.error_estimate < 1e-4 * b.value


def test_ring_with_collapsed_segment_G_vanishes_g_does_not():
    """End of section 3.4.3 and Prop. 17: J^G = 0 on this non-admissible deformation, J^g > 0."""
    sc = direct.scenes.get("ring")
    assert direct.penalty(sc, "G").value == 0.0
    g = direct.penalty(sc, "g")
    # one curve across the cylinder, |r| = 1 on the ring's vertices, length 1 along the segment, twice
    ring = sc.components[0]
    rmin = np.cos(np.pi / ring.n_vertices)  # the polygon's closest approach to its centre
    # within its estimate of those bounds: with OpenBLAS's Sandybridge kernels (OPENBLAS_CORETYPE) the value,
    # extrapolated, came out 1.15e-5 below the lower one, with an estimate of 4.6e-5
    assert rmin**4 * 2 - g.error_estimate <= g.value <= 2 + g.error_estimate


def test_circle_crossing_an_interval():
    t = 2 * np.pi * np.arange(120) / 120
    circ = np.column_stack([np.cos(t), np.sin(t)])
    ring = direct.Component(circ, circ, closed=True, name="ring")
    stick = direct.Component([[3, -1], [3, 1]], [[0.2, -2], [0.5, 2]], name="stick")
    sc = direct.Scene((ring, stick))
    res = direct.penalty(sc)
    assert len(res.crossings) == 2 and {c.sign for c in res.crossings} == {-1, 1}
    assert res.value > 0
    assert direct.penalty(direct.Scene((ring, stick.reversed()))).value == pytest.approx(res.value, rel=RTOL)
    assert direct.penalty(rigid(sc, 0.4, (1, 2))).value == pytest.approx(res.value, rel=RTOL)


@pytest.mark.slow
def test_two_overlapping_circles():
    t = 2 * np.pi * np.arange(120) / 120
    circ = np.column_stack([np.cos(t), np.sin(t)])
    a = direct.Component(circ, circ, closed=True, name="a")
    b = direct.Component(circ + [3, 0], circ + [1.2, 0], closed=True, name="b")
    sc = direct.Scene((a, b))
    res = direct.penalty(sc)
    assert len(res.crossings) == 2
    assert res.value > 0
    swapped = direct.Scene((b, a))
    assert direct.penalty(swapped).value == pytest.approx(res.value, rel=RTOL)


def _brute_flow(C, supply):
    """Enumerate families of curves on an annulus: each point's curve goes to a point or a side."""
    n = len(supply)
    neg = [u for u in range(2, n) if supply[u] > 0]
    pos = [u for u in range(2, n) if supply[u] < 0]
    best = np.inf
    ends = pos + [0, 1]
    for targets in itertools.product(ends, repeat=len(neg)):
        used = [v for v in targets if v >= 2]
        if len(set(used)) != len(used):
            continue
        rest = [v for v in pos if v not in used]
        for sources in itertools.product([0, 1], repeat=len(rest)):
            cost = sum(C[u, v] for u, v in zip(neg, targets)) + sum(C[g, v] for g, v in zip(sources, rest))
            out0 = sum(1 for v in sources if v == 0) - sum(1 for v in targets if v == 0)
            extra = supply[0] - out0  # curves from side 0 to side 1 (or back) make up the rest
            cost += abs(extra) * (C[0, 1] if extra > 0 else C[1, 0])
            best = min(best, cost)
    return best


@pytest.mark.parametrize("name", ["eight", "fig13"])
def test_flow_against_enumeration(name):
    sc = eight() if name == "eight" else direct.scenes.get(name)
    met = get_metric("G")
    for dom in domains(sc, direct.find_crossings(sc)):
        if len(dom.points) > 8:
            pytest.skip("too many points to enumerate")
        g = build_graph(dom, met, resolution=32)
        T, _ = grid_distances(g)
        supply = np.zeros(T.shape[0], dtype=int)
        supply[2 + np.flatnonzero(dom.signs < 0)] = 1
        supply[2 + np.flatnonzero(dom.signs > 0)] = -1
        supply[0] = boundary_conditions(dom)["flux"]
        supply[1] = -supply[0] - supply[2:].sum()
        assert solve_flow(T, supply)[0] == pytest.approx(_brute_flow(T, supply), rel=1e-9)


@pytest.mark.parametrize("name,k", [("fig11", 2), ("fig13", 3)])
def test_multiple_covers_get_a_value(name, k):
    """Passes on the same vertices: no crossing after perturbation; #phi - #j = k - 1 curves across the annulus."""
    res = direct.penalty(name)
    assert res.crossings == []
    assert len(res.pairs) == k - 1
    assert all(p.start is None and p.end is None for p in res.pairs)
    assert np.isfinite(res.value) and res.value > 0


def test_triple_cover_is_three_reversed_polygons():
    """``G`` is invariant under reparametrization, so ``J(fig13) = 3 J(reversed 96-gon)`` exactly.

    In deformed arclength each of the two curves of ``fig13`` crosses three of the strips
    between zero lines that the reversed polygon's curve crosses once (``validation/failures.py``).
    Two local geodesics compete there, 4.8e-8 relative apart, and the second pass must see it;
    starting from evenly resampled routes, the refinement settled 1.5e-4 too high (with a warning).
    """
    t = lambda s: np.column_stack([np.cos(-s), np.sin(-s)])  # noqa: E731
    with warnings.catch_warnings():
        warnings.simplefilter("error", direct.ToleranceWarning)
        rev = direct.penalty(direct.scenes.circle_scene(t, n=96), tol=1e-5)
        res = direct.penalty("fig13", tol=1e-5)
    assert abs(res.value - 3 * rev.value) <= res.error_estimate + 3 * rev.error_estimate
    assert res.value == pytest.approx(3 * rev.value, rel=1e-6)


def test_exact_double_cover_is_invariant():
    """The value of a multiple cover (decided by the perturbation rule) survives a rigid motion and a relabelling."""
    sc = direct.scenes._cover(2, per_turn=32)
    base = direct.penalty(sc).value
    assert direct.penalty(rigid(sc, 0.9, (2.0, 1.0))).value == pytest.approx(base, rel=RTOL)
    c = sc.components[0]
    rolled = direct.Component(np.roll(c.reference, -5, axis=0), np.roll(c.deformed, -5, axis=0), closed=True)
    assert direct.penalty(direct.Scene((rolled,))).value == pytest.approx(base, rel=2e-2)


def test_winding_and_turning_numbers():
    t = 2 * np.pi * np.arange(50) / 50
    c = np.column_stack([np.cos(t), np.sin(t)])
    assert winding_number(c, [0.1, 0.2]) == 1 and winding_number(c[::-1], [0, 0]) == -1
    assert winding_number(c, [3, 0]) == 0
    twice = np.column_stack([np.cos(2 * t), np.sin(2 * t)])
    assert turning_number(twice) == 2 and winding_number(twice, [0, 0]) == 2
    with pytest.raises(direct.DegenerateError):
        winding_number(c, c[3])
    # an exact reversal (a hairpin) is decided by the perturbation, and the total stays an integer
    hairpin = np.array([[0, 0], [2, 0], [1, 0], [1, 1]], dtype=float)
    assert turning_number(hairpin) in (-1, 0, 1)


@pytest.mark.parametrize("metric,rel", [("G", 1e-3), pytest.param("g", 2e-3, marks=pytest.mark.slow)])
def test_torus_closed_curve_against_independent_minimization(metric, rel):
    """Nested circles: the closed curve of class (1, 0) as a Fourier graph x2 = f(x1), minimized by BFGS."""
    from scipy.optimize import minimize

    from direct.metric import segment_lengths

    sc = direct.scenes.get("nested")
    c1, c2 = sc.components
    met = get_metric(metric)
    K, N = 4, 400
    s = np.linspace(0, 1, N + 1)
    k = np.arange(1, K + 1)
    basis_c, basis_s = np.cos(2 * np.pi * np.outer(s, k)), np.sin(2 * np.pi * np.outer(s, k))

    def length(z):
        f = z[0] + basis_c @ z[1 : 1 + K] + basis_s @ z[1 + K :]
        X = np.column_stack([s * c1.length, f])
        return segment_lengths(met, (c1, c2), X[:-1], X[1:]).sum()

    starts = np.linspace(0, c2.length, 4, endpoint=False)
    best = min(minimize(length, np.r_[c0, np.zeros(2 * K)], method="BFGS").fun for c0 in starts)
    res = direct.penalty(sc, metric)
    assert res.value / 2 == pytest.approx(best, rel=rel)


@pytest.mark.slow
def test_foreseen_entries_batch_the_rounds_without_changing_the_choice(monkeypatch, refine_batches):
    """The star polygon of 9 vertices (a double cover, 9 crossings on the annulus): by symmetry every point's
    curve to the diagonal is a contender in turn. Refining the entries the next solves would ask for in one batch
    (``_foreseen``) must give the same value and pairs as refining only the chosen ones, in fewer batches."""
    import sys

    P = sys.modules["direct.penalty"]
    scene = direct.scenes.circle_scene(lambda t: np.column_stack([np.cos(2 * t), np.sin(2 * t)]), n=9, name="star")
    runs = {}
    for mode in ("batched", "one by one"):
        if mode == "one by one":
            monkeypatch.setattr(P, "_foreseen", lambda missing, *args, **kwargs: missing)
        first = len(refine_batches)
        runs[mode] = (direct.penalty(scene), refine_batches[first:])
    (fast, nb_fast), (slow, nb_slow) = runs["batched"], runs["one by one"]
    assert fast.value == pytest.approx(slow.value, rel=1e-12)
    assert sorted(str((p.start_crossing, p.end_crossing, p.start, p.end)) for p in fast.pairs) == sorted(
        str((p.start_crossing, p.end_crossing, p.start, p.end)) for p in slow.pairs)
    assert len(nb_fast) <= len(nb_slow) / 3


@pytest.mark.slow
def test_rough_refinement_hides_no_entry_from_the_checks_of_entries_not_chosen(monkeypatch):
    """Below ``tol=1e-4`` entries are refined roughly first (``_settle``); the checks of ``finish`` that look at
    entries not chosen (the shifted starts of curves between the grounds, the slid ends on the annulus, ...) must
    still see every entry they would see with every entry refined in full. A code review of the first version found
    the star polygon {7/2} at ``tol=1e-5`` giving shifted starts to no curve between the grounds (1 in full) and
    sliding 14 curves to the diagonal (27 in full)."""
    import sys

    P = sys.modules["direct.penalty"]
    t = 2 * np.pi * np.arange(7) / 7
    scene = direct.Scene((direct.Component(np.column_stack([np.cos(t), np.sin(t)]),
                                           np.column_stack([np.cos(2 * t), np.sin(2 * t)]), closed=True, name="star"),))
    more, slid = P._more_starts, P._slid_ends
    seen: dict = {}

    def more_spy(domain, metric, starts, cache, *args, **kwargs):
        seen["shifted"].update(k for k in starts if k[0] < domain.n_grounds and k[1] < domain.n_grounds)
        return more(domain, metric, starts, cache, *args, **kwargs)

    def slid_spy(domain, metric, keys, *args, **kwargs):
        seen["slid"].update(keys)
        return slid(domain, metric, keys, *args, **kwargs)

    monkeypatch.setattr(P, "_more_starts", more_spy)
    monkeypatch.setattr(P, "_slid_ends", slid_spy)
    runs = {}
    for rough in (True, False):
        if not rough:
            monkeypatch.setattr(P, "_ROUGH_TOL", 1e-30)  # never below tol / 10: every entry in full
        seen.update(shifted=set(), slid=set())
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", direct.ToleranceWarning)
            res = direct.penalty(scene, tol=1e-5)
        runs[rough] = res, {k: set(v) for k, v in seen.items()}
    (fast, fast_seen), (full, full_seen) = runs[True], runs[False]
    assert full_seen["shifted"] and full_seen["slid"]
    assert fast_seen == full_seen
    assert (fast.value, fast.error_estimate) == (full.value, full.error_estimate)


def test_hairpin_short_curves_are_refined_to_the_refined_values_tolerance():
    """The built-in ``hairpin`` (an octagon folded into a thin loop, two segments at 0.4 degrees): the metric has
    a valley much narrower than a grid cell and the grid's value was 33 times J at 128 cells. The absolute
    tolerance taken from it let the curves stop short of their relative tolerance (1.1e-3 off, estimate 1.6e-3, with
    a warning at the default tol). Refined again with the refined value's, a run must reach its tolerance,
    without a warning, within its estimate of a tight run. Since stop 30 (the annulus grid with the 16 moves of
    the parameters, the hairpin in its deformed arclength) the grid's value is 6 times J at 128 cells, close
    enough to need no second refinement; at 96 cells it is 61 times J, and the second refinement runs."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", direct.ToleranceWarning)  # 512 segments reached: an estimate of 2e-5
        ref = direct.penalty("hairpin", tol=1e-6)
    for resolution, again in ((128, 0), (96, 1)):
        with warnings.catch_warnings():
            warnings.simplefilter("error", direct.ToleranceWarning)
            res = direct.penalty("hairpin", resolution=resolution)
        assert res.grid_value > (10 if again else 1) * res.value
        assert res.settings.get("refined_again", 0) == again
        assert res.error_estimate <= 1e-3 * res.value
        assert abs(res.value - ref.value) <= res.error_estimate
        assert abs(res.value - ref.value) <= ref.error_estimate + 1e-3 * ref.value


def test_hairpin_with_g_at_the_default_tol_is_within_its_estimate():
    """The hairpin's narrow valley with the metric ``g`` (``validation/coarse_grids.py``, at every resolution):
    three levels whose changes decay by 0.74 where Richardson assumes 1/4; the estimate missed their tail and the
    value was 1.1e-3 above an upper bound of J (estimate 6.2e-4, no warning). ``polyline_length`` at ``tol=1e-4``
    is the exact length of real curves, so J is at most their sum and the default run's error at least its
    excess; the tail now enters the estimate and the run goes on to more levels."""
    res = direct.penalty("hairpin", "g")
    upper = sum(p.polyline_length for p in direct.penalty("hairpin", "g", tol=1e-4).pairs)
    assert res.value - upper <= res.error_estimate  # was 1.1e-3 * J against 6.2e-4 * J


def _torus_graph(scene, resolution=48):
    (dom,) = [d for d in domains(scene, direct.find_crossings(scene)) if d.kind == "torus"]
    return build_graph(dom, get_metric("G"), resolution, 16)


@pytest.mark.parametrize("scene", [direct.scenes.get("nested"), polygon_pair(24, 1.0), polygon_pair(17, 0.3, 0.2, 1),
                                   polygon_pair(30, 1.6, 0.3, 2)], ids=["nested", "apart", "deep", "wobbly"])
def test_closed_curve_bounds_are_below_every_closed_grid_curve(scene):
    """``closed_curve_bounds`` (one pass over the edges) never exceeds the shortest closed grid curve of its
    class, found by the searches of ``closed_curve_distances`` on the cover."""
    from direct.geodesics import closed_curve_bounds, closed_curve_distances

    graph = _torus_graph(scene)
    bounds = closed_curve_bounds(graph)
    found = closed_curve_distances(graph)
    assert set(bounds) == set(found)
    for c, curves in found.items():
        assert 0 < bounds[c] <= curves[0][0], c
    # not vacuous: around the circles of two polygons pushed together, within a factor 2 of the grid curve
    if len(scene.components[0].reference) == 24:
        assert bounds[(1, 0)] > 0.5 * found[(1, 0)][0][0]


@pytest.mark.parametrize("scene", [direct.scenes.get("nested"), polygon_pair(17, 0.3, 0.2, 1),
                                   polygon_pair(12, 0.6)], ids=["nested", "deep", "overlapping"])
def test_stopped_closed_curve_searches_are_the_full_searches(scene):
    """``closed_curve_distances`` stops each base point's search at ``1 + margin`` times the shortest closed curve
    found so far: its lengths and routes are those of full searches from every base point (one scipy call, no
    limit), picked by the same rule (the shortest first, then the shortest whose routes lie more than two grid
    steps from those picked, within ``1 + margin`` of the shortest; distances here by brute force over the nine
    nearest periodic copies), class by class; and asking for some classes gives those and their opposites only,
    the same curves."""
    from scipy.sparse.csgraph import dijkstra
    from scipy.spatial.distance import cdist

    from direct.geodesics import _COVER, _cover_matrix, _cover_polyline, closed_curve_distances

    graph = _torus_graph(scene)
    N, M = graph.n_nodes, _cover_matrix(graph)
    S, V = graph.domain.local_lengths
    margin = 0.04
    found = closed_curve_distances(graph, most=3, margin=margin)
    assert len(found) == 8

    def apart(p, q):  # Hausdorff distance on the torus, in grid steps, more than 2
        p, q = p / graph.h, q / graph.h
        copies = [cdist(p, q + np.array([i * S, j * V]) / graph.h) for i in (-1, 0, 1) for j in (-1, 0, 1)]
        r = np.min(copies, axis=0)
        return max(r.min(axis=1).max(), r.min(axis=0).max()) > 2.0

    for axis, classes in ((0, ((1, 0), (1, 1), (1, -1))), (1, ((0, 1),))):
        seam = np.flatnonzero(np.isfinite(graph.coords[:, 0]) & np.isclose(graph.coords[:, axis], 0.0))
        seam = seam[np.unique(np.linspace(0, len(seam) - 1, min(24, len(seam))).astype(int))]
        src = seam + N * _COVER.index((0, 0))
        dist, pred = dijkstra(M, directed=True, indices=src, return_predecessors=True)
        for c in classes:
            tgt = seam + N * _COVER.index(c)
            d = dist[np.arange(len(src)), tgt]
            picked, routes = [], []
            for k in np.argsort(d, kind="stable"):
                if d[k] > (1 + margin) * d.min() or len(picked) == 3:
                    break
                nodes = [int(tgt[k])]
                while nodes[-1] != src[k]:
                    nodes.append(int(pred[k, nodes[-1]]))
                at = graph.coords[np.array(nodes[::-1]) % N]
                if all(apart(at, other) for other in routes):
                    picked.append((k, nodes[::-1]))
                    routes.append(at)
            assert [length for length, _ in found[c]] == [d[k] for k, _ in picked], c
            for (_, nodes), (_, poly) in zip(picked, found[c]):
                np.testing.assert_array_equal(poly, _cover_polyline(graph, nodes))
            np.testing.assert_array_equal(found[(-c[0], -c[1])][0][1], found[c][0][1][::-1])
    if scene.name == "nested":  # not vacuous: around the circles, a family of shifted copies, several starts apart
        assert len(found[(1, 0)]) == 3
    some = closed_curve_distances(graph, most=3, margin=margin, classes=[(-1, 1), (0, 1)])
    assert set(some) == {(1, -1), (-1, 1), (0, 1), (0, -1)}
    for c, curves in some.items():
        assert [length for length, _ in curves] == [length for length, _ in found[c]]


@pytest.mark.parametrize("scene", [polygon_pair(17, 0.3, 0.2, 1), polygon_pair(12, 0.6)], ids=["deep", "overlapping"])
def test_closed_curves_searched_through_more_lines(scene):
    """With ``lines=4`` the base points are the seam's (the same ones) and those of three more lines across the
    period: the shortest closed grid curve of each class is never longer than through the seam alone, each curve
    closes up to its class's shift, and, ranked by their coarse geodesics (``_ranked_loops``), a class and its
    opposite keep the same curves, backwards, the shortest coarse geodesic first."""
    from direct.geodesics import closed_curve_distances
    from direct.refinement import GeodesicJob, coarse_geodesics

    graph = _torus_graph(scene)
    S, V = graph.domain.local_lengths
    seam = closed_curve_distances(graph, most=16, margin=0.04)
    wide = closed_curve_distances(graph, most=16, margin=0.04, lines=4)
    assert set(seam) == set(wide)
    for c, curves in wide.items():
        assert curves[0][0] <= seam[c][0][0] * (1 + 1e-12), c
        for _, poly in curves:
            shift = graph.domain.to_local(poly[-1:], wrap=False)[0] - graph.domain.to_local(poly[:1], wrap=False)[0]
            np.testing.assert_allclose(shift, [c[0] * S, c[1] * V], atol=1e-9 * max(S, V))
    assert max(len(curves) for curves in wide.values()) > 2  # not vacuous: more than two curves to rank
    ranked = direct.starts._ranked_loops(graph.domain, get_metric("G"), wide, 2)
    seen = set()
    for c in wide:  # each class ranked by its own coarse geodesics, its opposite in the same order
        if c in seen:
            continue
        seen |= {c, (-c[0], -c[1])}
        curves = ranked[c]
        assert len(curves) == min(2, len(wide[c]))
        opposite = ranked[(-c[0], -c[1])]
        for (_, p), (_, q) in zip(curves, opposite):
            np.testing.assert_array_equal(p, q[::-1])
        if len(wide[c]) > 2:
            lengths = [L for _, L in coarse_geodesics(graph.domain, get_metric("G"),
                                                      [GeodesicJob(np.asarray(p, dtype=float), closed=True)
                                                       for _, p in wide[c]])]
            assert [L for _, L in coarse_geodesics(graph.domain, get_metric("G"),
                                                   [GeodesicJob(np.asarray(p, dtype=float), closed=True)
                                                    for _, p in curves])] == sorted(lengths)[:2]


def test_cover_matrix_is_the_matrix_of_the_cover_edges():
    """The 3 x 3 cover of a torus graph, stacked block by block, against the direct construction from its edges."""
    import scipy.sparse as sp

    from direct.geodesics import _COVER, _cover_index, _cover_matrix

    graph = _torus_graph(polygon_pair(17, 0.3, 0.2, 1), resolution=24)
    N = graph.n_nodes
    rows, cols, data = [], [], []
    for c in _COVER:
        for r, q, dk in ((graph.rows, graph.cols, graph.winds), (graph.cols, graph.rows, -graph.winds)):
            to = np.array(c)[None, :] + dk
            ok = (np.abs(to) <= 1).all(axis=1)
            rows.append(r[ok] + N * _COVER.index(c))
            cols.append(q[ok] + N * _cover_index(to[ok]))
            data.append(graph.weights[ok])
    want = sp.csr_matrix((np.concatenate(data), (np.concatenate(rows), np.concatenate(cols))), shape=(9 * N, 9 * N))
    got = _cover_matrix(graph)
    assert got.shape == want.shape
    np.testing.assert_array_equal(got.indptr, want.indptr)
    np.testing.assert_array_equal(got.indices, want.indices)
    np.testing.assert_array_equal(got.data, want.data)


@pytest.mark.parametrize("scene,resolution,searched_any", [(polygon_pair(24, 1.0), 64, False),
                                                           (polygon_pair(16, 0.3), 64, None),
                                                           (direct.scenes.get("nested"), 64, True)],
                         ids=["apart", "deep", "nested"])
def test_closed_curves_are_searched_only_when_the_program_picks_one(monkeypatch, scene, resolution, searched_any):
    """On a torus the closed curves enter program (34) at lower bounds, and are searched for (the picked classes
    only, each once at most, from the seam they cross) only once a solve picks one: the result is the one the
    searched lengths give from the start (bit for bit), the grid's own value too, and with ``refine=False`` (the
    grid's family: a closed curve picked at its bound used to reach the output unsearched). Two polygons pushed
    apart by their crossings (no closed curve can compete) never search; pushed deep into each other, closed
    curves compete at their bounds (searched or not, they lose); ``nested`` needs one. One grid
    (``second_pass=False``: below the default resolution a second pass would search its own grid's seams)."""
    import sys

    P = sys.modules["direct.penalty"]
    searched = []
    inner = P.closed_curve_distances

    def spy(graph, *args, **kwargs):
        found = inner(graph, *args, **kwargs)
        searched.extend(c for c in found if c >= (0, 0))  # a class and its opposite are one search
        return found

    monkeypatch.setattr(P, "closed_curve_distances", spy)
    lazy = direct.penalty(scene, resolution=resolution, second_pass=False)
    assert searched_any is None or bool(searched) == searched_any
    assert len(set(searched)) == len(searched)  # each class at most once
    lazy_grid = direct.penalty(scene, resolution=resolution, refine=False)
    # the bounds replaced by the grid lengths themselves: every closed curve searched up front
    monkeypatch.setattr(P, "closed_curve_bounds", lambda graph: {c: f[0][0] for c, f in inner(graph).items()})
    eager = direct.penalty(scene, resolution=resolution, second_pass=False)
    eager_grid = direct.penalty(scene, resolution=resolution, refine=False)
    for a, b in ((lazy, eager), (lazy_grid, eager_grid)):
        # bit for bit (the grid's family has no estimate: NaN on both sides)
        np.testing.assert_array_equal([a.value, a.grid_value, a.error_estimate],
                                      [b.value, b.grid_value, b.error_estimate])
        assert [(p.start, p.end, p.closed, p.length) for p in a.pairs] == [
            (p.start, p.end, p.closed, p.length) for p in b.pairs]
    assert any(p.closed for p in lazy.pairs) == (scene.name == "nested")


@pytest.mark.slow
def test_newton_steps_on_a_closed_curve_stay_within_a_period(monkeypatch):
    """``nested`` with the degenerate ``euclid`` metric at 64 cells: where the length is nearly flat, a Newton step
    on a closed curve moved vertices by 2e6 periods, and measuring the trial polyline (split on every vertex line
    it crosses) took 24 GB. The line search now starts within one period; any trial polyline reaching 12 periods
    away (beyond the 10 that the L-BFGS-B polish's bounds allow) fails this test before it can take the memory."""
    import sys

    R = sys.modules["direct.refinement"]
    scene = direct.scenes.get("nested")
    period = max(c.length for c in scene.components)
    inner = R.segment_lengths

    def bounded(metric, comps, P, Q, *args, **kwargs):
        assert np.abs(np.asarray(P)).max() < 12 * period and np.abs(np.asarray(Q)).max() < 12 * period
        return inner(metric, comps, P, Q, *args, **kwargs)

    monkeypatch.setattr(R, "segment_lengths", bounded)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", direct.ToleranceWarning)
        res = direct.penalty(scene, "euclid", resolution=64)
    assert res.value > 0 and all(p.closed for p in res.pairs)


def _interval_moved_into_a_24_gon(angle: float = 0.0, shift=(0.0, 0.0)) -> direct.Scene:
    """A regular 24-gon kept in place and an interval moved inside it: no crossing, one curve across C x I."""
    t = 2 * np.pi * np.arange(24) / 24
    P = np.column_stack([np.cos(t), np.sin(t)])
    c, s = np.cos(angle), np.sin(angle)
    R = np.array([[c, -s], [s, c]])
    inside = np.linspace([-0.3, 0.1], [0.4, -0.2], 4)
    return direct.Scene((direct.Component(P, P @ R.T + shift, closed=True, name="C"),
                         direct.Component(np.column_stack([np.linspace(0, 1, 4), np.full(4, 3.0)]),
                                          inside @ R.T + shift, name="I")))


def test_a_curve_across_a_cylinder_gets_starts_both_ways_round():
    """Its length ripples along the circle, a local minimum about every edge; the grid picked the higher one.

    With forward shifts only, the unmoved scene gave 1.3660003 (estimate 2.1e-7, no warning) and the same
    scene translated by (0.5, 0.5) 1.3643590, whose curves' exact length (upper_bound) bounds J: the first
    was 1.2e-3 above J, silently (an adversarial review).
    """
    found = []
    for angle, shift in ((0.0, (0.0, 0.0)), (0.0, (0.5, 0.5)), (1.0, (0.0, 0.0))):
        # the two neighbouring minima, 1.2e-3 apart relative, are one family: their spread joins the estimate,
        # above tol=1e-3, and each result says so
        with pytest.warns(direct.ToleranceWarning):
            res = direct.penalty(_interval_moved_into_a_24_gon(angle, shift))
        assert res.crossings == []
        found.append(res)
    best = min(r.upper_bound for r in found)
    for res in found:
        assert res.value - res.error_estimate <= best  # J <= best: no value claims to be above it
        assert res.value <= best + 1e-9 * best


@pytest.mark.slow
def test_a_curve_to_the_diagonal_is_refined_with_its_end_slid_beside_a_small_loop():
    """A noisy figure eight with g (p = 2) at tol=1e-5, listed from vertex 0 and from vertex 13.

    Relabelling the vertices is an isometry of M x M.  From vertex 13 both grids sent a crossing point's
    curve to the diagonal 0.25 from where a shorter one ends (1.5024197 against 1.5021047): the value was
    6.3e-4 above the other listing's upper_bound, with an estimate of 1.2e-5 and no warning (an
    adversarial review).  The curves to the diagonal are now refined again with their end slid beside a small
    loop's crossing point (there, 0.076 from the diagonal).
    """
    rng = np.random.default_rng(3)
    t = 2 * np.pi * np.sort(rng.uniform(0, 1, 20))
    ref = np.column_stack([np.cos(t), np.sin(t)])
    dfm = np.column_stack([np.cos(t), np.sin(2 * t)]) + rng.normal(scale=0.03, size=(20, 2))
    found = []
    for k in (0, 13):
        sc = direct.Scene((direct.Component(np.roll(ref, -k, 0), np.roll(dfm, -k, 0), closed=True, name="C"),))
        with warnings.catch_warnings():
            warnings.simplefilter("error", direct.ToleranceWarning)  # and neither needs to warn
            found.append(direct.penalty(sc, metric="g", power=2, tol=1e-5))
    a, b = found
    assert abs(a.value - b.value) <= a.error_estimate + b.error_estimate
    for r in found:
        assert r.value - r.error_estimate <= min(a.upper_bound, b.upper_bound)


def _touching_triangles(start: int = 0) -> direct.Scene:
    """Two closed triangles, one edge of B lying on one edge of A, B outside A: they touch, they do not cross."""
    RA = [[-997.0, 0.0], [-1001.5, 2.598076211353316], [-1001.5, -2.598076211353315]]
    RB = np.array([[-1021.5, -2.598076211353315], [-1017.0, 0.0], [-1021.5, 2.598076211353316]])
    B = np.array([[8, 8], [2.5, 5.5], [5.5, 2.5]], dtype=float)
    return direct.Scene((direct.Component(RA, [[0, 0], [6, 2], [2, 6]], True, "A"),
                         direct.Component(np.roll(RB, -start, 0), np.roll(B, -start, 0), True, "B")))


@pytest.mark.parametrize("start", [0, 1, 2])
def test_curves_that_touch_without_crossing_have_no_penalty(start):
    """The seam's point fell on the stretch where the triangles touch: its winding number was rounding's choice
    (J = 267 with 0 crossings, no warning) or a DegenerateError, depending on where B starts (a review)."""
    sc = _touching_triangles(start)
    assert direct.find_crossings(sc) == []
    assert direct.penalty(sc).value == 0.0


@pytest.mark.parametrize("deformed", [[[2, 7], [3, 5], [5, 3], [9, 1]], [[9, 1], [5, 3], [3, 5], [2, 7]],
                                      [[2, 7], [2.25, 5.75], [5.5, 2.5], [8, 1]]])
def test_an_interval_along_a_circles_edge_has_no_penalty(deformed):
    """An interval runs along an edge of a triangle and leaves on the side it came from (J = 23 and 8.2 before)."""
    tri = direct.Component([[-997.0, 0.0], [-1001.5, 2.598076211353316], [-1001.5, -2.598076211353315]],
                           [[0, 0], [6, 2], [2, 6]], True, "A")
    d = np.asarray(deformed, dtype=float)
    ref = np.column_stack([np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(d, axis=0), axis=1))]),
                           np.full(len(d), 1010.0)])
    sc = direct.Scene((tri, direct.Component(ref, d, name="I")))
    assert direct.find_crossings(sc) == []
    assert direct.penalty(sc).value == 0.0


def test_two_squares_overlapping_along_edges_do_not_depend_on_where_one_starts():
    """The seam point of B at one start lay on A's edge: a DegenerateError the rule did not call for (a review)."""
    def poly(n, cx):
        a = 2 * np.pi * np.arange(n) / n
        return np.column_stack([3 * np.cos(a) + cx, 3 * np.sin(a)])

    A, B = [[0, 0], [2, 0], [2, 2], [0, 2]], [[1, 0], [3, 0], [3, 1], [1, 1]]
    found = [direct.penalty(direct.Scene((direct.Component(poly(4, -1000.0), A, True, "A"),
                                          direct.Component(np.roll(poly(4, -1020.0), -s, 0), np.roll(B, -s, 0),
                                                           True, "B"))))
             for s in range(4)]
    for r in found:
        assert len(r.crossings) == 2
        assert abs(r.value - found[0].value) <= r.error_estimate + found[0].error_estimate
    # and they agree with a nearby generic scene: B moved up by 1e-9, off A's edge (the same two crossings)
    moved = direct.penalty(direct.Scene((direct.Component(poly(4, -1000.0), A, True, "A"),
                                         direct.Component(poly(4, -1020.0), np.array(B) + [0, 1e-9], True, "B"))))
    assert len(moved.crossings) == 2
    assert abs(moved.value - found[0].value) <= moved.error_estimate + found[0].error_estimate + 1e-7


def _interval_by_a_triangle(d) -> direct.Scene:
    """An interval (deformed polyline ``d``, reference far away) beside the triangle (0, 0), (6, 2), (2, 6)."""
    d = np.asarray(d, dtype=float)
    ref = np.column_stack([np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(d, axis=0), axis=1))]),
                           np.full(len(d), 1010.0)])
    tri = direct.Component([[-997.0, 0.0], [-1001.5, 2.598076211353316], [-1001.5, -2.598076211353315]],
                           [[0, 0], [6, 2], [2, 6]], True, "A")
    return direct.Scene((tri, direct.Component(ref, d, name="I")))


@pytest.mark.parametrize("reverse", [False, True])
def test_a_curve_touching_a_circle_along_one_free_stretch_reads_the_other(reverse):
    """An interval runs along a triangle's edge from one end to its first crossing: every level of that stretch
    lies on the triangle, where rounding picked the winding number (J 3.1 times too low, silently; a review).
    It was refused in one listing only; the condition is now read beyond its last crossing, on the other side
    of the crossings (the sum of their signs), and both listings agree with the scenes moved off the edge."""
    d = np.array([[3, 5], [5, 3], [5.05, 3.0], [5.0, 2.9]])
    res = direct.penalty(_interval_by_a_triangle(d[::-1] if reverse else d))
    assert len(res.crossings) == 2
    for eps in (-1e-9, 1e-9):  # the stretch along the edge moved inside (2 crossings) or outside (1)
        moved = direct.penalty(_interval_by_a_triangle(d + [[eps, eps], [eps, eps], [0, 0], [0, 0]]))
        assert len(moved.crossings) == (2 if eps < 0 else 1)
        assert abs(res.value - moved.value) <= res.error_estimate + moved.error_estimate + 1e-9 * res.value
    assert res.value > 0


def test_a_curve_touching_a_circle_along_both_free_stretches_reads_the_one_between():
    """Both stretches from the crossings to the ends run along the triangle's edge; the one between the two
    crossings is off it, and the condition is read there (a code review: refused in both listings before).
    Its curves run where the metric vanishes, their lengths are rounding's (J about 1e-31, with a warning that
    says so): their levels differ by rounding, and they stop at three levels (116 segments) instead of going on
    to the last ones (1,856 segments and 19 s before stop 50)."""
    d = np.array([[3, 5], [5, 3], [5.05, 3.0], [5.5, 2.5], [5.8, 2.2]])
    with pytest.warns(direct.ToleranceWarning, match="mostly from rounding"):  # J is rounding's, about 1e-31
        res = direct.penalty(_interval_by_a_triangle(d))
    assert len(res.crossings) == 2
    assert max(len(p.path) - 1 for p in res.pairs) < 256
    for eps in (-1e-9, 1e-9):  # the stretches along the edge moved inside or outside
        moved = direct.penalty(_interval_by_a_triangle(d + np.array([1, 1, 0, 1, 1])[:, None] * eps))
        # J is about 0 (2e-31; 1.8e-17 with the stretches moved inside, as the cube of a move of 1e-9 would be)
        assert abs(res.value - moved.value) <= res.error_estimate + moved.error_estimate + 1e-15


@pytest.mark.parametrize("reverse", [False, True])
def test_a_curve_touching_a_circle_wherever_it_could_be_read_is_refused(reverse):
    """An interval along the triangle's edge from end to end, with a spike of the triangle poking through it in
    the middle: every stretch off its crossings lies on the edge, so no point reads the condition."""
    d = np.array([[3, 5], [5, 3]], dtype=float)
    sc = _interval_by_a_triangle(d[::-1] if reverse else d)
    with pytest.raises(direct.DegenerateError, match="component 'I' runs along that of component 'A', touching it "
                                                     "without crossing, wherever the topological condition"):
        direct.penalty(sc)


@pytest.mark.parametrize("order", range(4))
def test_an_interval_with_both_ends_on_a_circle_in_every_listing(order):
    """An interval from a square's edge back to it, bulging out: the perturbation counts both end contacts as
    crossings in some listings, leaving no stretch below the first or beyond the last (a code review: refused in
    two of the three listings, with a message about curves running along each other); read between them now."""
    sq = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]])
    a = 2 * np.pi * np.arange(4) / 4
    C = direct.Component(np.column_stack([np.cos(a), np.sin(a)]) + [100.0, 0.0], sq, True, "C")
    d = np.array([[0.0, 1.0], [-2.0, 2.0], [0.0, 3.0]])
    iv = direct.Component([[0.0, 50.0], [1.0, 50.0], [2.0, 50.0]], d, name="I")
    comps = [(iv, C), (C, iv), (iv.reversed(), C), (C, iv.reversed())][order]
    res = direct.penalty(direct.Scene(comps))
    moved = [direct.penalty(direct.Scene((direct.Component(iv.reference, d + [[e, 0], [0, 0], [e, 0]], name="I"),
                                          C))) for e in (1e-9, -1e-9)]  # the ends moved inside or outside
    for r in moved:
        assert abs(res.value - r.value) <= res.error_estimate + r.error_estimate + 1e-20


@pytest.mark.parametrize("seed", range(40))
def test_a_cylinders_condition_read_in_every_gap_of_the_interval(seed, monkeypatch):
    """The flux of eq. (6) on a cylinder read in any gap between the interval's crossings, or beyond the last
    (the winding number there, plus the sum of the signs ``s`` of the crossings below), is the one read before
    its first crossing, on random polylines across random polygons (0 to 12 crossings), in either order: what
    makes the readings of an interval that starts on the circle sound (``_interval_level``)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(3, 9))
    a = 2 * np.pi * np.sort(rng.uniform(0, 1, n))
    ring = np.column_stack([np.cos(a), np.sin(a)]) * rng.uniform(0.5, 1.5, (n, 1))
    ring = ring[::-1] if seed % 2 else ring  # turned either way
    a0 = 2 * np.pi * np.arange(n) / n
    pent = direct.Component(np.column_stack([np.cos(a0), np.sin(a0)]) + [10.0, 0.0], ring, True, "C")
    m = int(rng.integers(2, 8))
    iv = direct.Component(np.column_stack([np.arange(m, dtype=float), np.full(m, 5.0)]),
                          rng.normal(scale=1.0, size=(m, 2)), name="I")
    P = sys.modules["direct.penalty"]
    inner = P._free_level
    for comps in ((iv, pent), (pent, iv)):
        sc = direct.Scene(comps)
        dom = next(d for d in domains(sc, direct.find_crossings(sc)) if d.kind == "cylinder")
        monkeypatch.setattr(P, "_free_level", inner)
        before = boundary_conditions(dom)
        v = np.sort(dom.to_local(dom.points)[:, 1]) if len(dom.points) else np.empty(0)
        gaps = list(zip(v, [*v[1:], dom.local_lengths[1]]))  # beyond each crossing

        def only(gap):
            def reading(*args, **kwargs):
                if kwargs.get("gap") != gap:
                    raise direct.DegenerateError("read elsewhere")
                return inner(*args, **kwargs)
            return reading

        for gap in gaps:
            monkeypatch.setattr(P, "_free_level", only(gap))
            assert boundary_conditions(dom) == before, (len(dom.points), gap, before)


def test_an_interval_starting_on_a_vertex_of_a_circle_in_every_listing():
    """An interval starts exactly on a vertex of a pentagon, integer coordinates as a property test makes them:
    the perturbation counts the contact as a crossing at the start in some listings, and the stretch from the
    start to it, of length 0, was all there was to read the condition from: a DegenerateError whose message
    spoke of curves running along each other, in one of the four listings only (a review, stop 49)."""
    a = 2 * np.pi * np.arange(5) / 5
    pent = direct.Component(np.column_stack([np.cos(a), np.sin(a)]), [[3, 0], [-1, -1], [-2, 1], [2, 3], [-2, 2]],
                            True, "C")
    d = np.array([[-1.0, -1.0], [-2.0, 0.0], [-3.0, -3.0], [0.0, -1.0]])  # starts on the pentagon's vertex 1
    iv = direct.Component([[0.0, 6.0], [1.0, 6.0], [2.0, 6.0], [3.0, 6.0]], d, name="I")
    found = []
    for comps in ((iv, pent), (pent, iv), (iv.reversed(), pent), (pent, iv.reversed())):
        res = direct.penalty(direct.Scene(comps))
        # the pentagon's self-crossing, and the contact at the start in some listings
        assert len(res.crossings) in (1, 2)
        found.append(res)
    # and the scene with the start moved off the vertex by 1e-9, either way
    for eps in ((1e-9, 0.0), (-1e-9, 0.0), (0.0, 1e-9), (0.0, -1e-9)):
        dd = d.copy()
        dd[0] += eps
        found.append(direct.penalty(direct.Scene((direct.Component(iv.reference, dd, name="I"), pent))))
    assert {1, 2} <= {len(r.crossings) for r in found} <= {1, 2, 3}  # moved, it may cross both edges at the vertex
    for r in found:
        assert abs(r.value - found[0].value) <= r.error_estimate + found[0].error_estimate + 1e-8 * r.value
    assert found[0].value > 0


@pytest.mark.parametrize("turn", [0, 1])
def test_a_spike_on_a_circle_is_refused_not_guessed(turn):
    """A square with a segment traversed out and back: J was 0 or 14.5 depending on a rotation (a review)."""
    a = 2 * np.pi * np.arange(7) / 7
    ref = np.column_stack([3 * np.cos(a) - 1000.0, 3 * np.sin(a)])
    d = np.array([[0, 0], [2, 0], [2, 1], [3, 1], [2, 1], [2, 2], [0, 2]], dtype=float)
    if turn:
        ref, d = ref @ np.array([[0, 1], [-1, 0]]), d @ np.array([[0, 1], [-1, 0]])
    with pytest.raises(direct.DegenerateError, match="turns exactly back on itself at vertex 3"):
        direct.penalty(direct.Scene((direct.Component(ref, d, True, "S"),)))


def test_a_figure_eight_on_an_unevenly_spaced_reference_circle():
    """``fig10`` with its reference vertices respaced at random (steps from 0.02 to 2, speeds spanning 265): J^G
    does not change (Prop. 18). In the reference arclength the closed geodesic of the annulus came out 1.6e-2 too
    high with an estimate of 4.5e-4 and no warning, in 75 s; the component is now computed in its deformed
    arclength, and its curve comes back in the reference arclength, the same curve (its exact length there is its
    ``polyline_length``, across the seam too)."""
    from direct.metric import segment_lengths

    base = direct.scenes.get("fig10")
    c = base.components[0]
    steps = np.exp(np.random.default_rng(1).uniform(np.log(0.02), np.log(2.0), c.n_vertices))
    angles = 2 * np.pi * np.concatenate([[0.0], np.cumsum(steps)[:-1]]) / steps.sum()
    ref = np.column_stack([np.cos(angles), np.sin(angles)])
    scene = direct.Scene((direct.Component(ref, c.deformed, closed=True, name=c.name),))
    a, b = direct.penalty(base), direct.penalty(scene)
    assert abs(a.value - b.value) <= a.error_estimate + b.error_estimate
    comps = scene.components * 2
    for p in b.pairs:
        exact = segment_lengths(get_metric("G"), comps, p.path[:-1], p.path[1:]).sum()
        assert exact == pytest.approx(p.polyline_length, rel=1e-9)


#: two random 7-gons deformed one inside the other, without a crossing (an adversarial review): only closed curves
NESTED_7 = [
    {"name": "a", "closed": True,
     "reference": [[-0.9999812258431823, 0.006127639118497409], [-0.6282688775394631, -0.7779962837413191],
                   [0.21654274990100467, -0.9762731367119096], [0.8982932699989085, -0.4393964053957065],
                   [0.9036106359443019, 0.42835478123669196], [0.2284907627258056, 0.973546080752719],
                   [-0.6186873151873751, 0.7856373247410268]],
     "deformed": [[0.1660108225639309, 0.6472887226216566], [0.05855679955182944, 0.6871495839530941],
                  [-0.22515579103824798, 0.396776824664185], [-0.47140163419246256, 0.14407843743809867],
                  [-0.39457282925796466, -0.04479249177561903], [-0.3028149733276996, -0.10384641223285002],
                  [0.602411255671242, 0.022877179936567404]]},
    {"name": "b", "closed": True,
     "reference": [[-0.7221877677689428, 2.3083029361888894], [0.09051383258716522, 2.004104801643073],
                   [0.8350566708594349, 2.4498360640198618], [0.9507848039227603, 3.3098519914887725],
                   [0.3505525871567584, 3.9365430495378755], [-0.5136528777078928, 3.8579980892883157],
                   [-0.9910672490492832, 3.1333630678332125]],
     "deformed": [[0.8613670514166641, 0.18162665297180536], [0.5624714873874339, 0.7510200528832931],
                  [0.2920671250531245, 0.9433864518687304], [0.23824598959288343, 1.1377774544066945],
                  [-0.9761099649668795, 0.4597068970299919], [-0.43336796400820377, -0.8293247809969382],
                  [0.6569125810321658, -0.46830850195823737]]},
]


def test_closed_geodesics_closer_than_the_grid_can_rank():
    """Two random nested 7-gons: six closed geodesics of the class the program picks lie within 1 % of each other
    (1.786 to 1.803), and the grid's shortest closed curve refines to the fourth. Listed ``(b, a)``, ``J`` came out
    7.0e-3 above (3.5967, estimate 3.8e-4, no warning), proved by the exact length of the curves of the listing
    with ``b`` started at its vertex 2 (3.5716); the grid's closed curves within its bias, on routes apart, now all
    start a refinement. The three listings agree within their estimates, each below the others' upper bounds."""
    a, b = NESTED_7
    b2 = dict(b, reference=np.roll(b["reference"], -2, 0).tolist(), deformed=np.roll(b["deformed"], -2, 0).tolist())
    results = []
    for comps in ([b, a], [a, b], [a, b2]):
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # and no warning
            results.append(direct.penalty(direct.Scene.from_dict({"components": comps})))
    for r, s in itertools.permutations(results, 2):
        assert abs(r.value - s.value) <= r.error_estimate + s.error_estimate
        assert r.value - r.error_estimate <= s.upper_bound
    assert all(r.error_estimate < 1e-3 * r.value for r in results)


#: a 13-gon entered by an interval, one crossing (a cylinder of M x M; an adversarial review)
ENTERED_13 = [
    {"name": "a", "closed": True,
     "reference": [[-0.997582764204796, -0.0694883339958472], [-0.851022830658335, -0.5251286906066693],
                   [-0.5095038225449522, -0.8604683926862635], [-0.051263628873207776, -0.9986851557697001],
                   [0.41872044437968803, -0.9081151851271273], [0.7927807099535774, -0.6095069695462897],
                   [0.9852244689203611, -0.17126805259765282], [0.9519651752994577, 0.3062063111973245],
                   [0.7006221324414768, 0.7135324992830794], [0.2887750024531558, 0.9573969907818699],
                   [-0.18922700048114155, 0.981933369577035], [-0.6238793780377752, 0.7815206469820224],
                   [-0.9156085086475083, 0.40207096250821894]],
     "deformed": [[0.6586184468329808, 0.7764726366907047], [0.4161180059789507, 0.8496344698575807],
                  [-0.6423452524137121, 0.8398230024498685], [-1.0338310968916535, 0.1434716561336162],
                  [-1.2133508291863206, 0.11692773094849046], [-0.999208420802318, 0.09850887490788836],
                  [-0.6171221245418059, -0.44383142588084457], [-0.5858275701795808, -0.9853327597151859],
                  [-0.22841789589028433, -0.8552897289892248], [1.0473705844988275, -0.37680089657717053],
                  [0.9726585562775868, -0.24663319124151337], [0.852235164806702, -0.11361386194213136],
                  [1.1443459413412875, -0.11637208390761167]]},
    {"name": "b", "closed": False,
     "reference": [[0.0, 3.0], [0.6853152415458719, 3.0], [1.0807094941751407, 3.0], [1.6106675005493816, 3.0],
                   [2.091575030500336, 3.0], [2.4769399402234735, 3.0], [2.887615770151367, 3.0],
                   [3.668869475814556, 3.0]],
     "deformed": [[1.3443728604503564, -1.1969384328713513], [1.8007946277998632, -1.072904663711502],
                  [1.333446164310181, -1.066403002337159], [0.9967328432643415, -0.48320283866369773],
                  [0.8378517734141462, -0.28121428545718974], [0.7050391766817965, 0.14140550494123832],
                  [0.42748948963288635, 0.06399877588364843], [-0.7212546138316546, 0.4373238502059297]]},
]


def test_a_curve_pinned_at_a_corner_of_the_cells_is_refined_from_beside_it():
    """The 13-gon entered by an interval: the grid routes the curve from the crossing point to the boundary
    through a corner of the cells (a vertex line of each component), and the refinement kept it there, 1.6e-4
    (relative) above the geodesic that passes 9e-3 beside it, with an estimate of 7e-5 and no warning at
    ``tol=1e-4``; listed from its vertex 10, the first grid's route missed the corner. Each listing's value, less
    its estimate, is now below the other's ``upper_bound`` (the exact length of its curves)."""
    a, b = ENTERED_13
    a10 = dict(a, reference=np.roll(a["reference"], -10, 0).tolist(),
               deformed=np.roll(a["deformed"], -10, 0).tolist())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", direct.ToleranceWarning)
        r, s = (direct.penalty(direct.Scene.from_dict({"components": [c, b]}), tol=1e-4) for c in (a, a10))
    assert r.value - r.error_estimate <= s.upper_bound
    assert s.value - s.error_estimate <= r.upper_bound
    assert abs(r.value - s.value) <= 1e-5 * r.value


def test_corner_vertices_and_the_starts_that_leave_them():
    """``_corner_vertices`` finds the vertices of a polyline on a corner of the cells (within 1e-2 of the longer
    segment from a vertex line of both components, a curve along one of the lines too), not those on one line only;
    ``_corner_starts`` bumps the curve around them across itself, to the left and to the right (the corner vertex
    by 0.3 of its longer segment, the vertices within 1.5 such segments along the curve less, in a tent), and
    leaves the vertices farther along and the ends as they were."""

    from direct.crossings import find_crossings
    from direct.refinement import GeodesicJob, RefinedPath

    sc = direct.Scene.from_dict({"components": ENTERED_13})
    (dom,) = [d for d in domains(sc, find_crossings(sc)) if d.kind == "cylinder"]
    va, vb = dom.comps[0].params[3], dom.comps[1].params[2]  # a corner of the cells
    X = np.array([[va - 0.3, vb - 0.2], [va - 0.1, vb - 0.1], [va, vb + 1e-7], [va + 0.1, vb + 0.05],
                  [va + 0.2, vb + 0.3], [va + 0.25, 0.5 * (dom.comps[1].params[2] + dom.comps[1].params[3])]])
    assert direct.starts._corner_vertices(dom, X, closed=False).tolist() == [2]
    assert direct.starts._corner_vertices(dom, X + [0.0, 0.05], closed=False).tolist() == []  # on the line va only
    riding = X.copy()
    riding[1:4, 0] = va  # along the line va through the corner (a crease): held there too
    assert direct.starts._corner_vertices(dom, riding, closed=False).tolist() == [2]
    path = RefinedPath(X, 1.0, 1.0, 0.0, len(X) - 1)
    left, right = direct.starts._corner_starts(dom, path, GeodesicJob(X, end_ground=1))
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(X, axis=0), axis=1))])
    longer = max(np.linalg.norm(X[2] - X[1]), np.linalg.norm(X[3] - X[2]))
    near = np.abs(arc - arc[2]) < 1.5 * longer  # the tent's reach
    near[[0, -1]] = False
    assert near[[1, 3]].all()  # the neighbours move too
    for start, side in ((left, 1.0), (right, -1.0)):
        assert start.end_ground == 1 and not start.closed
        np.testing.assert_array_equal(start.route[~near], X[~near])
        moves = start.route - X
        move = moves[2]
        chord = X[3] - X[1]
        assert abs(move @ chord) < 1e-12  # across the curve
        assert np.sign(chord[0] * move[1] - chord[1] * move[0]) == side
        assert abs(np.linalg.norm(move) - 0.3 * longer) < 1e-12
        assert 0 < np.linalg.norm(moves[1]) < np.linalg.norm(move)
        assert np.all(np.linalg.norm(moves, axis=1) <= np.linalg.norm(move) + 1e-12)  # a tent: the corner moves most
    assert direct.starts._corner_starts(dom, RefinedPath(X + [0.0, 0.05], 1.0, 1.0, 0.0, 5), GeodesicJob(X)) == []


#: two overlapping random polygons, an 11-gon and a 7-gon (a torus with crossings; an adversarial review)
OVERLAPPING_11_7 = [
    {"name": "a", "closed": True,
     "reference": [[0.9405682949607733, 0.3396045973107308], [0.8378165020152257, 0.5459519291576607],
                   [0.5874687102576585, 0.8092468810370562], [0.3803540264015859, 0.9248409671938748],
                   [-0.15624436461090896, 0.9877184307925682], [-0.29998682207644095, 0.9539433455821565],
                   [-0.9244419878914844, -0.3813227124408415], [-0.8086455741784621, -0.5882961289704237],
                   [-0.5493745439208394, -0.8355762146517633], [-0.13430114335745866, -0.9909405647630333],
                   [0.392678501953805, -0.9196758092411236]],
     "deformed": [[0.8490997492700286, 0.6547376145912149], [0.7450566838081566, 0.5946566374357461],
                  [0.30006361710773055, 0.9626051781199464], [-0.43461323618102293, 0.9522277959841408],
                  [-1.1613854402275943, 0.21467231513023544], [-0.41365822657461027, -0.8763722241489631],
                  [-0.4139352070038145, -1.122212471119446], [0.16902676342595466, -1.043254416318593],
                  [0.6800515354370312, -0.9455183231211851], [0.7470930438462677, -0.6632563482428101],
                  [0.9743133338942608, -0.5024912606171871]]},
    {"name": "b", "closed": True,
     "reference": [[0.9707270180339284, 3.2401854626303543], [0.8064105797236215, 3.591356049186793],
                   [0.21063520098978347, 3.9775647355055286], [-0.5306463259287053, 3.8475933439913073],
                   [-0.9627626674317108, 3.270348009424477], [-0.9897307216891192, 2.8570556103068916],
                   [-0.29734468761864374, 2.045229798985656]],
     "deformed": [[0.4245871417451592, -0.2946201432710093], [0.32337825733808745, 0.1020962167851282],
                  [0.24451493541012015, 0.12724237480718614], [0.04381436974313985, 0.49140273819489866],
                  [-1.22171369412842, -0.11884937776253357], [-1.0240546325037427, -0.8975145331269324],
                  [0.057307264244131295, -1.1282054841109985]]},
]


def test_a_curve_held_beside_a_corner_of_the_cells():
    """Two overlapping polygons listed with both vertex lists reversed: a curve between crossing points was held
    with vertices 3.8e-3 and 7.5e-3 of their longer segments from a corner of the cells, 1.4e-3 (relative) above
    ``J`` at the default ``tol``, with an estimate of 8.7e-5 and no warning (all five listings tried, before the
    starts beside the corners; with a window of 1e-3 around the corners, four). Each listing's value, less its
    estimate, is now below the other's ``upper_bound``."""
    rev = [dict(c, reference=c["reference"][::-1], deformed=c["deformed"][::-1]) for c in OVERLAPPING_11_7]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r, s = (direct.penalty(direct.Scene.from_dict({"components": comps})) for comps in (OVERLAPPING_11_7, rev))
    assert r.value - r.error_estimate <= s.upper_bound
    assert s.value - s.error_estimate <= r.upper_bound


def test_a_start_beside_a_corner_keeps_the_estimate_of_the_curve_it_replaces(monkeypatch):
    """``_restarted`` keeps the shortest of the curve held and its starts, with the larger of the two
    estimates: a start that settles a little lower in the same geodesic must not drop what the held estimate
    covers (the spread of a family of closed curves: ``nested`` listed from another vertex came out 7.2e-5 above
    ``J`` with an estimate of 8.0e-6); a longer start changes nothing."""

    from direct.refinement import GeodesicJob, RefinedPath

    X = np.array([[0.0, 0.0], [1.0, 1.0]])
    held = {"k": RefinedPath(X, 2.0, 2.0, 1e-4, 1)}
    for lengths, want in (((1.9999, 2.5), (1.9999, 1e-4)), ((2.1, 2.5), None)):
        monkeypatch.setattr(direct.starts, "refine_many", lambda domain, metric, jobs, tol, atol, above=None,
                            lengths=lengths: [RefinedPath(X, L, L, 1e-7, 1) for L in lengths])
        out = direct.starts._restarted(None, None, {"k": [GeodesicJob(X), GeodesicJob(X)]}, held, 1e-3, 0.0)
        assert (None if not out else (out["k"].length, out["k"].error_estimate)) == want


def _limacon_32(reverse: bool = False) -> direct.Scene:
    """The limaçon r = 0.7 + cos t sampled at 32 vertices (t_k = 2 pi k / 32 + 0.1), one self-crossing; reference
    the unit 32-gon."""
    u = 2 * np.pi * np.arange(32) / 32
    t = u + 0.1
    ref = np.column_stack([np.cos(u), np.sin(u)])
    dfm = np.column_stack([(0.7 + np.cos(t)) * np.cos(t), (0.7 + np.cos(t)) * np.sin(t)])
    if reverse:
        ref, dfm = ref[::-1], dfm[::-1]
    return direct.Scene((direct.Component(ref, dfm, closed=True, name="L"),))


def test_a_limacon_whose_cell_corners_line_up_along_its_curves():
    """Found by an adversarial review (stop 28): on the limaçon sampled evenly around its loop the cells' corners
    line up along the curves from the crossing point to the diagonal, and curves stopped at one corner of the row or
    another, in local geodesics up to 2.1e-5 (relative) apart: at the default tol both listings lay above the upper
    bound of the run at tol=1e-5 by more than their estimates (2.6e-6 and 1.1e-5, estimates 2.6e-7 and 4.4e-6), with
    no warning, and the two curves of the reversed listing, mirror images of equal length, differed by 1.6e-5.
    Now a run of collapsed vertices merges, and the two mirror curves of a circle with itself take the shorter of
    the two, their estimate widened by their spread. No listing at either tol is above another's upper bound by
    more than its estimate, the default runs do not warn, the mirror curves have one length, and the two listings
    at tol=1e-5 agree within their estimates."""
    runs = {}
    for rev in (False, True):
        with warnings.catch_warnings():
            warnings.simplefilter("error", direct.ToleranceWarning)
            runs[rev, 1e-3] = direct.penalty(_limacon_32(rev))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", direct.ToleranceWarning)  # the given listing: two minima 2.1e-5 apart
            runs[rev, 1e-5] = direct.penalty(_limacon_32(rev), tol=1e-5)
    upper = min(r.upper_bound for r in runs.values())
    for r in runs.values():
        assert r.value - r.error_estimate <= upper
        a, b = (p.length for p in r.pairs)
        assert a == b
    a, b = (runs[rev, 1e-5] for rev in (False, True))
    assert abs(a.value - b.value) <= a.error_estimate + b.error_estimate


def _figure_eight_on_vertices(roll: int = 0, reverse: bool = False) -> direct.Scene:
    """The figure eight (sin t, sin t cos t) at 24 vertices evenly in t (reference: the unit 24-gon): its crossing
    lies on vertices 0 and 12, both at the origin, where the polyline runs straight through."""
    t = 2 * np.pi * np.arange(24) / 24
    ref = np.column_stack([np.cos(t), np.sin(t)])
    dfm = np.column_stack([np.sin(t), np.sin(t) * np.cos(t)])
    if reverse:
        ref, dfm = ref[::-1], dfm[::-1]
    return direct.Scene((direct.Component(np.roll(ref, roll, 0), np.roll(dfm, roll, 0), closed=True, name="L"),))


def test_figure_eight_crossing_on_vertices_in_every_listing():
    """Found by an adversarial review (stop 29): the figure eight above gave 1.797252 as listed (estimate 6.8e-6,
    no warning), 1.701223 started from vertex 5 and 1.684693 reversed: the first 7 % above J. Its curves from the
    crossing point to the diagonal run on either side of the direction (-1, 1) of the parameters, where the
    annulus grid, its 16 moves taken in (s, v), had gaps of 45 degrees: every route there cost up to 8 % more, and
    the grid chose the straight curve along (-1, 1), a local geodesic 6.7 % longer. With the 16 moves of the
    parameters every listing must find the same curves: each within its estimate of the least upper bound of all,
    with no warning."""
    runs = []
    for kw in ({}, {"roll": 5}, {"reverse": True}, {"roll": 3}):
        with warnings.catch_warnings():
            warnings.simplefilter("error", direct.ToleranceWarning)
            runs.append(direct.penalty(_figure_eight_on_vertices(**kw)))
    upper = min(r.upper_bound for r in runs)
    for r in runs:
        assert len(r.crossings) == 1
        assert r.value - r.error_estimate <= upper <= r.upper_bound
        assert r.value <= 1.69  # the straight curves: 2 x 0.898626


@pytest.mark.parametrize("reverse", [False, True])
def test_a_symmetric_figure_eight_with_eight_neighbours(reverse):
    """Found by an adversarial review (stop 30): the figure eight (sin t, sin t cos t) at 12 vertices, its crossing on
    vertices 0 and 6, gave 1.564671089 with ``neighbours=8`` as given and reversed (estimates 1.5e-14 and 2.4e-14, no
    warning), 4.9 % above the 16-neighbour run. Both grids had 8 moves: the straight curve from the crossing point
    along (-1, 1), a local geodesic, is one of them, and the shortest curves beside it cost up to 8.2 % more on that
    grid. The route check's grid has 16 moves now (``second_neighbours``): the two stencils must agree."""
    t = 2 * np.pi * np.arange(12) / 12
    ref = np.column_stack([np.cos(t), np.sin(t)])
    dfm = np.column_stack([np.sin(t), np.sin(t) * np.cos(t)])
    if reverse:
        ref, dfm = ref[::-1], dfm[::-1]
    a, _ = _stencils_agree(direct.Scene((direct.Component(ref, dfm, closed=True, name="L"),)), (8, 16))
    assert len(a.crossings) == 1
    assert a.value <= 1.5  # the straight curves: 1.5647


def _stencils_agree(sc: direct.Scene, stencils: tuple[int, int]):
    """The penalties of ``sc`` with the two stencils, without a warning, each value less its estimate below the
    other's ``upper_bound``."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", direct.ToleranceWarning)
        a, b = (direct.penalty(sc, neighbours=k) for k in stencils)
    assert a.value - a.error_estimate <= b.upper_bound
    assert b.value - b.error_estimate <= a.upper_bound
    return a, b


def _limacon(n: int, a: float, reverse: bool = False, roll: int = 0, angle: float = 0.0) -> direct.Scene:
    """The limaçon ``r = a + cos t`` at ``n`` vertices evenly in ``t`` from 0 (reference: the unit ``n``-gon), its
    vertex list reversed and rolled by ``roll``, the plane turned by ``angle``."""
    t = 2 * np.pi * np.arange(n) / n
    r = a + np.cos(t)
    c, s = np.cos(angle), np.sin(angle)
    dfm = np.column_stack([r * np.cos(t), r * np.sin(t)]) @ np.array([[c, -s], [s, c]]).T
    ref = np.column_stack([np.cos(t), np.sin(t)])
    if reverse:
        ref, dfm = ref[::-1], dfm[::-1]
    return direct.Scene((direct.Component(np.roll(ref, -roll, 0), np.roll(dfm, -roll, 0), closed=True, name="L"),))


def test_bent_and_straight_starts():
    """``_bent_starts`` bends the chord of a straight open curve along (1, -1) (within 1e-5 of its chord) by 1 % and
    10 % of it at its middle, to either side, in 16 segments, its ends kept, and leaves alone curved ones, those
    along other directions, those with both ends free and closed ones;
    ``_straight_starts`` runs straight from the crossing point of a short curve to its ground along the parameter
    axes and (1, -1), oriented as the curve, and leaves long curves alone."""

    from direct.crossings import find_crossings
    from direct.refinement import GeodesicJob, RefinedPath

    X = np.column_stack([np.linspace(1.0, 2.0, 9), np.linspace(3.0, 2.0, 9)])  # along (1, -1)
    path = RefinedPath(X, 1.0, 1.0, 0.0, 8)
    starts = direct.starts._bent_starts(path, GeodesicJob(X, end_ground=0))
    chord = X[-1] - X[0]
    normal = np.array([-chord[1], chord[0]]) / np.linalg.norm(chord)
    assert len(starts) == 4
    for start, (bend, side) in zip(starts, [(b, side) for b in (0.01, 0.1) for side in (1.0, -1.0)]):
        assert len(start.route) == 17 and start.coarse  # refined from the bent polyline itself
        np.testing.assert_allclose(start.route[[0, -1]], X[[0, -1]])
        np.testing.assert_allclose(start.route[8] - X[4], side * bend * np.linalg.norm(chord) * normal)
        off = (start.route - X[0]) @ normal
        assert np.all(side * off >= -1e-12) and np.all(side * off <= bend * np.linalg.norm(chord) + 1e-12)
        assert start.end_ground == 0 and start.start_ground is None
    assert direct.starts._bent_starts(path, GeodesicJob(X, start_ground=0, end_ground=1)) == []  # both ends free
    Z = np.column_stack([X[:, 0], np.linspace(3.0, 2.5, 9)])  # straight, not along (1, -1)
    assert direct.starts._bent_starts(RefinedPath(Z, 1.0, 1.0, 0.0, 8), GeodesicJob(Z, end_ground=0)) == []
    Y = X.copy()
    Y[4, 1] += 1e-4  # 7e-5 of the chord off it
    assert direct.starts._bent_starts(RefinedPath(Y, 1.0, 1.0, 0.0, 8), GeodesicJob(Y, end_ground=0)) == []
    Y[4, 1] = X[4, 1] + 1e-7  # within 1e-5 of the chord: straight still
    assert len(direct.starts._bent_starts(RefinedPath(Y, 1.0, 1.0, 0.0, 8), GeodesicJob(Y, end_ground=0))) == 4
    assert direct.starts._bent_starts(path, GeodesicJob(X, closed=True)) == []

    (dom,) = domains(*(lambda sc: (sc, find_crossings(sc)))(_limacon(17, 0.928)))
    assert dom.kind == "annulus"
    ng = dom.n_grounds
    p = dom.points[0]
    for g in range(ng):
        for key in ((ng, g), (g, ng)):
            q = p + [0.0, 0.01]
            X = np.array([p, q]) if key[0] >= ng else np.array([q, p])
            held = RefinedPath(X, 1.0, 1.0, 0.0, 1)
            assert direct.starts._straight_starts(dom, key, held, ng, cell=1e-4) == []  # a long curve
            starts = direct.starts._straight_starts(dom, key, held, ng, cell=10.0)
            assert 1 <= len(starts) <= 3
            for job in starts:
                a, b = job.route
                point, other = (a, b) if key[0] >= ng else (b, a)
                np.testing.assert_array_equal(point, p)
                d = other - point
                assert min(abs(d[0]), abs(d[1]), abs(d[0] + d[1])) < 1e-12  # along an axis or (1, -1)
                v = dom.to_local(other[None, :], wrap=False)[0, 1]
                assert abs(v - (0.0 if g == 0 else dom.local_lengths[1])) < 1e-9  # on the ground
                assert (job.start_ground, job.end_ground) == ((g, None) if key[0] < ng else (None, g))
    assert direct.starts._straight_starts(dom, (ng, ng + 1), held, ng, cell=10.0) == []  # point to point



def _epitrochoid(e: float, first: int, reverse: bool, n: int = 21, t0: float = 0.67483) -> direct.Scene:
    """The epitrochoid ``e^{it} + e e^{3it}`` at ``n`` vertices ``t = 2 pi k / n + t0`` (reference: the unit
    ``n``-gon at ``2 pi k / n``), listed from vertex ``first``, forwards or backwards."""
    k = (first + (-1 if reverse else 1) * np.arange(n)) % n
    t = 2 * np.pi * k / n
    z = np.exp(1j * (t + t0)) + e * np.exp(3j * (t + t0))
    return direct.Scene((direct.Component(np.column_stack([np.cos(t), np.sin(t)]), np.column_stack([z.real, z.imag]),
                                          closed=True, name="E"),))


@pytest.mark.parametrize("e", [0.48587, 0.486])
def test_an_epitrochoid_whose_small_loops_are_nearly_symmetric(e):
    """An adversarial review (stop 31): the epitrochoid ``e^{it} + 0.486 e^{3it}`` at 21 vertices, listed backwards
    from vertex 7, gave 0.0170643 at ``tol=1e-5`` and at the default ``tol`` (estimates 8.4e-8 and 6.4e-7, no
    warning), 1.96e-3 above the ``upper_bound`` of the listing forwards from vertex 0 (0.0170310): the curve from
    a small loop's crossing point reached the diagonal 0.15 before the loop's middle, where the shorter one, 0.4 %
    shorter, reaches it 0.15 after (``_reflected_starts``). Both listings agree now."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", direct.ToleranceWarning)
        a = direct.penalty(_epitrochoid(e, first=7, reverse=True))
        b = direct.penalty(_epitrochoid(e, first=0, reverse=False))
    assert len(a.crossings) == len(b.crossings) == 2
    assert a.value - a.error_estimate <= b.upper_bound
    assert b.value - b.error_estimate <= a.upper_bound
    assert abs(a.value - b.value) <= a.error_estimate + b.error_estimate


def _trefoil(reverse: bool = False, roll: int = 0, n: int = 27, c: float = 1.6, t0: float = 0.03) -> direct.Scene:
    """The curve ``r = 1 + c cos 3t`` at ``n`` vertices ``t = 2 pi k / n + t0`` (reference: the unit circle at the
    same ``t``), its vertex list reversed, then rolled by ``roll``."""
    t = t0 + 2 * np.pi * np.arange(n) / n
    z = (1 + c * np.cos(3 * t)) * np.exp(1j * t)
    ref, dfm = np.column_stack([np.cos(t), np.sin(t)]), np.column_stack([z.real, z.imag])
    if reverse:
        ref, dfm = ref[::-1], dfm[::-1]
    return direct.Scene((direct.Component(np.roll(ref, -roll, 0), np.roll(dfm, -roll, 0), closed=True, name="T"),))


@pytest.mark.slow
def test_a_trefoil_whose_curves_run_beside_a_vertex_line():
    """An adversarial review (stop 32): the trefoil ``r = 1 + 1.6 cos 3t`` at 27 vertices (15 crossings; its
    rotation by a third of a turn maps the polygon onto itself, and each curve onto two copies) gave 1.0088995 at
    the default ``tol`` (estimate 5.5e-4) as listed and 1.0093941 (estimate 9.3e-5, no warning) listed backwards
    and rolled by 14: one or two of the three copies of a curve ran across a vertex line by 0.32 cells, 0.5 %
    longer than the others, 0.18 cells beside it (``_crease_starts``). Both listings now agree, below the old
    values by more than the old estimates."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", direct.ToleranceWarning)
        a = direct.penalty(_trefoil())
        b = direct.penalty(_trefoil(reverse=True, roll=14))
    assert len(a.crossings) == len(b.crossings) == 15
    assert a.value - a.error_estimate <= b.upper_bound
    assert b.value - b.error_estimate <= a.upper_bound
    assert abs(a.value - b.value) <= a.error_estimate + b.error_estimate
    # the three copies of each curve under the rotation have one length (within their estimates)
    lengths = np.sort([p.length for p in a.pairs])
    errors = np.array([p.error_estimate for p in sorted(a.pairs, key=lambda p: p.length)])
    for k in range(0, len(lengths), 6):  # each copy twice (the curve and its mirror image), three copies
        assert lengths[k + 5] - lengths[k] <= errors[k:k + 6].max() + 1e-12 * lengths[k]



def test_crease_starts():
    """``_crease_starts`` folds a curve's stretch beside a vertex line (within one cell, two cells or more along it)
    onto the side it is not wholly on (each side, for a stretch across it): offsets kept in size, the other
    vertices and the ends as they were; none for a stretch shorter than two cells or farther than one."""

    from direct.crossings import find_crossings
    from direct.metric import _vertex_params
    from direct.refinement import RefinedPath

    scene = _trefoil()
    (dom,) = domains(scene, find_crossings(scene))
    cell = 0.01
    line = _vertex_params(dom.comps[0], 0.0, dom.lengths[0])[5]  # a vertex line x1 = line
    x2 = np.linspace(2.0, 2.06, 13)  # six cells along the line, 0.3 cells to its left
    X = np.column_stack([np.full(13, line - 0.003), x2])
    X[[0, -1], 0] = line - 0.05  # the ends away from it
    (job,) = direct.starts._crease_starts(dom, RefinedPath(X, 1.0, 1.0, 0.0, 12), cell)
    np.testing.assert_allclose(job.route[1:-1, 0], line + 0.003)  # folded onto the right
    np.testing.assert_array_equal(job.route[[0, -1]], X[[0, -1]])
    np.testing.assert_array_equal(job.route[:, 1], x2)
    assert job.start_ground is None and job.end_ground is None
    Y = X.copy()
    Y[1:-1:2, 0] = line + 0.003  # across the line and back: a start on each side
    assert len(direct.starts._crease_starts(dom, RefinedPath(Y, 1.0, 1.0, 0.0, 12), cell)) == 2
    short = RefinedPath(X, 1.0, 1.0, 0.0, 12)
    assert direct.starts._crease_starts(dom, short, cell=0.05) == []  # 1.2 cells along it
    far = X.copy()
    far[1:-1, 0] = line - 0.02  # two cells away
    assert direct.starts._crease_starts(dom, RefinedPath(far, 1.0, 1.0, 0.0, 12), cell) == []

def _rose(reverse: bool = False, n: int = 43, c: float = 2.5, k: int = 4, t0: float = 0.013) -> direct.Scene:
    """The rose ``r = 1 + c cos kt`` at ``n`` vertices ``t = 2 pi j / n + t0`` (reference: the unit ``n``-gon at
    ``2 pi j / n``), its vertex list reversed or not."""
    t = 2 * np.pi * np.arange(n) / n
    z = (1 + c * np.cos(k * (t + t0))) * np.exp(1j * (t + t0))
    ref, dfm = np.column_stack([np.cos(t), np.sin(t)]), np.column_stack([z.real, z.imag])
    if reverse:
        ref, dfm = ref[::-1], dfm[::-1]
    return direct.Scene((direct.Component(ref, dfm, closed=True, name="R"),))


@pytest.mark.parametrize("rose", [dict(), dict(n=40, c=1.288, k=6, t0=0.1998)], ids=["k4", "k6"])
def test_a_rose_whose_curves_go_round_a_hill(rose):
    """Adversarial reviews (stops 32 and 33). The rose ``r = 1 + 2.5 cos 4t`` at 43 vertices (24 crossings near the
    origin) gave 37.673166 at the default ``tol`` with an estimate of 2.9e-3, no warning, 1.2e-4 (relative) above
    the ``upper_bound`` of its reversed listing (37.665620): a pair of curves between two crossing points went
    round a hill of the metric at 0.9736495, the other side 0.9694202 (``_alternative_starts``). The rose
    ``r = 1 + 1.288 cos 6t`` at 40 vertices gave 0.2764025 (estimate 1.8e-5), 4.2e-3 above the reversed listing's
    bound (0.2752401): a pair of curves round a narrow ring valley the long way, 0.0022930 against 0.0017095
    (``_chord_starts``). Both listings agree now."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", direct.ToleranceWarning)
        a = direct.penalty(_rose(**rose))
        b = direct.penalty(_rose(reverse=True, **rose))
    assert len(a.crossings) == len(b.crossings) == (24 if not rose else 54)
    assert a.value - a.error_estimate <= b.upper_bound
    assert b.value - b.error_estimate <= a.upper_bound
    assert abs(a.value - b.value) <= a.error_estimate + b.error_estimate


def _rose_and_ellipse(reverse: bool = False) -> direct.Scene:
    """The rose ``r = 1 + 1.989 cos 4t`` at 46 vertices ``t = 2 pi j / 46 + 0.1784`` (reference the unit 46-gon)
    crossing an ellipse of semi-axes 2.21 and 1.247 at 31 vertices (phase 0.216, turned by 1.568, centred at
    (0.385, -0.322); reference a unit 31-gon centred at (6, 0)), both vertex lists reversed or not."""
    t = 2 * np.pi * np.arange(46) / 46
    z = (1 + 1.989 * np.cos(4 * (t + 0.1784))) * np.exp(1j * (t + 0.1784))
    rose = (np.column_stack([np.cos(t), np.sin(t)]), np.column_stack([z.real, z.imag]))
    s = 2 * np.pi * np.arange(31) / 31
    w = (2.21 * np.cos(s + 0.216) + 1.247j * np.sin(s + 0.216)) * np.exp(1.568j) + (0.385 - 0.322j)
    ellipse = (np.column_stack([6 + np.cos(s), np.sin(s)]), np.column_stack([w.real, w.imag]))
    return direct.Scene(tuple(direct.Component(R[::-1] if reverse else R, D[::-1] if reverse else D, closed=True,
                                               name=name) for name, (R, D) in zip("AB", (rose, ellipse))))


@pytest.mark.slow
def test_a_rose_crossing_an_ellipse_beside_a_vertex_line():
    """An adversarial review (stop 33): the rose and ellipse of ``_rose_and_ellipse`` (a torus with crossings) gave
    70.835562 at the default ``tol`` (estimate 3.6e-3, no warning), 4.5e-5 (relative) above its reversed listing's
    bound (70.828847): a curve between crossing points of the two curves was 3.7729855 against 3.7692863, beside
    a vertex line (``_crease_starts``, on a torus since). Both listings agree now."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", direct.ToleranceWarning)
        a = direct.penalty(_rose_and_ellipse())
        b = direct.penalty(_rose_and_ellipse(reverse=True))
    assert a.value - a.error_estimate <= b.upper_bound
    assert b.value - b.error_estimate <= a.upper_bound
    assert abs(a.value - b.value) <= a.error_estimate + b.error_estimate


def test_chord_starts(monkeypatch):
    """``_chord_starts`` on the rose ``r = 1 + 1.288 cos 6t`` at 40 vertices, as ``penalty`` calls it: each start
    runs between the ends of its curve, at most 2 % longer and at least a fine cell away from it somewhere (the
    other side of a ring valley; a few of them here); none for a curve within half a cell of its chord."""
    import shapely

    from direct.refinement import polyline_lengths

    P = sys.modules["direct.penalty"]
    calls = []

    def recorded(domain, metric, keys, held, cell):
        out = chord_starts(domain, metric, keys, held, cell)
        calls.append((domain, metric, keys, dict(held), cell, out))
        return out

    chord_starts = P._chord_starts
    monkeypatch.setattr(P, "_chord_starts", recorded)
    direct.penalty(_rose(n=40, c=1.288, k=6, t0=0.1998))
    found = 0
    for domain, metric, keys, held, cell, out in calls:
        for k in keys:
            X = held[k].points
            chord = (X[-1] - X[0]) / np.hypot(*(X[-1] - X[0]))
            bulge = np.abs((X - X[0]) @ [-chord[1], chord[0]]).max()
            for job in out.get(k, []):
                found += 1
                assert bulge >= 0.5 * cell
                np.testing.assert_allclose(job.route[[0, -1]], X[[0, -1]], atol=1e-12)
                assert polyline_lengths(domain, metric, [job.route])[0] <= 1.02 * held[k].length
                assert shapely.hausdorff_distance(shapely.linestrings(X), shapely.linestrings(job.route)) >= cell
    assert found >= 2


def test_alternative_routes_go_the_other_way_round():
    """``route.alternatives`` of ``grid_distances`` on the rose of ``test_a_rose_whose_curves_go_round_a_hill``:
    between the two crossing points on either side of the hill it finds the route round the other side, from
    one point to the other, within the margin of the grid's length and at least 10 cells from the route
    (its coarse geodesic within 2 % of the route's); none with a margin of zero, or a plateau longer than the
    route."""
    from direct.crossings import find_crossings
    from direct.refinement import GeodesicJob, coarse_geodesics, polyline_lengths

    met = get_metric("G")
    scene = _rose()
    (dom,) = domains(scene, find_crossings(scene))
    graph = build_graph(dom, met, resolution=128, neighbours=16)
    T, route = grid_distances(graph)
    ng = dom.n_grounds
    plane = scene.components[0].phi(dom.points[:, 0])
    a, b = (ng + int(np.argmin(np.hypot(*(plane - q).T))) for q in ([-0.0375, 0.0748], [-0.0635, 0.0196]))
    assert dom.signs[a - ng] != dom.signs[b - ng]
    (alt,) = route.alternatives(a, b, 0.0775, 0.25, most=1)
    main = route(a, b)
    L = dom.lengths[0]
    for X in (main, alt):  # from a to b (modulo the circle)
        for end, p in ((X[0], dom.points[a - ng]), (X[-1], dom.points[b - ng])):
            assert np.abs((end - p + L / 2) % L - L / 2).max() < 1e-9
    assert polyline_lengths(dom, met, [alt])[0] <= 1.0775 * T[a, b]
    gap = np.abs((alt[:, None, :] - main[None, :, :] + L / 2) % L - L / 2).max(axis=2).min(axis=1).max()
    assert gap >= 10 * graph.cell.max()
    (_, c_main), (_, c_alt) = coarse_geodesics(dom, met, [GeodesicJob(main), GeodesicJob(alt)])
    assert abs(c_alt / c_main - 1.0) < 0.02
    assert route.alternatives(a, b, 0.0, 0.25) == []
    assert route.alternatives(a, b, 0.0775, 1.01) == []


def test_reflected_starts():
    """``_reflected_starts`` reflects a curve from a crossing point ``(x1, x2)`` to the diagonal across the line
    ``y1 + y2 = x1 + x2``, resampled to 16 segments: the same point, the end on the same ground, oriented as the
    curve; none for a curve between two points, whose reflection is more than 5 % longer, or which is its own
    reflection."""

    from direct.crossings import find_crossings
    from direct.refinement import RefinedPath, polyline_lengths

    met = get_metric("G")
    scene = _epitrochoid(0.486, first=7, reverse=True)
    (dom,) = domains(scene, find_crossings(scene))
    assert dom.kind == "annulus"
    ng = dom.n_grounds
    checked = 0
    for i, (x1, x2) in enumerate(dom.points):
        a = ng + i
        g = 0 if x2 >= x1 else 1  # the diagonal below the point (v = 0) or above it (v = S)
        m = 0.5 * (x1 + x2) + (0.0 if g == 0 else 0.5 * dom.lengths[0])
        for end in (m - 0.01, m + 0.01):
            Q = np.array([end, end + (0.0 if g == 0 else dom.lengths[0])])
            if (Q[1] - x2) * (x1 - Q[0]) < 0:
                continue
            X = np.array([[x1, x2], 0.5 * (np.array([x1, x2]) + Q) + [0.002, 0.001], Q])
            length = float(polyline_lengths(dom, met, [X])[0])
            for key, path in (((a, g), X), ((g, a), X[::-1])):
                held = RefinedPath(path, length, length, 0.0, 2)
                starts = direct.starts._reflected_starts(dom, met, key, held, ng)
                if not starts:
                    continue
                (job,) = starts
                checked += 1
                Y = job.route if key[0] == a else job.route[::-1]
                np.testing.assert_allclose(Y[0], [x1, x2])
                np.testing.assert_allclose(Y[-1, 0] + Y[-1, 1], 2 * (x1 + x2) - Q[0] - Q[1])
                assert abs((Y[-1, 1] - Y[-1, 0]) - (Q[1] - Q[0])) < 1e-12  # on the same ground
                assert len(Y) == 17  # 16 segments evenly along the reflection, reflected back onto the curve:
                Z = (x1 + x2) - Y[:, ::-1]
                t = np.clip(np.einsum("kij,ij->ki", Z[:, None, :] - X[None, :-1], np.diff(X, axis=0))
                            / (np.diff(X, axis=0) ** 2).sum(axis=1), 0.0, 1.0)
                gap = np.linalg.norm(X[None, :-1] + t[..., None] * np.diff(X, axis=0) - Z[:, None, :], axis=2)
                assert gap.min(axis=1).max() < 1e-12
                assert (job.start_ground, job.end_ground) == ((g, None) if key[0] == g else (None, g))
                assert float(polyline_lengths(dom, met, [job.route])[0]) <= 1.05 * length
                far = RefinedPath(path, length, length / 2, 0.0, 2)  # its reflection more than 5 % longer
                assert direct.starts._reflected_starts(dom, met, key, far, ng) == []
        # a curve along the antidiagonal is its own reflection (the mirror image of a symmetric loop's): none
        d = 0.0 if g == 0 else dom.lengths[0]
        S = np.array([[x1, x2], [(x1 + x2 - d) / 2, (x1 + x2 + d) / 2]])
        same = float(polyline_lengths(dom, met, [S])[0])
        assert direct.starts._reflected_starts(dom, met, (a, g), RefinedPath(S, same, same, 0.0, 1), ng) == []
    assert checked >= 4
    assert direct.starts._reflected_starts(dom, met, (ng, ng + 1), held, ng) == []  # point to point

def test_a_limacon_whose_curves_bulge_from_straight_by_half_a_percent():
    """A second review (stop 31): the limaçon ``a = 0.57`` at 15 vertices gave 0.0493788835 at ``tol=1e-5`` in 13 of
    its 30 listings, estimates at most 4e-11, no warning, 5.1e-5 (relative) above the ``upper_bound`` of the listing
    from vertex 10. With bent starts from curves straight within 1e-5 of their chord (a version of this stop), the
    listing from vertex 3 still gave 0.0493788825 at the default ``tol`` with an estimate of 2.5e-9: its curves were
    straight to 4.8e-6 of their chord, and its bent starts, replaced by their coarse geodesics, came back to them;
    the shorter curves bulge by half a percent. Now the bent starts are refined from
    the bent polylines: each listing's value, less its estimate, is below the least ``upper_bound`` of all."""
    listings = ({"roll": 3}, {"roll": 10}, {"reverse": True, "roll": 2})
    runs = [direct.penalty(_limacon(15, 0.57, **kw)) for kw in listings]
    upper = min(r.upper_bound for r in runs)
    for r in runs:
        assert r.value - r.error_estimate <= upper <= r.upper_bound


@pytest.mark.parametrize(("a", "n", "bound"), [(0.8, 12, 0.00076838760), (0.3, 16, 0.42840042450)])
def test_a_symmetric_limacon_leaves_its_straight_curves(a, n, bound):
    """The limaçons ``r = a + cos t`` sampled evenly at ``n`` vertices (``validation/symmetric.py``): on a242e98 (on
    an AMD EPYC) a = 0.8 at 12 vertices gave 0.00076868540 with an estimate of 4e-17 and a = 0.3 at 16 vertices
    0.4284049085 with 5e-15, no warning, 3.9e-4 and 1.1e-5 (relative) above ``bound``, the exact length of
    curves found at stop 31 (by the starts beside the corners, a tent of three segments then, and from bent
    starts): each value, less its estimate, must be at most that proven upper bound of ``J``."""
    res = direct.penalty(_limacon(n, a))
    assert len(res.crossings) == 1
    assert res.value - res.error_estimate <= bound


@pytest.mark.parametrize(("n", "a", "others"), [
    (12, 0.43, [{"reverse": True, "angle": 1.0}, {"reverse": True, "roll": 4}]),
    (17, 0.928, [{"reverse": True, "angle": 1.0}, {"roll": 1, "angle": 2.5}]),
])
def test_symmetric_limacons_at_tol_1e5_in_every_listing(n, a, others):
    """Found by an adversarial review (stop 31), at ``tol=1e-5`` as listed (from ``t = 0``), no warning: ``a = 0.43``
    at 12 vertices gave 0.14455880 (estimate 6e-13), 3.8e-3 above the ``upper_bound`` of the reversed listing: its
    curves ran straight along (1, -1) from the crossing point to the diagonal, a local geodesic on the fixed line of
    the mirror's isometry, the shortest ones bulging 7 % of their chord beside it (now refined again from bent
    starts, ``_bent_starts``). ``a = 0.928`` at 17 vertices gave 1.3828e-5 (estimate 2e-17), 18 % above: its inner
    loop is tiny, the curve one grid cell long, and the grid could not rank the ways to the diagonal (now straight
    starts along the axes and (1, -1), ``_straight_starts``). Every listing must be within its estimate of the
    least ``upper_bound`` of all, the given one without a warning (the reversed listing of the first finds the
    bulging curves from its grid and warns, its estimate 3.8e-3 relative, as before)."""
    runs = []
    for k, kw in enumerate([{}] + others):
        with warnings.catch_warnings():
            warnings.simplefilter("error" if k == 0 else "ignore", direct.ToleranceWarning)
            runs.append(direct.penalty(_limacon(n, a, **kw), tol=1e-5))
    upper = min(r.upper_bound for r in runs)
    for r in runs:
        assert len(r.crossings) == 1
        assert r.value - r.error_estimate <= upper <= r.upper_bound


def test_a_random_closed_polygon_agrees_with_the_finer_stencil():
    """Seed 52 of ``validation/random_closed.py`` (a 10-gon deformed at random radii and angles, three
    self-crossings): with its 16 moves taken in (s, v), the annulus grid gave 0.0449921 in every listing, at
    ``tol=1e-5`` with an estimate of 2.7e-7, where 32 neighbours gave 0.0441923: 1.8 % too high, silently.
    With the moves of the parameters both stencils must agree within their estimates."""
    rng = np.random.default_rng(52)
    n = int(rng.integers(6, 12))
    t = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    radius = 1.0 + 0.3 * rng.standard_normal(n)
    angle = t + rng.uniform(-1.2, 1.2, n)
    sc = direct.Scene((direct.Component(np.column_stack([np.cos(t), np.sin(t)]),
                                        np.column_stack([radius * np.cos(angle), radius * np.sin(angle)]),
                                        closed=True, name="c"),))
    a, _ = _stencils_agree(sc, (16, 32))
    assert len(a.crossings) == 3


def _unevenly_referenced(d: np.ndarray, speeds) -> np.ndarray:
    """A unit circle polygon as the reference of the closed polyline ``d``, its segments' reference lengths
    proportional to their deformed lengths over ``speeds`` (the speeds ``|phi'|`` of the segments, up to a factor)."""
    w = np.linalg.norm(np.roll(d, -1, 0) - d, axis=1) / np.asarray(speeds, dtype=float)
    th = np.r_[0.0, np.cumsum(w)[:-1]] / w.sum() * 2 * np.pi
    return np.column_stack([np.cos(th), np.sin(th)])


@pytest.mark.parametrize("shape", ["limacon", "eight"])
def test_a_closed_curve_in_uneven_reference_speeds(shape):
    """``J^G`` ignores the reference (Prop. 18), but the annulus grid is uniform in the reference arclength, where
    unequal speeds squeeze the stencil's directions. Found by an adversarial review (stop 30): a limaçon at 24
    vertices whose reference gives its two halves speeds 1 and 12 came out 3.1e-3 above the evenly referenced one
    with an estimate of 8.1e-7 (right before the annulus grid took the moves of the parameters, by luck); a figure
    eight at 20 vertices, speeds alternating 1 and 12, listed reversed, 4.8e-4 above with 4.7e-5 (before too).
    Closed components now go into their deformed arclength whenever their speeds differ: each run within its
    estimate of the other's upper bound."""
    n = {"limacon": 24, "eight": 20}[shape]
    t = 2 * np.pi * np.arange(n) / n + {"limacon": 0.1, "eight": 0.07}[shape]
    if shape == "limacon":
        r = 0.7 + np.cos(t)
        d = np.column_stack([r * np.cos(t), r * np.sin(t)])
        uneven = _unevenly_referenced(d, np.r_[np.ones(12), 12 * np.ones(12)])
    else:
        d = np.column_stack([np.sin(t), np.sin(t) * np.cos(t)])
        uneven = _unevenly_referenced(d, np.resize([1.0, 12.0], n))[::-1].copy()
        d = d[::-1].copy()
    even = np.column_stack([np.cos(2 * np.pi * np.arange(n) / n), np.sin(2 * np.pi * np.arange(n) / n)])
    a, b = (direct.penalty(direct.Scene((direct.Component(ref, d, closed=True, name="c"),))) for ref in (uneven, even))
    assert a.settings.get("deformed_arclength") == b.settings.get("deformed_arclength") == ["c"]
    assert a.value - a.error_estimate <= b.upper_bound
    assert b.value - b.error_estimate <= a.upper_bound


def test_a_curve_to_a_side_ends_in_the_next_strip():
    """An adversarial review (stop 34): an epitrochoid ``T`` crossed by two intervals (5 crossings), with the
    saturating metric ``h(s) = 1 - exp(-s)``, gave 11.121743 (estimate 2.3e-4, no warning) listed as ``L1, L0, T``
    with ``T`` from its 11th vertex, 5.1e-4 (relative) above the ``upper_bound`` of the listing as given
    (11.116035): a curve from a crossing point of ``L0`` and ``T`` to the end of ``L0`` ended in the strip of its
    crossing point (2.2473042), where in the other listings it climbs into the next strip between the vertex lines
    of ``T`` (2.2444451; ``_strip_starts``).  Both listings agree now."""
    import os

    from direct.metric import GFamily

    given = direct.load_scene(os.path.join(os.path.dirname(__file__), "data", "epitrochoid_and_two_intervals.json"))
    T, L0, L1 = given.components
    permuted = direct.Scene((L1, L0, direct.Component(np.roll(T.reference, -10, axis=0),
                                                      np.roll(T.deformed, -10, axis=0), closed=True, name="T")))
    metric = GFamily(h=lambda s: 1.0 - np.exp(-s), label="1-exp(-s)")
    with warnings.catch_warnings():
        warnings.simplefilter("error", direct.ToleranceWarning)
        a = direct.penalty(given, metric=metric)
        b = direct.penalty(permuted, metric=metric)
    assert len(a.crossings) == len(b.crossings) == 5
    assert a.value - a.error_estimate <= b.upper_bound
    assert b.value - b.error_estimate <= a.upper_bound
    assert abs(a.value - b.value) <= a.error_estimate + b.error_estimate


@pytest.mark.parametrize("power", [2.0, 4.5])
def test_a_curve_to_the_diagonal_tries_the_other_side_of_its_own_strip(power):
    """An adversarial review (stop 37): a jittered limaçon of 13 vertices (one self-crossing on its symmetry axis),
    metric ``g``, at ``tol=1e-5``. Its curve from the crossing point to the diagonal ends on the short edge across
    the axis, where the length has two nearly tied minima: at 0.30 and 0.70 of the edge (``p = 2``), or at its two
    vertex lines (``p = 4.5``). Listed as given (``p = 2``) or from its 7th vertex (``p = 4.5``) the refinement
    kept the longer, 1.4e-3 and 7.2e-4 (relative) above the other listing's ``upper_bound``, 171 and 139 times
    its estimate, without a warning. ``_strip_starts`` now also moves the end to its mirror position in its own
    strip, and keeps the moves beside a vertex line up to ``_STRIP_NEAR ** order`` times as long as they stand (a
    distortion of ``|r|`` by 1.6: the metric ``|r|^(2p)`` is steep near the diagonal, and the start that fixes
    ``p = 3`` stood 14 times as long). ``validation/limacon_listings.py`` runs all 26 listings."""
    import os

    given = direct.load_scene(os.path.join(os.path.dirname(__file__), "data", "limacon_13_jittered.json"))
    (c,) = given.components
    rolled = direct.Scene((direct.Component(np.roll(c.reference, 6, axis=0), np.roll(c.deformed, 6, axis=0),
                                            closed=True, name="limacon"),))
    with warnings.catch_warnings():
        # the contract is the bounds below; a warning (an estimate above tol) would not break it
        warnings.simplefilter("ignore", direct.ToleranceWarning)
        a, b = (direct.penalty(s, metric="g", power=power, tol=1e-5) for s in (given, rolled))
    assert len(a.crossings) == len(b.crossings) == 1
    assert a.value - a.error_estimate <= b.upper_bound
    assert b.value - b.error_estimate <= a.upper_bound
    # the same local geodesic in both listings: 1.1e-8 (relative) apart with OpenBLAS's AVX-512 kernels, within
    # 1e-9 with its Haswell kernels (rounding); the two minima of the bug lay 1.4e-3 and 7.2e-4 apart
    assert a.value == pytest.approx(b.value, rel=1e-6)


@pytest.mark.slow
def test_a_closed_geodesic_whose_refraction_vertex_must_slide_far():
    """An adversarial review of 0a6d674: a random 8-gon nested in a 16-gon, no crossing, metric ``g`` with ``p =
    2`` (``nested_8_16_g`` of ``validation/listings_scenes.json``). Listed from the middle of both vertex lists it
    gave 4.4897585 at the default ``tol`` until stop 37 (relative estimate 6.0e-4, no warning), 3.4e-3 (relative)
    above the other listings' least ``upper_bound`` once its estimate is taken off: its closed curve met a vertex
    line 0.25 from where the shortest does, and
    Newton, moving the vertices along the normals, could slide that refraction vertex by about a segment per
    round; the rounds' gains dropped and the level stopped (``validation/rugged_closed_g.py``). The polish of a
    closed curve now moves its vertices in both coordinates (``_settle``)."""
    import os

    given = direct.load_scene(os.path.join(os.path.dirname(__file__), "data", "nested_8_16_g.json"))
    rolled = direct.Scene(tuple(direct.Component(np.roll(c.reference, -(len(c.reference) // 2), axis=0),
                                                 np.roll(c.deformed, -(len(c.deformed) // 2), axis=0), closed=True,
                                                 name=c.name) for c in given.components))
    with warnings.catch_warnings():
        warnings.simplefilter("error", direct.ToleranceWarning)
        a, b = (direct.penalty(s, metric="g", power=2) for s in (given, rolled))
    assert len(a.crossings) == len(b.crossings) == 0
    assert a.value - a.error_estimate <= b.upper_bound
    assert b.value - b.error_estimate <= a.upper_bound


def test_closed_geodesics_the_grid_ranks_apart_are_ranked_by_their_coarse_geodesics():
    """An adversarial review (stop 38): a 7-gon nested in a 17-gon, no crossing, unevenly spaced references, metric
    ``g`` with ``p = 2``. The torus has two closed geodesics of the class picked, 2.14194 and 2.14852, which part
    by up to 0.9 (in ``x2``) over nearly half the period and meet near the seam; the grid, not isotropic for
    ``g``, weighs them 2.8 % and 1.3 % above (4.0 % and 1.2 % listed reversed), so listed with both vertex lists
    reversed, or rolled by one, no closed grid curve through a point of the seam led to the shorter, and the
    value came out 4.29706 (relative estimate 4.2e-4, no warning), 3.1e-3 above the least ``upper_bound`` of
    the other listings. Where the grid is not isotropic
    (``g``), the closed grid curves are now searched through points of four lines across the period and ranked
    by their coarse geodesics (``_ranked_loops``)."""
    import os

    given = direct.load_scene(os.path.join(os.path.dirname(__file__), "data", "nested_uneven4_g.json"))
    reversed_ = direct.Scene(tuple(direct.Component(c.reference[::-1], c.deformed[::-1], closed=True, name=c.name)
                                   for c in given.components))
    rolled = direct.Scene(tuple(direct.Component(np.roll(c.reference, 1, axis=0), np.roll(c.deformed, 1, axis=0),
                                                 closed=True, name=c.name) for c in given.components))
    with warnings.catch_warnings():
        warnings.simplefilter("error", direct.ToleranceWarning)
        runs = [direct.penalty(s, metric="g", power=2) for s in (given, reversed_, rolled)]
    for r in runs:
        assert len(r.crossings) == 0
        assert r.value - r.error_estimate <= min(s.upper_bound for s in runs if s is not r)


def test_best_of_closed_starts_by_length_plus_estimate():
    """``_best_of_starts(..., by_bound=True)`` (a torus's closed curves) keeps the least ``length + error_estimate``
    and widens its estimate by the farthest start within the family window, below it as well as above; without it
    the least length is kept and only the starts above count."""
    from direct.refinement import RefinedPath

    pts = np.zeros((2, 2))
    good = RefinedPath(pts, 3.0759775, 3.0759952, 5.3e-5, 148)
    near = RefinedPath(pts, 3.0759777, 3.0759987, 6.3e-5, 144)
    rough = RefinedPath(pts, 3.0751729, 3.0760114, 2.5e-3, 130)
    far = RefinedPath(pts, 3.2, 3.2, 1e-5, 148)
    best = direct.starts._best_of_starts([rough, near, good, far], 5e-4, by_bound=True)
    assert (best.length, best.upper, best.segments) == (good.length, good.upper, good.segments)
    assert best.error_estimate == pytest.approx(good.error_estimate + (good.length - rough.length), rel=1e-12)
    plain = direct.starts._best_of_starts([rough, near, good, far], 5e-4)
    assert plain.length == rough.length
    assert plain.error_estimate == pytest.approx(rough.error_estimate + (near.length - rough.length), rel=1e-12)


def _polygon(n: int, radius: float = 1.0, centre=(0.0, 0.0), phase: float = 0.0) -> np.ndarray:
    t = phase + 2 * np.pi * np.arange(n) / n
    return np.column_stack([centre[0] + radius * np.cos(t), centre[1] + radius * np.sin(t)])


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="address-space limit (resource.RLIMIT_AS): Linux")
@pytest.mark.parametrize("n_big, n_small, near_vertex", [(32, 12, True), (16, 8, False)])
def test_a_tiny_polygon_crossing_a_large_one_scales_as_its_size_cubed(n_big, n_small, near_vertex):
    """A polygon ``s`` across crossing an edge of a unit polygon: ``J^G`` is local, so ``J / s^3`` stays put.

    Its torus piece is 1e8 times longer one way than the other.  At ``s = 1e-8`` and ``1e-9`` the polish's
    box (10 times the longer side) spanned 1e9 periods of the small circle, and the folded and corner starts
    looked for vertex lines 1.0 around the curve (3e8 periods): numpy asked for 15 and 19.5 GiB and the
    process was killed (a review at stop 48).  Run with 4 GB of address space beyond what the process uses,
    so that a relapse fails here instead of taking the machine down.
    """
    import resource

    A = _polygon(n_big)
    a, b = A[0], A[1]
    mid = 0.5 * (a + b)
    out, along = mid / np.linalg.norm(mid), (b - a) / np.linalg.norm(b - a)

    def scene(s):
        c = a + 2 * s * along - 0.3 * s * out if near_vertex else mid - 0.3 * s * out
        return direct.Scene((direct.Component(A, A, closed=True, name="A"),
                             direct.Component(_polygon(n_small, 0.5), _polygon(n_small, s, c, 0.1), closed=True,
                                              name="B")))

    with open("/proc/self/statm") as fh:  # the address space in use now, in pages
        in_use = int(fh.read().split()[0]) * resource.getpagesize()
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    limit = in_use + 4 * 2**30
    resource.setrlimit(resource.RLIMIT_AS, (limit if hard == resource.RLIM_INFINITY else min(limit, hard), hard))
    try:
        results = {s: direct.penalty(scene(s)) for s in (1e-6, 1e-8, 1e-9)}
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
    ref = results[1e-6]
    for s, r in results.items():
        assert len(r.crossings) == 2 and r.value > 0
        assert abs(r.value / s**3 - ref.value / 1e-18) <= r.error_estimate / s**3 + ref.error_estimate / 1e-18


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="a known limitation (README, Known limitations; docs/record.md, stop 50): "
                                       "the refinement settles 1.5e-4 to 4.8e-4 above J on this curve, with a warning")
def test_a_spiral_across_a_wobbly_circle_against_an_independent_solver():
    """An interval spiralling 1.3 turns inside a closed curve whose radius wobbles by 3 % (160 and 140 vertices,
    one crossing; ``spiral_out_far`` of ``validation/independent_cylinder.py``, a review at stop 50): the winding
    numbers send the curve of the crossing to the far end of the spiral, once round the cylinder, along a narrow
    valley of the metric. The independent solver (free vertices, 16 to 512 segments, Richardson) gives
    0.821836004484 +- 4.1e-8 and a family of exact length 0.8218365570, below every listing's value: 0.8221216
    (estimate 3.0e-4), 0.8222313 and 0.8219553, each warned, each estimate covering its error (0.94, 0.45 and
    0.90 of it). Newton along the normals stops at a point that is stationary for its moves but not a minimum:
    from ``direct``'s curve, L-BFGS-B with the vertices free goes on down to 0.410929 (half of ``J``, the piece
    ``I x C``) after 30,000 iterations. Strict: it fails once the refinement meets ``tol`` here."""
    import os

    scene = direct.load_scene(os.path.join(os.path.dirname(__file__), "data", "spiral_across_a_wobbly_circle.json"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", direct.ToleranceWarning)
        res = direct.penalty(scene, tol=1e-5)
    reference = 0.821836004484
    assert len(res.crossings) == 1
    assert abs(res.value - reference) <= 1e-5 * reference
