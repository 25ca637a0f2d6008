r"""Other starts: the guards of the refinement against local geodesics (section 5.1.1).

The refinement (:mod:`direct.refinement`) settles in the local geodesic that
its start leads to, and the grid that supplies the starts ranks routes within
its stencil's bias (``shared/NUMERICS.md``): a route can lead to a longer
local geodesic than another route of the same entry of program (34), or the
refinement can stall where the length has kinks (the vertex lines of the
polygons, the corners of the cells).  So the chosen curves of
:func:`direct.penalty.penalty` are refined again from other starts, and
each entry keeps the shortest curve found (:func:`_best_of_starts`, its
estimate widened by the spread of the starts that settle in one family):

* around a circle, starts shifted along it (:func:`_family_shifts`,
  :func:`_more_starts`), closed curves of a torus ranked by their coarse
  geodesics (:func:`_ranked_loops`), and the mirror image of each curve of a
  circle with itself (:func:`_mirror_pairs`);
* curves held at corners of the cells, left from beside them
  (:func:`_corner_starts`, :func:`_leave_corners`), and straight ones from
  bent starts (:func:`_bent_starts`) or, when only a few cells long, straight
  starts to their ground (:func:`_straight_starts`);
* curves to the diagonal reflected across their point's antidiagonal
  (:func:`_reflected_starts`) or with their end slid towards a shallow point
  (:func:`_slid_ends`);
* curves between two crossing points along other grid routes
  (:func:`_alternative_starts`) or reflected across their chords
  (:func:`_chord_starts`);
* curves to a side with their end moved into the neighbouring strips between
  vertex lines (:func:`_strip_starts`); on a torus, a chosen curve moved onto
  the ends of its competitors (:func:`_transplanted_starts`);
* stretches along a vertex line folded onto either side of it
  (:func:`_crease_starts`).

Which of these run, and when, is decided in :func:`direct.penalty._solve_domain`;
the constants below are the thresholds, each with the measurement behind it.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import shapely

from .grid import Domain
from .metric import Metric, _vertex_params
from .refinement import (
    GeodesicJob,
    RefinedPath,
    _project,
    _resample,
    coarse_geodesics,
    polyline_lengths,
    refine_many,
)

#: starts of a curve with both ends free around a circle, shifted by these fractions of an edge (and unshifted),
#: both ways round (see _family_shifts)
_FAMILY_SHIFTS = (-0.61, -0.29, 0.29, 0.61)

#: a curve from a crossing point to the diagonal is refined again with its end slid to another crossing point whose
#: grid cost to the diagonal is below this fraction of the curve's (see _slid_ends)
_SHALLOW = 0.01
#: ... when that point lies within this fraction of the curve's chord along the diagonal from its end
_SLIDE_REACH = 0.5

#: a vertex of a refined curve within this fraction of its longer segment from a vertex line of both components sits
#: on a corner of the cells, where the refinement can pin it (see _corner_starts)
_ON_CORNER = 0.01
#: corner starts that settle within this (relative) of the shortest curve widen its estimate by their spread
_CORNER_FAMILY = 1e-4
#: the starts beside a corner move the corner vertex across the curve by 0.3 of its longer segment, and the
#: vertices within this many of those segments (along the curve) a tent's share of that
_CORNER_REACH = 1.5
#: a refined open curve within this fraction of its chord from the chord counts as straight (see _bent_starts) ...
_STRAIGHT = 1e-5
#: a chosen curve from a crossing point to the boundary whose chord is at most this many fine cells gets straight starts
_SHORT = 4.0
#: ... and along (1, -1) within this fraction of its chord ...
_ANTIDIAGONAL = 1e-3
#: ... and is refined again from starts bent across the chord by these fractions of its length, to either side
_BEND = (0.01, 0.1)
#: segments of the bent starts (refined from there, not from their coarse geodesics)
_BENT_SEGMENTS = 16
#: a chosen curve to the diagonal is refined again from its reflection when that is at most this fraction longer
#: (see _reflected_starts)
_REFLECTED_WITHIN = 0.05
#: ... and not within this fraction of it (the mirror image of a curve of a symmetric loop) ...
_REFLECTED_SAME = 1e-9
#: ... evenly resampled to this many segments
_REFLECTED_SEGMENTS = 16
#: a stretch of a chosen curve within this many fine cells of a vertex line, and running at least this many along it,
#: gets starts folded onto each side of the line (see _crease_starts)
_CREASE_BAND = 1.0
_CREASE_EXTENT = 2.0
#: a chosen curve between two crossing points is refined again along other grid routes between them whose plateau
#: (see _alternative_starts) is at least this fraction of its grid length ...
_ALTERNATIVE_SHARE = 0.25
#: ... at most this many, the cheapest ...
_ALTERNATIVE_MOST = 2
#: ... when their coarse geodesics are at most this fraction longer than the curve (and for _chord_starts)
_ALTERNATIVE_COARSE = 0.02
#: a chosen curve between two crossing points that strays at least this many fine cells from its chord is refined
#: again from its reflection across the chord ...
_CHORD_BULGE = 0.5
#: ... when the coarse geodesic from there lies this many fine cells from it somewhere (see _chord_starts)
_CHORD_AWAY = 1.0
#: a chosen curve to a side of the domain is refined again with its end in the middle of this many strips (between
#: vertex lines) on either side of its own (see _strip_starts)
_STRIP_REACH = 2
#: ... an end within this fraction of the narrower strip beside it from a vertex line is at that line
_STRIP_SNAP = 1e-3
#: ... and its starts beside that line (and the mirror start in its own strip, _OWN_STRIP) go on when they are at most
#: this factor to the power of the metric's order (at least 1) times as long as the curve as they stand: a distortion
#: of |r| by at most that factor, whatever the power (2.56 for G, 6.6 for g with p = 2, 17 with p = 3). The stop-36
#: review's curl (G) stood 1.02 and 1.04 times as long; the stop-37 review's limacon with g, where |r|^(2p) is steep
#: near the diagonal, 1.5 (p = 2) and 14 (p = 3); on interval seeds 183 and 263 of validation/default_tol.py such
#: starts were 2.5 to 1e9 times as long, and with no limit at all their coarse geodesics made the 175 scenes 1.23
#: times slower at tol=1e-3 (20 times for every metric: about 1.15 times, validation/same_values.py). No cap: at g with
#: p = 4.5 the limit is 69 (38 interval scenes at tol=1e-3: 21 coarse-geodesic starts instead of 1, 0.6 s of 29.8 s).
#: A metric without an order (a GFamily of another h, euclid) gets 1.6 itself; the starts in the farther strips keep
#: the 2 % limit of _ALTERNATIVE_COARSE (with g they stood 5.5 to 72 times as long along the limacon's diagonal: never
#: kept)
_STRIP_NEAR = 1.6
#: a chosen curve whose end lies at least half this fraction of its strip from the strip's middle also gets a start
#: with its end at the mirror position in the strip (see _strip_starts)
_OWN_STRIP = 0.25
#: on a torus, an entry not chosen whose curve is at most this fraction longer than a chosen curve of its class is
#: refined again from the chosen curve moved onto its ends (see _transplanted_starts)
_TRANSPLANT = 0.01
#: ... and whose ends lie within this fraction of the chosen curve's length (in the parameters) from its ends
_TRANSPLANT_REACH = 0.25


def _family_shifts(domain: Domain) -> list[np.ndarray]:
    """Shifts (parameters) along the circle of a periodic domain: the other starts of a curve with free ends.

    Rotating a curve whose ends are both free along the circle (the ``s`` axis)
    maps it to a curve of nearly the same length: exactly the same on a
    regular polygon rotated by a whole number of edges.  The refinement then
    faces a family of nearly tied geodesics, and a route the grid laid on a
    symmetry line of the polygon (its cells aligned with the vertices) is a
    critical point that doubling the segments does not move, with an estimate
    at rounding level.  Starts shifted by fractions of an edge (0.29 and 0.61:
    not symmetric about a half edge) leave those lines.  The shifts back
    (-0.29 and -0.61, that is 0.71 and 0.39 of an edge) mirror them about
    the half edge: on a polygon symmetric about it they repeat the forward
    starts, and are there for the curves that no symmetry ties (below).

    The vertex lines also make the length ripple along the family, with a
    local minimum about every edge, and the grid's stencil bias (a few per
    cent) can rank two neighbouring minima either way.  So the starts go
    both ways round: 0.61 of an edge reaches past the midpoint to the
    neighbouring minimum on either side.  With forward shifts only, a
    24-gon with an interval moved inside it (no crossing, one curve across
    the cylinder) settled 1.2e-3 above ``J`` with an estimate of 2.1e-7, at
    every ``tol``: its neighbouring minimum lay 0.9 of an edge back (an
    adversarial review; ``tests/test_circles.py``).
    """
    axis = domain.basis[:, 0]
    comp = domain.comps[int(np.flatnonzero(axis)[0])]
    edge = comp.length / comp.n_segments
    return [f * edge * axis for f in _FAMILY_SHIFTS]


def _ranked_loops(domain: Domain, metric: Metric, found: dict, most: int) -> dict:
    """The grid's closed curves of each class ranked by their coarse geodesics, at most ``most`` kept.

    ``found`` is :func:`direct.geodesics.closed_curve_distances`'s output
    (each class with its opposite, the same curves run backwards, in the same
    order).  Where a class has more than ``most`` curves, each is straightened
    at a coarse scale (:func:`direct.refinement.coarse_geodesics`, once for a
    class and its opposite) and the ``most`` shortest are kept, in that
    order; otherwise the grid's order stays.
    """
    out: dict = {}
    for c, cands in found.items():
        if c in out:
            continue
        order = list(range(len(cands)))
        if len(cands) > most:
            coarse = coarse_geodesics(domain, metric, [GeodesicJob(np.asarray(p, dtype=float), closed=True)
                                                       for _, p in cands])
            order = np.argsort([L for _, L in coarse], kind="stable")[:most].tolist()
        out[c] = [cands[i] for i in order]
        opposite = (-c[0], -c[1])
        if opposite in found:
            out[opposite] = [found[opposite][i] for i in order]
    return out


def _more_starts(domain: Domain, metric: Metric, starts: dict, cache: dict, tol: float, atol: float,
                 family: float = 0.01, by_bound: bool = False) -> dict:
    """Refine entries again from more starts, all in one batch: ``{key: RefinedPath}`` (see :func:`_best_of_starts`).

    ``starts`` maps each entry to its further jobs; ``cache`` holds its first refined curve.
    """
    starts = {k: jobs for k, jobs in starts.items() if jobs}
    refined = iter(refine_many(domain, metric, [j for jobs in starts.values() for j in jobs], tol=tol, atol=atol)
                   if starts else [])
    return {k: _best_of_starts([cache[k]] + [next(refined) for _ in jobs], family, by_bound)
            for k, jobs in starts.items()}


def _restarted(domain: Domain, metric: Metric, starts: dict, held: dict, tol: float, atol: float,
               spread_if_held: bool = True, clearly: bool = False) -> dict:
    """Refine further starts of chosen curves in one batch, the changed entries: ``{key: RefinedPath}``.

    The starts beside corners (:func:`_corner_starts`), bent
    (:func:`_bent_starts`), straight (:func:`_straight_starts`),
    reflected (:func:`_reflected_starts`), along other grid routes
    (:func:`_alternative_starts`), reflected across the chord
    (:func:`_chord_starts`) or folded across a crease
    (:func:`_crease_starts`).  With
    ``spread_if_held=False`` their spread counts only where one of them
    beats the curve held.  With ``clearly=True`` a start replaces the
    curve only where it beats it by more than the curve's estimate (the
    folded starts of :func:`_crease_starts`: on ``fig10`` at ``tol=1e-5``
    one settled 5.6e-11 (relative) lower, with an estimate of 2.5e-5 where
    the curve had 3.9e-6, and the value warned).

    The shortest of the curve held and its starts is kept, with the larger
    of its own estimate and the held curve's: a start that settles in the
    same geodesic, a little shorter, must not drop what the held estimate
    covers (the spread of a family of closed curves, on ``nested`` listed
    from another vertex: 7.2e-5 above ``J``, 9.7e-6 relative, with an
    estimate of 8.0e-6 when the start's own replaced it; an adversarial
    review).  Plus the spread of the starts that settle within
    ``_CORNER_FAMILY`` (relative) of the shortest: local geodesics that
    close, each held at its own corners, leave a shorter one possible (the
    limaçon at 32 vertices listed from the middle of its vertex list: both
    mirror curves held at the same corner, 4.1e-6 relative above ``J`` at
    ``tol=1e-5`` with an estimate of 2.6e-7, its starts 1.7e-5 above it;
    docs/record.md, *Known limitations*).  A window of ten tolerances made the two
    overlapping polygons of ``test_a_curve_held_beside_a_corner_of_the_cells``
    warn at the default ``tol`` (their starts 1.3e-3 apart, in other
    geodesics), though their value is right.  On the random interval scenes
    of ``validation/default_tol.py`` (seeds 100 to 299) at ``tol=1e-3`` it
    widened 69 of 175 estimates, none beyond ``tol`` (seed 187 the most,
    4.7e-4 to 5.1e-4 relative); at ``tol=1e-5`` (seeds 100 to 149) 11 of
    47, seed 118 from 8.0e-6 to 1.0e-5 (a warning).  A start is refined
    only until it lies clearly above ``(1 + _CORNER_FAMILY)`` times the
    curve held (``refine_many``'s ``above``), beyond which it counts for
    nothing here: the far bent starts of a nodal loop (stop 49).
    """
    starts = {k: jobs for k, jobs in starts.items() if jobs}
    if not starts:
        return {}
    # a start that ends more than _CORNER_FAMILY above the curve it checks counts for nothing below: refined only
    # until it lies clearly above that (refine_many's ``above``)
    above = [(1 + _CORNER_FAMILY) * held[k].length for k, jobs in starts.items() for _ in jobs]
    refined = iter(refine_many(domain, metric, [j for jobs in starts.values() for j in jobs], tol=tol, atol=atol,
                               above=above))
    out = {}
    for k, jobs in starts.items():
        found = [next(refined) for _ in jobs]
        best = min([held[k]] + found, key=lambda rp: rp.length)
        if clearly and best.length >= held[k].length - held[k].error_estimate:
            continue  # no start beats the curve by more than its estimate: it stays, with its estimate
        # starts in other local geodesics this close to the shortest: another could find one shorter still
        spread = max([rp.length - best.length for rp in found if rp.length <= (1 + _CORNER_FAMILY) * best.length],
                     default=0.0)
        if best is held[k] and not spread_if_held:
            spread = 0.0
        estimate = max(best.error_estimate, held[k].error_estimate) + spread
        if best is not held[k] or spread > 0:
            out[k] = replace(best, error_estimate=estimate)
    return out


def _leave_corners(domain: Domain, metric: Metric, keys: list, held: dict, job_of, tol: float,
                   atol: float) -> dict:
    """Refine the chosen curves held at corners of the cells again from beside them, straight ones from bent starts.

    Returns ``{key: RefinedPath}``, the changed entries.  ``job_of(key,
    points)`` is the curve as a job, its ends held as the entry's are; see
    :func:`_corner_starts`, :func:`_bent_starts` and :func:`_restarted`.  Once: a second round on the curves the first
    replaced found nothing on the limaçon where the replacement stops at the
    next corner of a row (docs/record.md, *Known limitations*).
    """
    jobs = {k: job_of(k, held[k].points) for k in keys}
    corner = {k: _corner_starts(domain, held[k], jobs[k]) for k in keys}
    # straight curves, again from bent starts (of the curves as held: a corner start may bend them a little); their
    # spread counts only where one of them beats the best curve so far
    bent = {k: _bent_starts(held[k], jobs[k]) for k in keys}
    out = _restarted(domain, metric, corner, held, tol, atol)
    out.update(_restarted(domain, metric, bent, {**held, **out}, tol, atol, spread_if_held=False))
    return out


def _straight_starts(domain: Domain, key: tuple, path: RefinedPath, ng: int, cell: float) -> list[GeodesicJob]:
    """Straight starts from a crossing point to its ground, for a chosen curve only a few grid cells long.

    Where a crossing point lies within ``_SHORT`` fine cells of its ground
    (the tiny inner loop of a limaçon ``a + cos t`` with ``a`` near 1), the
    grid cannot rank the ways there: the limaçon ``a = 0.928`` at 17 vertices
    gave 1.3828e-5 at ``tol=1e-5`` with an estimate of 2e-17, no warning,
    18 % above the curves of another listing (an adversarial review, stop
    31; its route was one cell long).  The starts are the straight segments
    from the point to the ground along the parameter axes and the direction
    ``(1, -1)``, both ways, that reach it within ``_SHORT`` cells: one of
    the two points fixed, the other, or both moving alike.  The curve is
    oriented as ``path`` is.  Only on a circle with itself (the annulus, its
    ground the diagonal): on every piece, the random interval scenes of
    ``tests/conftest.py`` (seeds 5 to 9, at most 10 crossings) took 1.8,
    0.18, 1.0, 1.1 and 0.19 s instead of 0.22, 0.086, 0.035, 0.23 and 0.12
    s; without the limit of ``_SHORT`` cells on the segments, seeds 0 to 29
    took 2.1 s instead of 0.25 s (median), their values within 1.1e-6
    (relative) of the old ones.  None for the other entries.
    """
    u, v = key
    if domain.kind != "annulus" or (u < ng) == (v < ng):
        return []
    X = np.asarray(path.points, dtype=float)
    if float(np.hypot(*(X[-1] - X[0]))) > _SHORT * cell:
        return []
    from_ground = u < ng
    g, p = (u, X[-1]) if from_ground else (v, X[0])
    axes = np.array([[0.0, 1.0], [1.0, 0.0], [1.0, -1.0], [0.0, -1.0], [-1.0, 0.0], [-1.0, 1.0]])  # in parameters
    p_local = np.repeat(domain.to_local(p[None, :], wrap=False), len(axes), axis=0)
    t, which = domain.exit_time(p_local, domain.to_local(axes, wrap=False))  # to_local is linear: directions too
    keep = np.isfinite(t) & (t > 0) & (which == g) & (t * np.hypot(*axes.T) <= _SHORT * cell)  # the ground nearby
    ends = p + t[keep, None] * axes[keep]
    if from_ground:
        return [GeodesicJob(np.array([q, p]), start_ground=g) for q in ends]
    return [GeodesicJob(np.array([p, q]), end_ground=g) for q in ends]


def _reflected_starts(domain: Domain, metric: Metric, key: tuple, path: RefinedPath, ng: int) -> list[GeodesicJob]:
    """The chosen curve from a crossing point to the diagonal, reflected across the point's antidiagonal (or none).

    A crossing point ``(x1, x2)`` of a curve with itself closes a loop of
    the deformed curve, ``phi([x1, x2])``; its curve to the diagonal
    (eq. (9): a free end on ``Delta``) runs inside the triangle the point
    cuts off the diagonal.  The reflection ``(y1, y2) -> (c - y2, c - y1)``,
    ``c = x1 + x2``, fixes the point and maps the diagonal onto itself; it
    is an isometry of ``G`` when the loop is symmetric about an axis (the
    limaçons of :func:`_bent_starts`).  On a loop that is nearly symmetric
    the geodesic and its mirror image are two local geodesics whose lengths
    differ by less than the grid's bias, and the grids route the curve to
    either: an adversarial review (stop 31) found the epitrochoid
    ``e^{it} + 0.486 e^{3it}`` at 21 vertices, listed reversed and rolled,
    1.96e-3 above ``J`` at ``tol=1e-5`` (and at the default ``tol``) with
    an estimate of 8.4e-8, no warning: the curve from a small loop's point
    reached the diagonal 0.15 before the loop's middle, the shorter one
    (0.4 % shorter) 0.15 after it.  The reflected curve, 0.2 % shorter than
    the held one there, is a start: resampled evenly to
    ``_REFLECTED_SEGMENTS`` (16) segments and refined from there, or from
    its coarse geodesic where that is shorter (as every grid route is).
    Kept at the held curve's 600 segments, a reflection that is itself a
    fine geodesic starts the refinement at that many and ends at 3000
    after its three levels: the figure eight ``fig10``, whose loops are
    symmetric, took 14 s instead of 3.9 s at the default ``tol`` and 63 s
    instead of 5.2 s at ``tol=1e-5``.  Only when its exact length is
    within ``_REFLECTED_WITHIN`` (5 %) of the curve's: on loops far from
    symmetric it is no start at all (the random interval scenes of
    ``tests/conftest.py``, seeds 0 to 29: 13 reflections, each at least 2.8
    times as long as its curve); and not when it is within
    ``_REFLECTED_SAME`` (1e-9) of it, the mirror image of a curve of a
    symmetric loop, a geodesic of the same length (``fig10``; straight
    curves on the mirror's fixed line are :func:`_bent_starts`' case).  On a
    circle with itself (the annulus), and on an interval with itself when
    the curve ends on the diagonal and its reflection stays in the
    triangle.
    """
    u, v = key
    if domain.kind not in ("annulus", "triangle") or (u < ng) == (v < ng):
        return []
    from_ground = u < ng
    X = np.asarray(path.points, dtype=float)
    if from_ground:
        X = X[::-1]
    L = max(domain.lengths)
    if domain.kind == "triangle" and abs(X[-1, 1] - X[-1, 0]) > 1e-9 * L:
        return []  # ends on a side of the triangle, not on the diagonal
    c = X[0, 0] + X[0, 1]
    Y = np.column_stack([c - X[:, 1], c - X[:, 0]])
    if domain.kind == "triangle" and not (Y.min() >= 0.0 and Y.max() <= L):
        return []
    ratio = polyline_lengths(domain, metric, [Y])[0] / path.upper
    if not ratio <= 1.0 + _REFLECTED_WITHIN or abs(ratio - 1.0) <= _REFLECTED_SAME:
        return []  # far from symmetric, or the mirror image of a curve of a symmetric loop
    Y = _resample(Y, _REFLECTED_SEGMENTS)
    if from_ground:
        return [GeodesicJob(Y[::-1], start_ground=u)]
    return [GeodesicJob(Y, end_ground=v)]


def _alternative_starts(domain: Domain, metric: Metric, keys: list, held: dict, route, ng: int,
                        margin: float) -> dict:
    """Other routes of the chosen curves between two crossing points, as coarse geodesics: ``{key: [GeodesicJob]}``.

    Where a hill of the metric stands between two crossing points, the
    geodesics around it on either side are two local minima of the length,
    and when they differ by less than the grid's bias the grid can route the
    curve around the longer side; the refinement then settles there.  An
    adversarial review (stop 32) found the rose ``r = 1 + 2.5 cos 4t`` at 43
    vertices (``t = 2 pi k / 43 + 0.013``, 24 crossings near the origin)
    1.2e-4 (relative) above the value of its reversed listing at the default
    ``tol``, with an estimate that did not cover it, no warning: one pair of
    curves went round a hill in ``M x M`` at 0.9736495, the other side being
    0.9694202 (0.4 % shorter); the grid's lengths of the two sides differed
    by up to 5 %, the other way.

    The other routes are those of *choice routing*: the plateaus of the two
    trees of grid shortest paths grown from the ends (edges that both trees
    use, the one each way), away from the curve's own route.  A node on a
    plateau lies on a path from one end to the other that is shortest
    from either end to every node of the plateau: a local geodesic of the
    grid, where a detour beside the route only touches the two trees at one
    node.  Kept: plateaus whose route, ``route.alternatives`` of
    :func:`direct.geodesics.grid_distances`, is within ``margin`` (the
    grid's bias with a margin) of the grid's length between the ends, at
    least ``_ALTERNATIVE_SHARE`` (a quarter) of that length long, the
    ``_ALTERNATIVE_MOST`` (2) cheapest; their coarse geodesics
    (:func:`direct.refinement.coarse_geodesics`, 16 segments) are starts
    when at most ``_ALTERNATIVE_COARSE`` (2 %) longer than the held curve.
    A start replaces the curve only where it beats it by more than the
    curve's estimate (``clearly`` in :func:`_restarted`).  On the random
    interval scenes of ``validation/ab.py --family random`` (seeds 100 to
    116) and its ``circles`` family the time did not change (0.98 and 0.99
    of the old); values identical.  Not on a torus, whose routes come
    from the universal cover (:func:`direct.geodesics.torus_distances`).
    """
    routes = {k: route.alternatives(k[0], k[1], margin, _ALTERNATIVE_SHARE, _ALTERNATIVE_MOST)
              for k in keys if k[0] >= ng and k[1] >= ng}
    routes = {k: polys for k, polys in routes.items() if polys}
    if not routes:
        return {}
    coarse = iter(coarse_geodesics(domain, metric, [GeodesicJob(p) for polys in routes.values() for p in polys]))
    starts = {}
    for k, polys in routes.items():
        found = [next(coarse) for _ in polys]
        starts[k] = [GeodesicJob(X, coarse=True) for X, length in found
                     if length <= (1.0 + _ALTERNATIVE_COARSE) * held[k].length]
    return starts


def _chord_starts(domain: Domain, metric: Metric, keys: list, held: dict, cell: float) -> dict:
    """Chosen curves between two crossing points reflected across their chords, as coarse geodesics.

    Returns ``{key: [GeodesicJob]}``; ``keys`` are entries between two
    crossing points, their curves ``held[key]``.  Where two strands of
    the deformed curve cross twice, close together (the lens of two petals
    of a rose ``r = 1 + c cos kt`` with ``k`` even, near the origin), the
    metric has a ring-shaped valley round a hill in ``M x M`` with the two
    crossing points on it, and the curve between them goes round one side
    or the other.  When the valley is narrower than a grid cell the grid's
    lengths of the two sides are no guide (the grid overestimates a narrow
    valley many times over) and neither side's route is a plateau of
    :func:`_alternative_starts`: an adversarial review (stop 33) found six
    roses with ``k = 6`` and ``8`` up to 4.5e-3 (relative) above ``J`` at
    the default ``tol``, one still so at ``tol=1e-5`` (estimate 2.1e-5, no
    warning); the curves round the longer side were up to 51 % longer.  The
    reflection of the curve across the line through its ends is the other
    side's shape; it need not lie in the valley (a narrow one), but its
    coarse geodesic (:func:`direct.refinement.coarse_geodesics`, 16
    segments) slides into it.  A start when that is at most
    ``_ALTERNATIVE_COARSE`` (2 %) longer than the curve and ends up at least
    ``_CHORD_AWAY`` (1) fine cell from it somewhere (Hausdorff distance: not
    the curve again); only for curves that stray ``_CHORD_BULGE`` (half a
    fine cell) from their chords (a nearly straight curve is its own
    reflection; the ring of the review's rose at 40 vertices is 3.7 cells
    across).  On a rectangle or a
    triangle (intervals) a reflection that leaves the domain is no start.
    """
    away = _CHORD_AWAY * cell
    todo = []
    for k in keys:
        X = np.asarray(held[k].points, dtype=float)
        chord = X[-1] - X[0]
        if len(X) < 3 or not np.hypot(*chord) > 0:
            continue
        d = chord / np.hypot(*chord)
        R = X - X[0]
        off = R @ np.array([-d[1], d[0]])  # signed distance from the chord
        if np.abs(off).max() < _CHORD_BULGE * cell:
            continue
        Y = X - 2.0 * np.outer(off, [-d[1], d[0]])
        if domain.kind in ("rect", "triangle") and not np.allclose(_project(domain, Y), Y, rtol=0.0, atol=1e-12):
            continue  # the reflection leaves the domain
        todo.append((k, X, _resample(Y, _REFLECTED_SEGMENTS)))
    if not todo:
        return {}
    coarse = coarse_geodesics(domain, metric, [GeodesicJob(Y) for _, _, Y in todo])
    starts: dict = {}
    for (k, X, _), (Z, length) in zip(todo, coarse):
        if length <= (1.0 + _ALTERNATIVE_COARSE) * held[k].length and shapely.hausdorff_distance(
                shapely.linestrings(X), shapely.linestrings(Z)) >= away:
            starts.setdefault(k, []).append(GeodesicJob(Z, coarse=True))
    return starts


def _grounds(key: tuple, ng: int) -> tuple:
    """``(start_ground, end_ground)`` of an entry ``(u, v)`` of a domain with ``ng`` grounds (``None``: a point)."""
    return (key[0] if key[0] < ng else None, key[1] if key[1] < ng else None)


def _arclength(X: np.ndarray) -> np.ndarray:
    """Each vertex's arclength from the first along the polyline ``X`` (in the parameters)."""
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(X, axis=0).T))])


