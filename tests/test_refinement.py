"""The batched refinement (direct.refinement.refine_many) against one curve at a time."""

import numpy as np
import pytest
from conftest import random_crossing_scene

import direct
from direct.crossings import find_crossings
from direct.geodesics import grid_distances
from direct.grid import build_graph
from direct.metric import get_metric
from direct.penalty import domains
from direct.refinement import GeodesicJob, refine, refine_many


def _jobs(scene, resolution=64):
    dom = domains(scene, find_crossings(scene))[0]
    met = get_metric("G")
    graph = build_graph(dom, met, resolution, 16)
    T, route = grid_distances(graph)
    n = len(dom.points)
    jobs = [GeodesicJob(route(1 + a, 0), end_ground=0) for a in range(n)]
    pairs = [(a, b) for a in range(n) for b in range(n) if a != b and np.isfinite(T[1 + a, 1 + b])]
    jobs += [GeodesicJob(route(1 + a, 1 + b)) for a, b in pairs]
    return dom, met, jobs


@pytest.mark.parametrize("seed", [3, 11])
def test_stacked_curves_refine_as_if_alone(seed):
    """Stacking curves into one Newton system changes nothing but the speed: each curve keeps its own damping,
    steps and line search, so its length is that of refining it alone (to rounding of the sums)."""
    dom, met, jobs = _jobs(random_crossing_scene(seed, min_crossings=2, max_crossings=4))
    assert len(jobs) >= 3
    together = refine_many(dom, met, jobs, tol=1e-4)
    for job, rp in zip(jobs, together):
        alone = refine(dom, met, job.route, end_ground=job.end_ground, tol=1e-4)
        assert rp.length == pytest.approx(alone.length, rel=1e-9, abs=1e-14)
        assert rp.segments == alone.segments
        # the polyline is a real curve between the same ends: its exact length bounds the extrapolated one above
        assert rp.upper >= rp.length - rp.error_estimate


def test_refined_lengths_beat_the_grid_and_converge():
    """Refined curves are shorter than their grid routes (the grid overestimates) and tighten with tol."""
    scene = direct.scenes.cross(0.7, 0.4, 0.5, 0.9, angle=1.1)
    dom, met, jobs = _jobs(scene)
    from direct.metric import segment_lengths

    grid_len = [float(segment_lengths(met, dom.comps, j.route[:-1], j.route[1:]).sum()) for j in jobs]
    loose = refine_many(dom, met, jobs, tol=1e-3)
    tight = refine_many(dom, met, jobs, tol=1e-7)
    for g, a, b in zip(grid_len, loose, tight):
        assert b.upper < g
        assert abs(a.length - b.length) <= a.error_estimate + b.error_estimate
        assert b.error_estimate <= a.error_estimate


@pytest.mark.parametrize("angle", [0.6, 1.1, 2.0])
def test_a_route_that_folds_back_refines_to_the_straight_routes_geodesic(angle):
    """On a coarse grid a route may leave a crossing point towards a node behind it and come back (the
    metric nearly vanishes at the point).  Moves across the curve cannot pull such a fold out; the routes
    are unfolded first, so the fold changes nothing (it was measured at 0.4 % on a 100-crossing zigzag)."""
    scene = direct.scenes.cross(0.8, 0.6, 0.7, 0.9, angle=angle)
    dom = domains(scene, find_crossings(scene))[0]
    met = get_metric("G")
    p = dom.points[0]
    straight = GeodesicJob(np.array([p, [p[0], 0.0]]), end_ground=0)
    # out towards a point behind the crossing (away from the side it ends on), then back past the start
    behind = p + np.array([0.15, 0.25])
    folded = GeodesicJob(np.array([p, behind, p + [0.02, -0.05], [p[0], 0.0]]), end_ground=0)
    a, b = refine_many(dom, met, [straight, folded], tol=1e-6)
    assert b.length == pytest.approx(a.length, rel=1e-6)
