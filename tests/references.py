"""Independent reference values of J for two straight segments crossing at any angle.

Also for several crossings of straight runs (:func:`straight_crossings_reference`) and for an interval
crossing a polygon once (:func:`cylinder_reference`, where the winding numbers decide which end the curve
must reach).

Not computed with `direct`: for two unit-speed segments crossing at the origin
at angle ``alpha`` the length element is ``rho |dx|`` with
``rho = (x1^2 + x2^2 - 2 x1 x2 cos alpha)^(k/2)`` (``k = 2`` for ``G``,
``k = 4`` for ``g`` with ``p = 2``; in general ``k = q`` for ``G`` with power ``q``
and ``k = 2p`` for ``g``: the deformation is an isometry, so both
metrics are isotropic in the parameters).  ``rho`` is homogeneous of degree
``k``, so the distance from the crossing point is ``|x|^(k+1) f(theta)`` with
the eikonal equation ``(k + 1)^2 f^2 + f'^2 = Q(theta)^2``,
``Q = (1 - cos(alpha) sin(2 theta))^(k/2)`` (shared/NUMERICS.md).  The ODE is
integrated from the cheapest direction ``theta_0`` (where the geodesic is
the straight ray and ``f = Q / (k + 1)``; the singular start uses the
second-order expansion ``f = Q_0/(k+1) + c (theta - theta_0)^2`` over an
interval ``1e-3 sin(alpha)`` wide, inside the valley of width ``~ alpha``) with
``solve_ivp`` at ``rtol = 1e-12`` and an absolute tolerance 1e-12 times the
starting value (the values are tiny for high powers at small angles: about
1e-10 for ``k = 6`` at 0.04 rad, where an absolute 1e-15 cost 3e-5 relative); the distance to the boundary of the
parameter rectangle ``[-a, b] x [-c, d]`` is the minimum of
``r(theta)^(k+1) f(theta)`` over the boundary, and ``J`` counts the two points
of the crossing.  At 60 degrees on the unit square this gives the
NUMERICS.md value 0.2581226580725618 to 1e-13.
"""

from __future__ import annotations

import numpy as np
import shapely
from scipy.integrate import solve_ivp
from scipy.optimize import minimize_scalar


def _profile(alpha: float, k: int):
    """``f(theta)`` of the distance ``|x|^(k+1) f(theta)`` from the crossing point."""
    ca = np.cos(alpha)

    def Q(t):
        return (1.0 - ca * np.sin(2 * t)) ** (k / 2)

    t0 = np.pi / 4 if ca >= 0 else 3 * np.pi / 4
    q0 = Q(t0)
    h = 1e-4
    B = (Q(t0 + h) - 2 * q0 + Q(t0 - h)) / (2 * h * h)  # Q = q0 + B d^2 + ...
    c = (-2 * (k + 1) * q0 + np.sqrt(4 * (k + 1) ** 2 * q0**2 + 32 * q0 * B)) / 8
    d0 = 1e-3 * min(1.0, abs(np.sin(alpha)))  # the valley around theta_0 is about alpha wide
    branches = {}
    for sgn in (1, -1):
        def rhs(t, f, sgn=sgn):
            return sgn * np.sqrt(np.maximum(Q(t) ** 2 - (k + 1) ** 2 * f**2, 0.0))

        f0 = q0 / (k + 1) + c * d0**2
        branches[sgn] = solve_ivp(rhs, (t0 + sgn * d0, t0 + sgn * np.pi / 2), [f0], rtol=1e-12, atol=1e-12 * f0,
                                  dense_output=True)

    def f(t):
        d = (t - t0 + np.pi / 2) % np.pi - np.pi / 2  # period pi: rho is even
        if abs(d) < d0:
            return q0 / (k + 1) + c * d * d
        return float(branches[1 if d > 0 else -1].sol(t0 + d)[0])

    return f


def crossing_reference(alpha: float, a: float = 1.0, b: float = 1.0, c: float = 1.0, d: float = 1.0,
                       k: int = 2) -> float:
    """``J`` of ``direct.scenes.cross(a, b, c, d, alpha)``: twice the distance from the crossing to the boundary.

    ``k = 2`` for the metric ``G`` (Example 14), ``k = 4`` for ``g`` with ``p = 2``.
    """
    f = _profile(alpha, k)
    lo, hi = np.array([-a, -c]), np.array([b, d])

    def dist(t):
        u = np.array([np.cos(t), np.sin(t)])
        with np.errstate(divide="ignore"):
            r = np.min(np.where(u > 0, hi / u, np.where(u < 0, lo / u, np.inf)))
        return r ** (k + 1) * f(t)

    ts = np.linspace(0, 2 * np.pi, 7201)
    vals = np.array([dist(t) for t in ts])
    best = np.inf
    for i in np.argsort(vals)[:6]:  # polish the best samples (each side of the rectangle is smooth)
        res = minimize_scalar(dist, bounds=(ts[i] - 2 * np.pi / 7200, ts[i] + 2 * np.pi / 7200), method="bounded",
                              options={"xatol": 1e-13})
        best = min(best, res.fun, vals[i])
    return 2.0 * best