def _beating_own(domain: Domain, metric: Metric, todo: list, held: dict, ng: int) -> dict:
    """The coarse geodesics of starts ``todo`` (``[(key, polyline)]``) that beat their entry's own, as starts.

    Returns ``{key: [GeodesicJob]}``.  The entries' own curves ``held[key]`` go
    through :func:`direct.refinement.coarse_geodesics` in the same batch, so that
    like is compared with like (the 16 segments overestimate both alike: within
    5e-5 relative on the review's scene of :func:`_strip_starts`, where the
    curve's own was 6.5e-4 over its refined length); a start must beat it by
    more than the entry's estimate.
    """
    own = list(dict.fromkeys(k for k, _ in todo))
    coarse = coarse_geodesics(domain, metric, [GeodesicJob(Y, *_grounds(k, ng)) for k, Y in todo]
                              + [GeodesicJob(np.asarray(held[k].points, dtype=float), *_grounds(k, ng)) for k in own])
    mine = {k: length for k, (_, length) in zip(own, coarse[len(todo):])}
    starts: dict = {}
    for (k, _), (Z, length) in zip(todo, coarse):
        if length < mine[k] - held[k].error_estimate:
            starts.setdefault(k, []).append(GeodesicJob(Z, *_grounds(k, ng), coarse=True))
    return starts


def _strip_starts(domain: Domain, metric: Metric, keys: list, held: dict, ng: int) -> dict:
    """Chosen curves to a side of the domain, their free end moved into the neighbouring strips, as coarse geodesics.

    Returns ``{key: [GeodesicJob]}``.  A side of the domain where an
    interval ends (``x_a = 0`` or ``L_a``) is cut by the vertex lines of the
    other component into strips, one per edge of that component; along each
    strip the distance between the two points of the deformed curves, and so
    the metric, is smooth, and it kinks at the vertex lines.  The length of
    a curve from a crossing point to the side, as a function of where it
    ends, has a local minimum in strip after strip, and the grid (by its
    bias) can pick any of the close ones.  An adversarial review (stop 34)
    found a scene of an epitrochoid and two intervals, with the saturating
    metric ``h(s) = 1 - exp(-s)`` (``GFamily``), 5.1e-4 (relative) above its
    other listings when its closed component was listed from another vertex,
    at the default ``tol`` and at ``tol=1e-5`` (24 and 66 times its
    estimate, no warning): a curve ran to the side in the strip of the
    crossing point (2.2473042), where in the other listings it climbed into
    the next strip (2.2444451).  Each chosen curve with one end on such a
    side gets starts whose end lies in the middle of the ``_STRIP_REACH``
    strips on either side of its own, the other vertices moved along the
    side in proportion to their arclength from the fixed end.  Those at most
    ``_ALTERNATIVE_COARSE`` (2 %) longer than the curve as they stand go on
    to their coarse geodesics (:func:`direct.refinement.coarse_geodesics`),
    which are starts when they beat the curve's own coarse geodesic by more
    than its estimate, wherever they end.  Not for ends at a corner.

    Wherever they end: beside a crease (a vertex line that the geodesic
    touches) the length has several local minima within one strip.  The
    crossing of ``crease_by_a_sliding_end`` (``tests/conftest.py``) on a grid
    of 176 cells had its curve end at 0.0612 along the side (the strip from
    0.0576 to 0.1153), where the geodesic ends at 0.0632; the start from the
    next strip slid back to 0.0625, its coarse geodesic 4.1e-4 (relative)
    shorter than the curve's own, and was dropped for ending in the curve's
    strip: 3.6e-4 off with an estimate of 1.6e-4 at the default ``tol``, at
    four angles.  ``validation/crease_motions.py`` (36 positions and grids,
    default ``tol``): 6 values off by more than their estimates with the
    rule, 2 without it (the other local geodesic at 160 cells: its starts
    slide elsewhere).  ``validation/same_values.py`` kept all 738 values of
    the built-in, closed, tori and interval families, in the same times.

    The diagonal of a self-domain is cut into strips alike, by the vertex
    lines of its component, and an end on it moves along it.  An end at a
    vertex line (within ``_STRIP_SNAP`` of the narrower strip beside it)
    sits on a kink of the length, which can hold a minimum; the strips on
    both sides of it are its own, and it also gets starts in their middles
    and at the next vertex lines, kept when they are not too long as they
    stand (a short move, but a crude shape; below).  An adversarial review (stop
    36) found a single open polyline crossing itself twice, with reference
    speeds 1 to 8, whose curve to the diagonal ended at vertex 7 where
    vertex 6 was 5.0e-5 (relative) shorter: the value was 3.2e-5 high at
    ``tol=1e-5``, 15 times its estimate, and at ``tol=1e-7``, without a
    warning beyond the tolerance's.  Its start at the middle of the strip
    between them settled back at vertex 7; the one at vertex 6 stayed there.
    Those starts go on when they are at most ``_STRIP_NEAR ** order`` times
    as long as the curve as they stand (``order`` the metric's, at least 1:
    a distortion of ``|r|`` by at most ``_STRIP_NEAR`` = 1.6).

    An end inside a strip, on a side or on the diagonal, also gets a start
    at its mirror position in that strip (when it lies at least
    ``_OWN_STRIP / 2`` of the strip from the middle), kept as the starts
    beside a vertex line are.  An adversarial review (stop 37) found a
    jittered limaçon of 13 vertices, with ``g`` at ``tol=1e-5``, whose curve
    from the crossing point on its symmetry axis to the diagonal ends on the
    short edge across the axis, where the length has two nearly tied minima:
    at 0.30 and 0.70 of the edge for ``p = 2``, at its two vertex lines for
    ``p = 3`` and ``4.5``.  One listing or another kept the longer, 6.5e-4 to
    1.4e-3 (relative) above another listing's ``upper_bound``, 140 to 220
    times its estimate, without a warning; the starts that find the shorter
    stood 1.5 (``p = 2``) and 14 (``p = 3``) times as long as the curve.

    Measured (``validation/ab.py``, default ``tol``): the random interval
    scenes and the ``circles`` family kept their times (old/new 1.00 and
    0.99, values identical); without the filter on the moved curves' own
    lengths the interval scenes took 1.5 times as long (a curve 0.57 long
    whose end moved by 0.84 and 1.5 into the next two strips: 3.6 and 13
    times longer as it stood, 0.15 s of coarse geodesics for nothing), and comparing the
    coarse geodesics with the curve's refined length (plus 2 %) instead of
    its own coarse geodesic refined near ties on the review's scene, 1.8
    times its time.  The review's scene takes 5 % to 8 % longer.
    """
    todo = []
    for k in keys:
        if (k[0] < ng) == (k[1] < ng):
            continue
        X = np.asarray(held[k].points, dtype=float)
        if k[0] < ng:
            X = X[::-1]  # the free end last
        end = X[-1]
        at = [a for a in (0, 1) if not domain.comps[a].closed
              and min(abs(end[a]), abs(end[a] - domain.comps[a].length)) <= 1e-9 * domain.comps[a].length]
        on_diagonal = _on_diagonal(domain, end)
        if len(at) + on_diagonal != 1 or len(X) < 3:
            continue  # at a corner
        # along a side x_a = const the end moves in x_b; along the diagonal in both (the strips: its edges)
        b = 0 if on_diagonal else 1 - at[0]
        move = np.array([1.0, 1.0]) if on_diagonal else np.eye(2)[b]
        comp = domain.comps[b]
        if comp.closed:
            lines = _vertex_params(comp, end[b] - comp.length, end[b] + comp.length)
        else:
            lines = np.asarray(comp.params, dtype=float)
        i = int(np.searchsorted(lines, end[b], side="right")) - 1
        s = _arclength(X)
        if not s[-1] > 0:
            continue  # a crossing point on the side itself
        # an end at a vertex line (a kink of the length, which can hold a minimum) has the strips on both sides for
        # its own; it gets starts in the middle of each and at the vertex lines beyond them, where the next minimum
        # may lie (the review's curl: its curve to the diagonal ended at vertex 7 where vertex 6 was 5e-5 shorter)
        m = i + int(np.argmin(np.abs(lines[i:i + 2] - end[b]))) if i + 1 < len(lines) else i
        width = np.diff(lines[max(m - 1, 0):m + 2]).min()
        if 0 < m < len(lines) - 1 and abs(end[b] - lines[m]) <= _STRIP_SNAP * width:
            targets = [(0.5 * (lines[j] + lines[j + 1]), j in (m - 1, m))
                       for j in range(m - 1 - _STRIP_REACH, m + _STRIP_REACH + 1) if 0 <= j < len(lines) - 1]
            targets += [(lines[m - 1], True), (lines[m + 1], True)]
        else:
            targets = [(0.5 * (lines[j] + lines[j + 1]), False)
                       for j in range(i - _STRIP_REACH, i + _STRIP_REACH + 1) if j != i and 0 <= j < len(lines) - 1]
            # and its mirror position in its own strip, where a second minimum can lie (a curve from a crossing on the
            # symmetry axis of a curve to an edge across it: _OWN_STRIP)
            if i + 1 < len(lines):
                width = lines[i + 1] - lines[i]
                t = lines[i] + lines[i + 1] - end[b]
                if abs(t - end[b]) >= _OWN_STRIP * width:
                    targets.append((t, True))
        for t, near in targets:
            Y = X + np.outer((t - end[b]) * s / s[-1], move)
            if domain.kind in ("rect", "triangle") and not np.allclose(_project(domain, Y), Y, rtol=0.0, atol=1e-12):
                continue  # the moved curve leaves the domain
            todo.append((k, near, Y[::-1] if k[0] < ng else Y))
    if todo:  # the moved curves as they stand: those far longer than the curve lead elsewhere (beside a vertex line
        # the move is short, and its crude shape alone can cost more: 2.0 % and 3.8 % on the review's curl)
        moved = polyline_lengths(domain, metric, [Y for *_, Y in todo])
        near = _STRIP_NEAR ** max(float(metric.order), 1.0)  # a distortion of |r| by that factor, in the length
        todo = [t for t, L in zip(todo, moved)
                if L <= (near if t[1] else 1.0 + _ALTERNATIVE_COARSE) * held[t[0]].length]
    return _beating_own(domain, metric, [(k, Y) for k, _, Y in todo], held, ng) if todo else {}