def _side_distance(f, k: int, point, direction, lo: float, hi: float, samples: int = 2001) -> float:
    """The least distance ``|x|^(k+1) f(theta)`` to the side ``point + t direction`` (lo <= t <= hi)."""
    def dist(t):
        x = point + t * direction
        return float(np.hypot(*x)) ** (k + 1) * f(np.arctan2(x[1], x[0]))

    ts = np.linspace(lo, hi, samples)
    vals = np.array([dist(t) for t in ts])
    best, step = float(vals.min()), (hi - lo) / (samples - 1)
    for i in np.argsort(vals)[:4]:  # polish the best samples (the distance is smooth along a side)
        res = minimize_scalar(dist, bounds=(max(ts[i] - step, lo), min(ts[i] + step, hi)), method="bounded",
                              options={"xatol": 1e-14 * max(1.0, hi - lo)})
        best = min(best, float(res.fun))
    return best


def _straight_run(X: np.ndarray, seg: int, t: float, closed: bool = False):
    """Around the point at fraction ``t`` of segment ``seg`` of the polyline ``X``: the unit direction, and
    the arclength back and forward to the ends of the straight run through it, each with ``True`` when that
    end is an end of the polyline (``False``: a bend; a closed polyline has bends only), and the point's
    arclength from the first vertex."""
    V = (np.roll(X, -1, axis=0) - X) if closed else np.diff(X, axis=0)
    L = np.hypot(V[:, 0], V[:, 1])
    u = V[seg] / L[seg]
    n = len(V)

    def straight(i):
        if not closed and not 0 <= i < n:
            return False
        w = V[i % n] / L[i % n]
        return abs(w[0] * u[1] - w[1] * u[0]) < 1e-12 and w @ u > 0

    back, i = t * L[seg], seg - 1
    while straight(i):
        back, i = back + L[i % n], i - 1
    fwd, j = (1.0 - t) * L[seg], seg + 1
    while straight(j):
        fwd, j = fwd + L[j % n], j + 1
    return (u, (back, not closed and i < 0), (fwd, not closed and j >= n),
            np.concatenate([[0.0], np.cumsum(L)])[seg] + t * L[seg])


def _crossing(p0, p1, q0, q1):
    """``(t, s)`` where segment ``p0 p1`` crosses segment ``q0 q1`` (fractions of each), or None.

    Raises ``ValueError`` for parallel segments that touch and for a crossing
    at or within 1e-9 (of the segments) of a vertex, where rounding could count
    it twice, or not at all.
    """
    u, v, w = p1 - p0, q1 - q0, q0 - p0
    lu, lv = np.hypot(*u), np.hypot(*v)
    den = u[0] * v[1] - u[1] * v[0]
    if abs(den) <= 1e-12 * lu * lv:  # parallel: apart (collinear pieces of one run), or no reference
        if shapely.distance(shapely.linestrings([p0, p1]), shapely.linestrings([q0, q1])) <= 1e-9 * (lu + lv):
            raise ValueError("parallel segments that touch")
        return None
    t = (w[0] * v[1] - w[1] * v[0]) / den
    s = (w[0] * u[1] - w[1] * u[0]) / den
    if not (-1e-9 <= t <= 1.0 + 1e-9 and -1e-9 <= s <= 1.0 + 1e-9):
        return None
    if min(t, 1.0 - t, s, 1.0 - s) <= 1e-9:
        raise ValueError("a crossing at a vertex")
    return t, s


def _rectangle_distances(alpha: float, k: int, a: float, b: float, c: float, d: float) -> tuple:
    """The distances from a crossing at angle ``alpha`` to the sides ``x1 = -a, b`` and ``x2 = -c, d`` of its
    rectangle of straight runs, in that order."""
    f = _profile(alpha, k)
    return (_side_distance(f, k, np.array([-a, 0.0]), np.array([0.0, 1.0]), -c, d),
            _side_distance(f, k, np.array([b, 0.0]), np.array([0.0, 1.0]), -c, d),
            _side_distance(f, k, np.array([0.0, -c]), np.array([1.0, 0.0]), -a, b),
            _side_distance(f, k, np.array([0.0, d]), np.array([1.0, 0.0]), -a, b))