def _on_diagonal(domain: Domain, point: np.ndarray) -> bool:
    """Whether a point of a self-domain (``triangle``, ``annulus``) lies on the diagonal ``x1 = x2`` (mod ``L``)."""
    if domain.pair[0] != domain.pair[1]:
        return False
    L = domain.comps[0].length
    gap = point[1] - point[0]
    return bool(min(abs(gap), abs(gap - L)) <= 1e-9 * L if domain.comps[0].closed else abs(gap) <= 1e-9 * L)


def _transplanted_starts(domain: Domain, metric: Metric, keys: list, held: dict, ends) -> dict:
    """A chosen curve's route moved onto the ends of its competitors on a torus, as coarse geodesics.

    Returns ``{key: [GeodesicJob]}`` for entries not chosen.  On a torus a
    curve that winds round it has several local geodesics, a fraction of a
    per cent apart, and the one the refinement finds from the grid's route
    depends on where the seams cut the curves.  When the curve of one pair of
    points that winds round was refined in a longer one than the curve of the
    neighbouring pair, the program gives the winding curve to the other pair,
    whatever their short curves cost.  An adversarial review (stop 34) found a
    star ``r = 1 + 0.3 cos 10t`` at 30 vertices crossing an ellipse (20
    crossings, a torus): listed from the 24th and 14th vertices it gave
    18.764541 at the default ``tol``, 1.36e-3 (relative) above the
    ``upper_bound`` of the listing as built (83 times its estimate, no warning).
    Its winding curve of one pair was 9.2948173, of the neighbouring pair
    9.3542432, against 9.2942309 in the listing as built; the short curves
    were 0.0135739 and 0.0257199.

    For each chosen curve and each entry of the same class (``key[2]``) not
    chosen whose refined curve is at most ``_TRANSPLANT`` (1 %) longer and
    whose ends lie within ``_TRANSPLANT_REACH`` (a quarter) of the curve's
    length (in the parameters) from its ends, a start is the chosen curve moved onto the entry's ends (``ends(key)``, in
    the periodic copy nearest the chosen curve's ends), by a shift that runs
    linearly in arclength from one end's displacement to the other's.  Its
    coarse geodesic (:func:`direct.refinement.coarse_geodesics`) is a start
    when it beats the entry's own coarse geodesic by more than the entry's
    estimate.
    """
    S, V = domain.local_lengths
    period = np.array([S, V])
    todo = []
    for k in keys:
        if k[0] == "closed":
            continue
        X = np.asarray(held[k].points, dtype=float)
        a, b = X[0], X[-1]
        s = _arclength(X)
        length = s[-1]  # in the parameters
        if not length > 0:
            continue
        s = (s / length)[:, None]
        for o, rp in held.items():
            if o[0] == "closed" or o in keys or o[2] != k[2] or rp.length > (1.0 + _TRANSPLANT) * held[k].length:
                continue
            a2, b2 = ends(o)
            shift = period * np.round((a - a2) / period)  # the copy of the entry's ends nearest the curve's
            da, db = a2 + shift - a, b2 + shift - b
            if max(np.hypot(*da), np.hypot(*db)) > _TRANSPLANT_REACH * length:
                continue  # ends too far apart for the curve's shape to carry over
            todo.append((o, X + (1.0 - s) * da + s * db))
    return _beating_own(domain, metric, todo, held, domain.n_grounds) if todo else {}


def _lines_around(comp, x: np.ndarray) -> np.ndarray:
    """The vertex parameters of ``comp`` from a period (at most 1.0) below ``x`` to one above: the nearest lines.

    Not a fixed 1.0 around: a circle 6e-9 long made that 3e8 periods of lines (19.5 GiB; a review at stop 48).
    """
    reach = min(1.0, comp.length)
    return _vertex_params(comp, float(x.min()) - reach, float(x.max()) + reach)


def _crease_starts(domain: Domain, path: RefinedPath, cell: float, start_ground: int | None = None,
                   end_ground: int | None = None) -> list[GeodesicJob]:
    """Starts that move a chosen curve's stretch along a vertex line wholly to one side of it (or none).

    Across a vertex line (a vertex parameter of one component) ``phi'``
    jumps, and the metric has a crease: a curve that runs beside the line
    can have two local geodesics a fraction of a cell apart, one on each
    side or one crossing it, whose lengths differ by less than the grid's
    bias.  An adversarial review (stop 32) found the trefoil ``r = 1 + 1.6
    cos 3t`` at 27 vertices (``t = 2 pi k / 27 + 0.03``; 15 crossings, three
    copies of each curve under its rotation by a third of a turn) 4.9e-4
    (relative) above ``J`` at the default ``tol`` in every listing, and 9.8e-4
    above with an estimate of 9.3e-5, no warning, listed backwards and
    rolled: of the three copies of one curve the grids sent one or two
    0.18 to 0.95 cells beside a vertex line for 4.6 cells (0.048056825), the
    others across it by 0.32 cells (0.048304039, 0.5 % longer; between the
    two the length rises to 0.04861).  For every stretch of consecutive
    interior vertices within ``_CREASE_BAND`` (1) cells of one vertex line,
    running at least ``_CREASE_EXTENT`` (2) cells along it, each side the
    stretch is not wholly on already gets a start: the curve with the
    stretch's offsets from the line folded onto that side.  On a circle
    with itself (the annulus) and on a torus (below), not on the pieces of
    intervals: on every piece, the random interval
    scenes of ``tests/conftest.py`` (seeds 0 to 29, at most 10 crossings)
    took 1.7 times as long at the default ``tol`` (28 starts) and 9.8 times
    at ``tol=1e-5`` (65 starts; seed 4: 367 s instead of 24 s), for values
    within their estimates; the random closed polygons of
    ``validation/random_closed.py`` (seeds 0 to 19) kept their times.  Of
    a pair of mirror images (:func:`_mirror_pairs`) only the longer gets
    starts, and the other follows its result: ``fig10``, whose curves cross
    vertex lines at shallow angles, took 3.7 s with both (12 starts) and
    takes 2.8 s, against 1.8 s without the rule.  The starts hold their
    ends as the curve does (``start_ground``, ``end_ground``).  On a torus
    (two closed curves, no ground) since stop 33: an adversarial review found a rose (``k = 4``, 46 vertices)
    crossing an ellipse 4.5e-5 (relative) above its reversed listing's bound
    at the default ``tol``, a curve between two crossing points 0.1 % longer
    than its other listing's (3.7729855 against 3.7692863), beyond the
    estimate, no warning; the folded starts find the shorter.
    """
    X = np.asarray(path.points, dtype=float)
    if domain.kind not in ("annulus", "torus") or len(X) < 4:  # not on the pieces of intervals (above)
        return []
    starts = []
    for axis, comp in enumerate(domain.comps):
        x = X[1:-1, axis]
        vp = _lines_around(comp, x)
        if len(vp) < 2:
            continue
        i = np.clip(np.searchsorted(vp, x), 1, len(vp) - 1)
        line = np.where(np.abs(vp[i] - x) < np.abs(vp[i - 1] - x), vp[i], vp[i - 1])  # the nearest vertex line
        off = x - line
        near = np.abs(off) <= _CREASE_BAND * cell
        # stretches: consecutive vertices near the same line
        cut = np.flatnonzero(np.diff(near.astype(int)) != 0) + 1
        cut = np.union1d(cut, np.flatnonzero(np.diff(line) != 0) + 1)
        for run in np.split(np.arange(len(x)), cut):
            if not near[run[0]] or np.ptp(X[run + 1, 1 - axis]) < _CREASE_EXTENT * cell:
                continue
            for side in (1.0, -1.0):
                if np.all(side * off[run] >= 0.0):
                    continue  # wholly on this side already
                Y = X.copy()
                Y[run + 1, axis] = line[run] + side * np.abs(off[run])
                starts.append(GeodesicJob(Y, start_ground=start_ground, end_ground=end_ground))
    return starts