def straight_crossings_reference(scene, k: int = 2) -> float:
    """``J`` of a scene of intervals whose crossings each see a component end before any bend.

    Not computed with ``direct``.  Every transversal crossing of two segments
    lies in a rectangle of ``M x M`` on which both deformed polylines are
    straight: the maximal straight runs through it, ``[-a, b] x [-c, d]`` in
    deformed arclength (for a polyline with itself, two different runs, whose
    parameter intervals meet at most at a bend: the rectangle lies in the
    triangle ``x1 < x2``).  There the metric is that of
    :func:`crossing_reference`, so the distance from the crossing to each side
    is the least of ``|x|^(k+1) f(theta)`` along it.  A side is part of the
    boundary of ``M x M`` when its run ends at an end of its polyline;
    otherwise at a bend, beyond which the metric differs.  When the nearest side
    is a true end (every bent side farther) and the rectangles of one piece are
    disjoint, every curve from the crossing point travels at least that
    distance before it leaves its rectangle, and the straight way to that end
    achieves it: ``J`` is twice the sum of those distances (both points of each
    crossing), whatever the matching could pair.

    Parameters
    ----------
    scene : direct.Scene
        Open components only.
    k : int, default 2
        Degree of ``rho``: ``k = q`` for ``G`` with power ``q``; ``k = 2 p``
        for ``g`` with power ``p`` on an isometric deformation.

    Returns
    -------
    float
        ``J`` (length units to the power ``k + 1``).

    Raises
    ------
    ValueError
        Where the argument does not apply: a closed component, a crossing at
        or within 1e-9 (of the segments) of a vertex, parallel segments that
        touch, a bend as near as every end, overlapping rectangles.
    """
    comps = scene.components
    if any(c.closed for c in comps):
        raise ValueError("intervals only")
    total, rects = 0.0, {}
    for ia, A in enumerate(comps):
        for ib in range(ia, len(comps)):
            P, Q = np.asarray(comps[ia].deformed, float), np.asarray(comps[ib].deformed, float)
            for i in range(len(P) - 1):
                for j in range(i + 2 if ia == ib else 0, len(Q) - 1):
                    hit = _crossing(P[i], P[i + 1], Q[j], Q[j + 1])
                    if hit is None:
                        continue
                    t, s = hit
                    ua, (a, end_a), (b, end_b), xa = _straight_run(P, i, t)
                    ub, (c, end_c), (d, end_d), xb = _straight_run(Q, j, s)
                    alpha = float(np.arccos(np.clip(ua @ ub, -1.0, 1.0)))
                    sides = list(zip(_rectangle_distances(alpha, k, a, b, c, d), (end_a, end_b, end_c, end_d)))
                    true = min((dist for dist, end in sides if end), default=np.inf)
                    bent = min((dist for dist, end in sides if not end), default=np.inf)
                    if not true < np.inf or not bent > true * (1.0 + 1e-9):
                        raise ValueError(f"crossing of {A.name} and {comps[ib].name}: a bend as near as every end")
                    rect = ((xa - a, xa + b), (xb - c, xb + d))
                    eps = 1e-9 * (a + b + c + d)  # rectangles that share a side (the runs meet at a bend) are disjoint
                    for other in rects.get((ia, ib), []):
                        if all(r[0] < q[1] - eps and q[0] < r[1] - eps for r, q in zip(rect, other)):
                            raise ValueError("overlapping rectangles")
                    rects.setdefault((ia, ib), []).append(rect)
                    total += 2.0 * true
    return total