def _bent_starts(path: RefinedPath, job: GeodesicJob) -> list[GeodesicJob]:
    """Four starts bent away from a chosen curve that came out straight along ``(1, -1)`` (or none).

    A geodesic of ``G`` is straight in the parameters only on the fixed line
    of an isometry: a polygon symmetric about an axis through its crossing
    (sampled evenly from a symmetric formula) makes ``(x1, x2) -> (s(x2),
    s(x1))`` one, ``s`` the reflection, and the straight curve from the
    crossing point along ``(-1, 1)`` a local geodesic that both grids weigh
    exactly (a move of every stencil), the shortest curves beside it up to
    the stencil's bias more.  An adversarial review (stop 31) found
    limaçons ``a + cos t`` sampled from ``t = 0`` whose straight curves were
    up to 18 % above ``J`` at ``tol=1e-5`` with estimates of 1e-14 relative,
    no warning (the shortest curves bulge by 7 % of their chord).  Four
    starts bend the chord, to either side, by ``_BEND`` (1 % and 10 %) of
    its length at its middle, in a parabola of ``_BENT_SEGMENTS`` (16)
    segments; the ends stay.  They are refined from there, not from their
    coarse geodesics: those went back to the straight curve (the limaçon
    ``a = 0.57`` at 15 vertices listed from vertex 3, a second review: 5.1e-5
    above another listing's ``upper_bound`` with an estimate of 2.5e-9, no
    warning; refined from the bent polylines at the curve's own 128
    segments, the limaçons ``a = 0.3`` at 16 vertices, 0.43 at 12, 0.454 at
    14 and 0.8 at 12 took 3.7 to 18 times as long).  The limaçon ``a = 0.3`` at 16 vertices needs the
    small bend (its shortest curves bulge by 0.9 %), ``a = 0.8`` at 12
    vertices the large one.  A curve counts as straight within
    ``_STRAIGHT`` (1e-5) of its chord: the same review found straight
    curves 6.2e-7 of their chord off it (``a = 0.43`` at 12 vertices listed
    reversed from vertex 4: 3.8e-3 above, estimate 8e-13, no warning, with a
    threshold of 1e-9).  Only curves along ``(1, -1)`` (within
    ``_ANTIDIAGONAL``, 1e-3 of the chord: that limaçon's was 1.8e-5 off),
    the direction of that fixed line: with every straight curve, the
    built-in scenes whose metric vanishes along whole lines (``fig13``,
    ``reversed``, ``ring``; ``fig11`` with ``g``) took 10 to 190 times as
    long, their estimates up to 7e4 times wider, for the same values.  Their
    straight curves run from the diagonal to the diagonal (both ends free,
    the curves of the flux condition, which :func:`_family_shifts` starts
    again anyway): those are left out, and closed curves.  A start's spread
    counts only where one of them beats the curve (:func:`_leave_corners`).
    """
    X = np.asarray(path.points, dtype=float)
    if job.closed or len(X) < 3 or (job.start_ground is not None and job.end_ground is not None):
        return []
    chord = X[-1] - X[0]
    length = float(np.hypot(*chord))
    if length == 0.0:
        return []
    normal = np.array([-chord[1], chord[0]]) / length
    off = (X - X[0]) @ normal
    if abs(chord[0] + chord[1]) > _ANTIDIAGONAL * length or np.abs(off).max() > _STRAIGHT * length:
        return []  # not straight, or not along (1, -1)
    X = X[0] + np.linspace(0.0, 1.0, _BENT_SEGMENTS + 1)[:, None] * chord
    s = np.linspace(0.0, 1.0, _BENT_SEGMENTS + 1)
    bend = (length * 4.0 * s * (1.0 - s))[:, None] * normal
    return [replace(job, route=X + side * b * bend, coarse=True) for b in _BEND for side in (1.0, -1.0)]


def _corner_vertices(domain: Domain, X: np.ndarray, closed: bool) -> np.ndarray:
    """Indices of the vertices of polyline ``X`` (parameters) on a corner of the cells.

    A corner is where a vertex line of each component meets another (a
    vertex parameter of ``M_i`` times one of ``M_j``): the metric has a
    crease along both lines.  A vertex sits on it when it lies within
    ``_ON_CORNER`` of its longer segment from both lines: pinned, a vertex
    that slides on one line stopped 5e-9 from the other, where a vertex on
    that line sits, its other segment 1e-3 long; on two overlapping polygons
    (a torus) pinned vertices stood 3.8e-3 and 7.5e-3 of their longer
    segments from a corner, 1.4e-3 relative above ``J`` (an adversarial
    review: a window of 1e-3 missed them; a quarter of the segment flagged
    three corners of one curve at once, and moving all three together lost
    the crease of ``test_a_crease_by_a_sliding_end_at_the_default_tol``).
    A curve along one of the lines counts too: a closed curve of two nested
    polygons lay exactly on a vertex line (its length exact, estimate
    5e-14), 1.2e-3 above the geodesic beside it, and the starts from its
    corners found that one (an adversarial review; skipping the corners of
    curves that do not cross both lines brought it back).  The ends are left
    out (held by their conditions), and on a closed curve the repeated last
    vertex.
    """
    n = len(X)
    seg = np.linalg.norm(np.diff(X, axis=0), axis=1)
    if closed:
        inner = np.arange(0, n - 1)
        near_seg = np.maximum(seg, np.roll(seg, 1))
    else:
        inner = np.arange(1, n - 1)
        near_seg = np.maximum(seg[:-1], seg[1:])
    if len(inner) == 0:
        return inner
    window = _ON_CORNER * near_seg
    corner = np.empty((len(inner), 2))
    for axis, comp in enumerate(domain.comps):
        x = X[inner, axis]
        vp = _lines_around(comp, x)
        if len(vp) == 0:
            return inner[:0]
        i = np.clip(np.searchsorted(vp, x), 1, max(len(vp) - 1, 1))
        hi, lo = vp[np.minimum(i, len(vp) - 1)], vp[i - 1]
        corner[:, axis] = np.where(np.abs(hi - x) < np.abs(lo - x), hi, lo)
    on = (np.abs(X[inner] - corner) <= window[:, None]).all(axis=1)
    return inner[on]


def _corner_starts(domain: Domain, path: RefinedPath, job: GeodesicJob) -> list[GeodesicJob]:
    """Two starts that leave the cell corners a refined curve sits on, one to each side (or none).

    A curve whose route runs through a corner of the cells (a grid node
    where vertex lines of both components meet, and so a vertex of the first
    polyline) can stay pinned there: the length is not smooth at a corner,
    and neither Newton nor L-BFGS moves a vertex off it, though the geodesic
    passes beside it.  Measured: a 13-gon entered by an interval (a cylinder,
    one crossing), refined at ``tol=1e-4``: the curve to the boundary held at
    a corner 1.6e-4 (relative) above the one beside it, 9e-3 away, with an
    estimate of 6e-5 (an adversarial review; listed from another vertex, the
    grid's route missed the corner).  Each start bumps the curve across
    itself around every corner vertex, all to the left or all to the right:
    the corner vertex by 0.3 of its longer segment, the vertices within
    ``_CORNER_REACH`` (1.5) such segments along the curve a tent's share of
    that.  Moving the corner vertex alone left that 13-gon listed from
    vertex 10 in the corner on another machine (other roundings; its curve
    had two vertices on the corner, its geodesic passed 2e-2 beside it, and
    Newton pulled the lone vertices back): 1.6e-4 above ``J`` with an
    estimate of 8.8e-5, no warning.  A bump of 1 % of the curve's length
    over a tenth of it also fixed that, but made seed 3 of the random
    interval scenes take 924 s at ``tol=1e-5`` under cProfile (23 s before,
    without it) and ``fig13`` with ``g`` 293 s instead of 10 s (its
    estimate 80 times wider).  A reach of 3 segments also did, but seed 3
    of ``test_local_refinement_and_the_uniform_grid_agree_within_their_
    estimates`` took 69 and 42 s (two grids) against 59 and 15 s with 1.5,
    one run each beside another process.
    On 39 random interval scenes at ``tol=1e-4`` 17 of 538
    curves had a vertex within 1e-9 of a corner (a first, narrower test),
    and such starts shortened them by at most 5.6e-6 relative, within their
    estimates.  On seeds 150 to 169 of ``validation/default_tol.py`` at
    ``tol=1e-3`` they lowered 4 values, seed 158 by 8.4e-5 relative
    (estimate 2.9e-4), and took 1.25 times the time (12.7 s against 10.2 s).
    """
    X = np.asarray(path.points, dtype=float)
    ks = _corner_vertices(domain, X, job.closed)
    if len(ks) == 0:
        return []
    prev = X[ks - 1] if not job.closed else X[(ks - 1) % (len(X) - 1)] - (ks == 0)[:, None] * job.shift
    chord = X[ks + 1] - prev
    normal = np.stack([-chord[:, 1], chord[:, 0]], axis=1) / np.linalg.norm(chord, axis=1)[:, None]
    seg = np.linalg.norm(np.diff(X, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    longer = np.maximum(np.linalg.norm(X[ks] - prev, axis=1), seg[ks])
    step = 0.3 * longer
    # a bump of the curve around each corner, a tent along its arclength, rather than the corner vertex alone
    tent = np.clip(1.0 - np.abs(arc[:, None] - arc[ks][None, :]) / (_CORNER_REACH * longer)[None, :], 0.0, None)
    if not job.closed:
        tent[[0, -1]] = 0.0  # the ends stay (held by their conditions)
    else:
        tent[-1] = 0.0  # the repeated last vertex follows the first
    bump = (tent @ (step[:, None] * normal)) / np.maximum(tent.sum(axis=1), 1.0)[:, None]
    starts = []
    for side in (1.0, -1.0):
        Y = X + side * bump
        if job.closed:
            Y[-1] = Y[0] + job.shift
        starts.append(replace(job, route=Y, coarse=False))
    return starts


def _slid_ends(domain: Domain, metric: Metric, keys: list, cache: dict, grid_costs: dict, tol: float,
               atol: float) -> dict:
    """Curves from a crossing point to the diagonal, refined again with their end slid towards shallow points.

    The metric vanishes on the diagonal (``r = 0`` there) and at every
    crossing point, so near a crossing point close to the diagonal (a small
    loop of a closed curve) a curve can reach the diagonal in two basins
    whose lengths differ by less than the grid's bias.  For each curve from a
    crossing point ``a`` to a side of the diagonal, and each other crossing
    point whose grid cost to that side is below ``_SHALLOW`` of the curve's
    and which lies along the diagonal within ``_SLIDE_REACH`` of the curve's
    chord from its end,
    the curve is refined again from copies whose end slides along the
    diagonal to beside that point (to ``s = x1``, ``x2`` and their mean for
    the point ``(x1, x2)``; the vertices move in proportion to their
    arclength from ``a``).  The shortest copy replaces the curve when
    it is shorter, with its own estimate: the other basins are other
    geodesics, longer, not a spread of this one (unlike the rotated copies
    of :func:`_family_shifts`, one family).
    Measured: a noisy figure eight with ``g``, ``p = 2``, at ``tol=1e-5``,
    listed from its 14th vertex, sent a crossing point's curve to the
    diagonal 0.25 from where a shorter one ends, next to a small loop's
    crossing point (1.5024197 against 1.5021047), both passes alike: 2.1e-4
    above ``J`` with an estimate of 3.9e-6, no warning (an adversarial
    review; ``tests/test_circles.py``).  Runs with the second pass
    (``tol <= 1e-4`` by default) on the annulus (a circle with itself).
    Sliding every such curve by fixed fractions of its chord, whether or not
    a shallow point lies near, made the random closed polygons of
    ``validation/random_closed.py`` 5 times slower at ``tol=1e-5``, and the
    interval scenes (on the triangles) 1.8 times at ``tol=1e-4``, for
    changes within their estimates.

    Returns
    -------
    dict
        ``{key: RefinedPath}`` for the curves a slid start shortened.
    """
    ng = domain.n_grounds
    S = domain.local_lengths[0]
    jobs, owner = [], []
    for k in keys:
        u, v = k
        if (u < ng) == (v < ng):
            continue
        a, g = (u, v) if v < ng else (v, u)
        reach = grid_costs[k]
        shallow = [p for p in range(ng, ng + len(domain.points)) if p != a
                   and min(grid_costs.get((p, g), np.inf), grid_costs.get((g, p), np.inf)) <= _SHALLOW * reach]
        if not shallow:
            continue
        X = cache[k].points if v < ng else cache[k].points[::-1]  # from a to the ground
        arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(X, axis=0), axis=1))])
        if not arc[-1] > 0:
            continue
        end_s = domain.to_local(X[-1:], wrap=False)[0, 0]
        chord = float(np.linalg.norm(X[-1] - X[0]))
        for p in shallow:
            x1, x2 = domain.points[p - ng]
            gap = x2 - x1 - S * np.round((x2 - x1) / S)  # the point's offset from the diagonal, the nearer way
            for target in (x1, x1 + 0.5 * gap, x1 + gap):  # the diagonal beside the point: s = x1 = x2 there
                shift = target - end_s
                shift -= S * np.round(shift / S)  # the nearer way round
                if abs(shift) > _SLIDE_REACH * chord:  # a point far along the diagonal: another basin altogether
                    continue
                jobs.append(GeodesicJob(X + (arc / arc[-1])[:, None] * (shift * domain.basis[:, 0]), end_ground=g))
                owner.append(k)
    if not jobs:
        return {}
    found: dict = {}
    for k, rp in zip(owner, refine_many(domain, metric, jobs, tol=tol, atol=atol)):
        if k[0] < ng:  # from the boundary to a point: the curve runs backwards
            rp = rp.reversed()
        found.setdefault(k, []).append(rp)
    best = {k: min(rps, key=lambda rp: rp.length) for k, rps in found.items()}
    return {k: rp for k, rp in best.items() if rp.length < cache[k].length}