def cylinder_reference(scene, k: int = 2, samples: int = 4000) -> float:
    """``J`` of an interval that crosses a polygon once: the curve must go to the end whose winding number changed.

    Not computed with ``direct``.  The piece of ``M x M`` of an interval ``I``
    and a circle ``C`` is a cylinder, whose boundary is the two circles
    ``{end} x C``.  ``j`` embeds both, so the reference polygon winds the same
    number of times ``w_j`` round every point of the reference interval; in
    the deformed scene it winds ``w(e)`` times round each end ``e`` of the
    interval, and one crossing changes it by one along the interval.  As for
    the turning number of a circle (Proposition 11), the curves of the pair's
    crossing point must end on the boundary circle of the end where ``w(e)``
    differs from ``w_j``: the flux of the current through that circle.  The
    crossing lies in the rectangle ``[-a, b] x [-c, d]`` of the interval (its
    sides ``x1 = -a, b`` the interval's ends) and of the straight run of the
    polygon through it (its sides ``x2 = -c, d`` at bends).  ``J`` is twice the
    distance (:func:`crossing_reference`'s profile) from the crossing to the
    side of the allowed end when that is at most the distance to either bent
    side (a curve that leaves the rectangle there is already longer) and at
    most the distance to the other end plus a lower bound of a curve across
    the cylinder from one boundary circle to the other (which a curve to the
    wrong end would need): ``int dist(phi(s), polygon)^k ds`` over the
    interval, each of ``samples`` stretches bounded below by its midpoint's
    distance less half its length (the distance is 1-Lipschitz).  The value
    is attained: the nearest point of a side lies on the branch of the
    profile's valley in that side's own half-plane (``f`` is symmetric about
    its cheapest direction and of period pi), so the way there keeps the sign
    of ``x1`` and does not meet the other end's side first, though that end
    may be nearer.  The polygon alone and the interval alone cross nothing
    and keep their turning numbers: their pieces add nothing.  A review (stop
    46) derived the condition from the proof of Proposition 11 on the
    cylinder (a closed form supported away from the boundary and the crossing
    is exact there, so the ends on each boundary circle count the flux
    through it, ``w(e) - w_j``), and found this function within 6e-10
    (relative) of ``direct`` at ``tol=1e-7`` on 109 random polygons of 3 to 8
    vertices, convex or not, either orientation.

    Parameters
    ----------
    scene : direct.Scene
        One open component, straight from end to end (collinear vertices
        allowed), and one closed polygon, simple in both embeddings and
        oriented alike in both.
    k : int, default 2
        As in :func:`straight_crossings_reference` (``g`` only for an
        isometric deformation).

    Returns
    -------
    float
        ``J`` (length units to the power ``k + 1``).

    Raises
    ------
    ValueError
        Where the argument does not apply: other components, a bent interval,
        a polygon that is not simple or turns the other way once deformed, a
        reference interval that meets its polygon, not exactly one crossing,
        a crossing within 1e-9 (of the segments) of a vertex, an allowed end
        farther than a bent side or than the other end with the crossing curve.
    """
    comps = scene.components
    opens = [c for c in comps if not c.closed]
    closed = [c for c in comps if c.closed]
    if len(opens) != 1 or len(closed) != 1:
        raise ValueError("one interval and one polygon")
    I_ref, I_def = np.asarray(opens[0].reference, float), np.asarray(opens[0].deformed, float)
    C_ref, C_def = shapely.Polygon(closed[0].reference), shapely.Polygon(closed[0].deformed)
    if not (C_ref.is_valid and C_def.is_valid):
        raise ValueError("a polygon that is not simple")
    if C_ref.exterior.is_ccw != C_def.exterior.is_ccw:
        raise ValueError("the polygon turns the other way once deformed (its turning number changed)")
    if shapely.intersects(shapely.linestrings(I_ref), C_ref.exterior):
        raise ValueError("the reference interval meets its polygon")
    ring = np.asarray(closed[0].deformed, float)
    crossings = [(i, j, *hit) for i in range(len(I_def) - 1) for j in range(len(ring))
                 if (hit := _crossing(I_def[i], I_def[i + 1], ring[j], ring[(j + 1) % len(ring)])) is not None]
    if len(crossings) != 1:
        raise ValueError(f"{len(crossings)} crossings, not one")
    i, j, t, s = crossings[0]
    u, (a, start_is_end), (b, end_is_end), _ = _straight_run(I_def, i, t)
    if not (start_is_end and end_is_end):
        raise ValueError("a bent interval")
    ub, (c, _), (d, _), _ = _straight_run(ring, j, s, closed=True)
    to_start, to_end, *bent_sides = _rectangle_distances(float(np.arccos(np.clip(u @ ub, -1.0, 1.0))), k, a, b, c, d)
    # a simple polygon winds once round the points inside it (either way, the same in both embeddings) and not
    # at all round the others: the winding number round an end changed where its inside-ness did
    inside_ref = C_ref.contains(shapely.Point(I_ref[0]))
    changed = [C_def.contains(shapely.Point(e)) != inside_ref for e in (I_def[0], I_def[-1])]
    if changed.count(True) != 1:
        raise ValueError("no end whose winding number changed alone")
    allowed, other = (to_start, to_end) if changed[0] else (to_end, to_start)
    length = a + b
    h = length / samples
    mids = I_def[0] + np.outer((np.arange(samples) + 0.5) * h, u)
    gaps = shapely.distance(shapely.points(mids), C_def.exterior)
    across = float(np.sum(np.maximum(gaps - 0.5 * h, 0.0) ** k) * h)
    if not (allowed * (1.0 + 1e-9) < min(bent_sides) and allowed < (other + across) * (1.0 - 1e-6)):
        raise ValueError("the allowed end is not the nearest way out")
    return 2.0 * allowed