def _mirror_of(domain: Domain, metric: Metric):
    """The swap ``(x1, x2) -> (x2, x1)`` on the nodes of a circle's domain with itself: ``(node map, length)`` or None.

    On the annulus ``x1 < x2 < x1 + L`` the swap is ``(x1, x2) -> (x2, x1 + L)``:
    it exchanges the two sides of the diagonal (grounds 0 and 1) and the two
    points of each crossing, and preserves a metric with
    :attr:`direct.metric.Metric.swap_symmetric`.  None when the metric does
    not say so, or when a point has no mirror among the points.
    """
    if not metric.swap_symmetric:
        return None
    ng = domain.n_grounds
    points: dict = {}  # the points of each crossing
    for k, c in enumerate(domain.crossing_ids):
        points.setdefault(int(c), []).append(ng + k)
    if any(len(p) != 2 for p in points.values()):
        return None
    node = {0: 1, 1: 0}
    node.update({u: v for u, v in points.values()})
    node.update({v: u for u, v in points.values()})
    return node, float(domain.lengths[0])


def _mirrored(rp: RefinedPath, period: float, flip: bool = False) -> RefinedPath:
    """The mirror image ``(x1, x2) -> (x2, x1 + L)`` of a refined curve on a circle's domain with itself.

    With ``flip``, run the other way (the entry of :func:`_mirror_key` stored reversed).
    """
    X = np.asarray(rp.points, dtype=float)
    image = replace(rp, points=np.column_stack([X[:, 1], X[:, 0] + period]))
    return image.reversed() if flip else image


def _mirror_key(key: tuple, cache: dict, node: dict) -> tuple[tuple, bool]:
    """The entry of ``key``'s mirror image in ``cache`` (see :func:`_mirror_of`), and whether it runs the other way.

    The curve may be stored the other way round, and the swap twice is the
    shift ``(L, L)``, a period: the same curve.
    """
    m = (node[key[0]], node[key[1]])
    flip = m not in cache and m[::-1] in cache
    return (m[::-1] if flip else m), flip


def _mirror_pairs(keys: list, cache: dict, node: dict, period: float) -> dict:
    """Give each chosen curve of a circle with itself the better of itself and its mirror image: ``{key: RefinedPath}``.

    The curve from ``u`` to ``v`` and the one from the mirror of ``u`` to the
    mirror of ``v`` are mirror images, of equal length in a swap-symmetric
    metric, but the grid routes and refines them apart.  Where they settle
    in different local geodesics the shorter stands for both, its estimate
    widened by their spread when they lie within 1 % (:func:`_best_of_starts`:
    minima that close leave the global one unknown to about their spread).
    Measured on the limaçon ``r = 0.7 + cos t`` at 32 vertices listed in
    reverse (docs/record.md, *Known limitations*): the two curves 0.0073431755 and
    0.0073430578 at the default ``tol``, held at different corners of the
    cells (the geodesic 0.0073430250); both are now 0.0073430578, each with
    an estimate of 1.2e-7.  An entry whose mirror was not refined gets the
    mirror image.
    """
    out: dict = {}
    for k in keys:
        if k not in cache or k in out:
            continue
        m, flip = _mirror_key(k, cache, node)
        if m == k:
            continue
        best = _best_of_starts([cache[k], _mirrored(cache[m], period, flip)]) if m in cache else cache[k]
        out[k], out[m] = best, _mirrored(best, period, flip)
    return out


def _best_of_starts(found: list[RefinedPath], family: float = 0.01, by_bound: bool = False) -> RefinedPath:
    """The shortest of the refined curves of one entry from several starts, its estimate widened by their spread.

    Starts that settle in nearby minima (within ``family``, relative: the
    same family of geodesics, shifted) leave the global one unknown to about
    their spread, which is added (nested: 2.7e-5 relative between the minima
    that eight starts reach in a probe, with discretization estimates of 6e-6).
    Farther minima are other geodesics, and add nothing.  Around a circle
    (:func:`_family_shifts`) the window is 1 %; for the closed curves of a
    torus it is ``direct.penalty._CLOSED_FAMILY``, as distinct closed geodesics lie closer
    (two random nested 7-gons: six within 1 %, 1.1e-3 apart at least).

    With ``by_bound`` (the closed curves of a torus) the best is the least
    ``length + error_estimate``, and the spread counts the starts on both
    sides of it: a start refined badly can extrapolate below the others (a
    17-gon nested in a 20-gon with ``g``: the sixth start 2.7e-4 below its
    own exact length with an estimate of 2.5e-3, against five at
    3.0759767 to 3.0759777, and the value warned).
    """
    found = sorted(found, key=(lambda rp: rp.length + rp.error_estimate) if by_bound else (lambda rp: rp.length))
    best = found[0]
    window = [rp.length - best.length for rp in found if rp.length <= (1 + family) * best.length]
    spread = max(abs(d) for d in window) if by_bound else max(window)
    return RefinedPath(best.points, best.length, best.upper, best.error_estimate + spread, best.segments)
