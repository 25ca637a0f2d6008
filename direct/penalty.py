r"""The penalty ``J(phi)`` by the direct method (section 5.1.1): the pipeline.

scene -> crossings (:mod:`direct.crossings`) -> pair domains and grid graphs
(:mod:`direct.grid`) -> grid geodesics (:mod:`direct.geodesics`) -> refined
geodesics, all the curves of a domain at once (:mod:`direct.refinement`),
the chosen ones refined again from other starts (:mod:`direct.starts`)
-> assignment program (34) (:mod:`direct.matching`)
-> :class:`Penalty`.

The refinement settles in the local geodesic its route leads to, so the
routes of a second grid (three quarters of the step from the default 128
cells up, the default grid below it: :func:`second_resolution`; at least 16
neighbours: :func:`second_neighbours`) give second
starts: from ``tol = 1e-4`` down, and below the default resolution, a whole
second solution (``second_pass``), otherwise a check of the chosen curves
only (``settings["route_check"]``: each second route straightened at the
coarse scale, refined where it is shorter than the refined curve).

Convention: ``value`` is ``J`` over the whole of ``M x M`` as in eq. (34):
each geometric crossing ``phi(x1) = phi(x2)`` gives the two signed points
``(x1, x2)`` and ``(x2, x1)``, so every curve ``gamma`` of one half of
``M x M`` has a mirror image in the other and both are listed in ``pairs``.

Circles: the conditions on gamma, derived from eq. (6)
------------------------------------------------------
The paper states ``Gamma(phi)`` for unions of intervals (Prop. 9, eq. (9))
and for one circle (Prop. 11, eq. (10)) and leaves the general case aside
(3.3.4).  All cases follow from one reading of eq. (6).  Let ``c`` be a
closed loop of ``M x M`` that avoids the crossing points and the diagonal,
and ``omega`` a closed 1-form supported in a thin tube around ``c``, the
Poincare dual of ``c``.  The left side of eq. (6), ``int_gamma omega ^ n``, is
the algebraic intersection number ``I(c, gamma)`` (sign ``det(c', gamma')``);
the right side is ``-1/2pi`` times the period ``P(c) = int_c Phi_phi`` (with
``Phi_phi = grad theta_phi - grad theta_j``, section 5.1.2).  So gamma is
admissible for eq. (6) if and only if, for every such loop,

    ``I(c, gamma) = -P(c) / 2 pi``.                                     (*)

Check on a small loop around a crossing point ``x`` of sign ``s``: there
``P(c) / 2 pi = sign det grad r_phi = -s`` (``grad r_phi = [phi'(x1),
-phi'(x2)]``), and (*) says that ``s`` curves end at ``x`` net: Prop. 9.
Curves run from the negative points (``gamma(0)``) to the positive ones
(``gamma(1)``).  The loops that remain generate the homology of each piece
of ``M x M`` modulo the crossing points:

* ``I_i x I_j``, and each triangle of ``I_i x I_i``: none; the boundary
  absorbs any number of ends: program (34).
* ``S^1 x I`` (a cylinder; local coordinates ``s`` around the circle and ``v``
  along the interval): the loop ``s -> (s, v0)`` below every crossing point.
  With ``e_s, e_v`` the local axes in the ``(x1, x2)`` plane, a curve going up
  through it counts ``det(e_s, e_v)``, so the net number of curves leaving the
  end circle ``v = 0`` is ``F0 = -det(e_s, e_v) P / 2 pi``, where ``P / 2 pi`` is
  the winding number of ``phi`` on the circle around ``phi(v0)`` on the
  interval, minus the same for ``j``.
* ``S^1 x S^1 \ Delta`` (one circle; local ``s = x1``, ``v = x2 - x1``): an
  annulus whose two boundary circles are the two sides of the diagonal.
  Near ``v = 0``, ``r_phi(s, s + v) ~ -v phi'(s)``, so ``P / 2 pi`` on the loop
  ``s -> (s, s + v0)`` is the turning number ``#phi`` minus ``#j``, and
  ``F0 = #j - #phi`` curves leave the side ``v = 0`` (``B_0^-``) net: this is
  eq. (10), with curves that cross the diagonal counted as one curve ending on
  one side and one starting on the other.
* ``S^1_i x S^1_j`` (a torus): the two seams ``s = 0`` and ``v = 0``; (*) fixes
  the total signed number of crossings of each seam by the family:
  ``K_s = P(seam s) / 2 pi`` (the winding number of ``phi_j`` around a point of
  ``phi_i``, minus the reference one) and ``K_v = -P(seam v) / 2 pi``.  Closed
  curves may be needed: the example ``(-M1) x {a}`` of section 3.3.4.

On the cylinder and the annulus (*) depends only on where curves end, so
each pair of terminals (boundary circles and crossing points) needs only its
shortest curve, and the least family is a min-cost flow with the supplies
above (:func:`direct.matching.solve_flow`); a curve from one boundary circle
to the other is allowed.  On the torus the shortest curve of each homotopy
class matters: distances come from a 3 x 3 block of the universal cover, and
a small integer program picks paths and closed curves whose classes add up to
``(K_s, K_v)`` (:func:`direct.matching.solve_torus`).  Within one piece, the
conditions are checked in the tests against brute-force enumeration, and
``J = 0`` exactly when no condition asks for a curve (Prop. 8), as on every
admissible deformation.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field, replace
from decimal import Decimal
from functools import partial
from typing import Any

import numpy as np
import shapely
from threadpoolctl import ThreadpoolController

from . import parallel
from .checks import is_real_number
from .crossings import Crossing, find_crossings
from .errors import DegenerateError, DegenerateMetricWarning, DirectError, SceneError, ToleranceWarning
from .geodesics import Backend, closed_curve_bounds, closed_curve_distances, grid_distances, torus_distances
from .grid import Domain, build_graph
from .matching import solve as solve_assignment
from .matching import solve_flow, solve_torus
from .metric import Metric, MetricName, _breaks, _vertex_params, get_metric
from .refinement import GeodesicJob, RefinedPath, coarse_geodesics, length_rounding, polyline_lengths, refine_many
from .scene import Scene
from .scenes import resolve
from .starts import (
    _TRANSPLANT,
    _alternative_starts,
    _best_of_starts,
    _chord_starts,
    _crease_starts,
    _family_shifts,
    _grounds,
    _leave_corners,
    _mirror_key,
    _mirror_of,
    _mirror_pairs,
    _mirrored,
    _more_starts,
    _ranked_loops,
    _reflected_starts,
    _restarted,
    _slid_ends,
    _straight_starts,
    _strip_starts,
    _transplanted_starts,
)
from .topology import exact_reversals, turning_number, winding_number

__all__ = ["penalty", "Penalty", "Pair", "second_resolution", "second_neighbours"]

#: searches from a crossing point stop at this factor times (its distance to the boundary + the largest one):
#: a curve between two points longer than sending both to the boundary is never used (see grid_distances);
#: the factor covers the grid's overestimate (at most 8 % with 8 neighbours) with a wide margin
_SEARCH_BOUND = 1.5

#: the rounding of a length's sums and extrapolation, relative (added to every curve's estimate: _rounding_errors)
_ARITHMETIC = 32 * np.finfo(float).eps

#: closed curves of a torus refined from this many starts each (see closed_curve_distances), the best kept: the
#: grid's closed curves of the class within its stencil bias (plus this margin) of the shortest, on routes apart
_CLOSED_STARTS = 6
_CLOSED_MARGIN = 0.01
#: ... searched through this many points of the seam; on a grid where the norm is not isotropic (a metric without
#: ``deformed_grid``: ``g``), through _WIDE_BASES points on each of _WIDE_LINES lines across the period (the seam
#: first), up to _WIDE_CANDIDATES grid curves a class, of which the _CLOSED_STARTS with the shortest coarse
#: geodesics are refined (see _ranked_loops)
_CLOSED_BASES = 24
_WIDE_BASES = 16
_WIDE_LINES = 4
_WIDE_CANDIDATES = 16
#: closed curves of one class whose refined lengths lie within this (relative) are one family of geodesics, shifted,
#: and their spread is added to the estimate (see _best_of_starts)
_CLOSED_FAMILY = 5e-4


#: crossings whose tangents make an angle with sine below this are grazing: their domain always gets a second pass
_GRAZING = 0.1

#: worst relative overestimate of grid distances by stencil (shared/NUMERICS.md), plus a margin for coarse grids
_STENCIL_BIAS = {8: 0.0824, 16: 0.0275, 32: 0.0131}

#: in _grid_lower_bounds, a refined entry's grid overestimate counts as a ratio for the entries whose grid length is
#: at most this many times its own; for the longer ones, as a ratio capped at 2 bias - 1 plus the rest as an amount
_LENGTH_CLASS = 10.0

#: the route check's searches on the second grid stop at this factor times the curve's length on the first grid
_ROUTE_CHECK_REACH = 2.0
#: the full second pass is the default from this tolerance down; above it the route check: on the 175 random scenes
#: of validation/default_tol.py it keeps tol=1e-3 within tol and within the estimate. With the check alone,
#: seeds 159 and 279 left tol=1e-4 6e-5 and 1.5e-4 off with estimates of 4.2e-5 and 1.6e-5 (279: an end that had
#: not slid into place, fixed since by the coarse pass's extra rounds; none of the 175 is now off by more than the
#: check's estimate at 1.01e-4, the farthest seed 185, 1.5e-5 against 1.6e-5)
_SECOND_PASS_TOL = 1e-4

#: below tol = _ROUGH_TOL / 10, an entry that a later round of _settle asks for is refined at _ROUGH_TOL first, and
#: enters at its rough length less _ROUGH_MARGIN times (its estimate + _ROUGH_TOL of it); only an entry asked for
#: again is refined in full. The star and wobbly circle at tol=1e-5: the rough refinement of its 84 entries took
#: 0.135 of the full one's time, and none came out farther above its full length than 0.39 of (estimate + 1e-3 of
#: it); at 1e-4, 0.29 of the time and up to 0.90. At tol=1e-3 (rough 1e-2) it saved nothing: 0.82 of the time on
#: the star and ellipse's 278 entries
_ROUGH_TOL = 1e-3
_ROUGH_MARGIN = 2.0

#: ``direct.penalty``'s default resolution (cells along the longer side of a pair domain); below it the default
#: computation runs as well (second_resolution)
_DEFAULT_RESOLUTION = 128


@dataclass(frozen=True)
class Pair:
    """One curve ``gamma`` of the optimal family: a matched pair of program (34).

    Attributes
    ----------
    components : tuple of str
        Names ``(M_a, M_b)`` of the domain ``M_a x M_b`` that holds the curve.
    start, end : tuple of float or None
        Parameters ``(x1, x2)`` of the negative point (``gamma(0)``) and of the
        positive point (``gamma(1)``); ``None`` where the curve ends freely on
        the boundary or the diagonal.
    start_crossing, end_crossing : int or None
        Index in :attr:`Penalty.crossings` of the geometric crossing of each end.
    length : float
        Length of the curve in the metric (refined, extrapolated).
    error_estimate : float
        Estimated absolute error of ``length``.
    path : (k, 2) ndarray
        The curve as a polyline in parameters ``(x1, x2)``, from ``gamma(0)``
        to ``gamma(1)``; on a circle the parameter is unwrapped (read it
        modulo the circle's length).
    closed : bool
        True for a closed curve ``gamma: S^1 -> M x M`` (section 3.3.4); its
        polyline then ends where it starts, up to whole turns.
    polyline_length : float
        The exact length of ``path`` itself in the metric (segment integrals,
        no extrapolation): ``length`` is Richardson-extrapolated from it and
        the coarser levels, and lies within ``error_estimate`` of it.
    """

    components: tuple[str, str]
    start: tuple[float, float] | None
    end: tuple[float, float] | None
    start_crossing: int | None
    end_crossing: int | None
    length: float
    error_estimate: float
    path: np.ndarray = field(repr=False)
    closed: bool = False
    polyline_length: float = float("nan")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (the path as a list of ``[x1, x2]``)."""
        return {
            "components": list(self.components),
            "start": None if self.start is None else list(self.start),
            "end": None if self.end is None else list(self.end),
            "start_crossing": self.start_crossing,
            "end_crossing": self.end_crossing,
            "length": self.length,
            "error_estimate": self.error_estimate,
            "closed": self.closed,
            "polyline_length": self.polyline_length,
            "path": self.path.tolist(),
        }


@dataclass(frozen=True)
class Penalty:
    """The result of :func:`penalty`.

    Attributes
    ----------
    value : float
        ``J(phi)`` over the whole of ``M x M`` (eq. (34); both points of each crossing).
        Units: length^(q + 1) for ``G = |y1 - y2|^(2 q) Id`` (length^3 by
        default: ``|r|^2`` times a deformed arclength), length^(2 p) times a
        reference length for ``g(s) = s^p``, length for ``euclid``.
    error_estimate : float
        Estimated absolute error of ``value``: the sum of the estimates of
        the refined geodesics (:func:`direct.refinement.refine_many`), plus
        the spread between the two solutions where a second pass runs (and,
        for a curve the route check refined again, the spread of its two
        starts when they settle within 1 % of each other), plus the rounding
        of ``r = phi(x1) - phi(x2)`` along each curve (:func:`_rounding_errors`:
        about 1e-15 of the value at the origin, more for a scene far from
        it or a crossing very close to an end); 0
        when no curve is needed (``J = 0``: no crossing, and no condition
        of a circle asks for a curve).  NaN with ``refine=False``: the grid value
        has no estimate (its stencil and sampling bias reach 9 % on the cases
        of ``validation/failures.md``, and many times ``J`` where the grid
        cannot follow a valley narrower than a cell: 6.2 times on the
        built-in ``hairpin``).
    grid_value : float
        The same program solved with the grid (Dijkstra) distances alone.
        An edge of length 0 weighs the smallest normal float (about
        2.2e-308: scipy's graphs drop zero weights), so a grid value of a
        few times 1e-308 means 0.
    upper_bound : float
        The exact length of the returned family of curves (the sum of the
        pairs' ``polyline_length``): a family with the boundary that eq. (9)
        asks for, so ``J <= upper_bound`` up to rounding, whatever the
        estimate says.  ``value`` (extrapolated) lies within
        ``error_estimate`` of it.
    crossings : list of Crossing
        The geometric crossings, each once (:func:`direct.find_crossings`).
    pairs : list of Pair
        The optimal matching, boundary included, on all of ``M x M``.
    settings : dict
        Metric and numerical settings used: the metric's name and
        parameters, ``tol``, ``resolution``, ``coarsen``, ``neighbours``,
        ``backend``, ``refine``, ``second_pass``, ``route_check`` (the
        chosen curves checked against a second grid's routes) and, where a
        grazing crossing forced a second pass, ``grazing_second_pass`` (the
        number of such domains); ``refined_again``, the number of domain
        solves whose chosen curves were refined a second time because the
        absolute tolerance taken from the grid's value was too loose (a
        grid that overestimates ``J`` many times over, in a narrow valley);
        ``deformed_arclength``, the names of the components computed in
        their deformed arclength (``G``: an interval whose speeds span more
        than 16, a closed component whose speeds differ at all);
        ``workers``, the processes asked for, where more than one, and
        ``workers_failed``, why the workers were not used.
    seconds : float
        Wall time of the computation.
    """

    value: float
    error_estimate: float
    grid_value: float
    upper_bound: float
    crossings: list[Crossing]
    pairs: list[Pair]
    settings: dict[str, Any]
    seconds: float

    @property
    def paths(self) -> list[np.ndarray]:
        """The optimal curves ``gamma`` in parameter space, one per pair: ``[pair.path for pair in pairs]``.

        Each a ``(k, 2)`` array of parameters ``(x1, x2)`` (reference arclength of the pair's two components).
        """
        return [p.path for p in self.pairs]

    def to_dict(self, scene: Scene | None = None) -> dict[str, Any]:
        """JSON-ready form of the result (what ``direct penalty --json`` prints, without the scene's header).

        Parameters
        ----------
        scene : Scene, optional
            The scene of the result: crossings then name their components
            (:meth:`direct.Crossing.to_dict`), otherwise give their indices.

        Returns
        -------
        dict
            ``value``, ``error_estimate``, ``grid_value``, ``upper_bound``,
            ``crossings``, ``pairs`` (:meth:`Pair.to_dict`), ``settings`` and
            ``seconds``, as the attributes of the same names.
        """
        crossings = [c.to_dict(scene) for c in self.crossings]
        return {
            "value": self.value,
            "error_estimate": self.error_estimate,
            "grid_value": self.grid_value,
            "upper_bound": self.upper_bound,
            "crossings": crossings,
            "pairs": [p.to_dict() for p in self.pairs],
            "settings": self.settings,
            "seconds": self.seconds,
        }

    def __repr__(self) -> str:
        return (
            f"Penalty(value={self.value!r}, error_estimate={rounded_up(self.error_estimate)}, "
            f"crossings={len(self.crossings)}, pairs={len(self.pairs)}, metric={self.settings.get('metric')!r})"
        )


def rounded_up(x: float, digits: int = 2) -> str:
    """``x`` in decimal, ``digits`` significant digits, rounded up: an error estimate or an upper bound printed.

    Printed to a few digits, a bound must not shrink: ``4.11e-08`` rounded to
    ``4.1e-08`` no longer covers an error of ``4.105e-08``.  The value beside
    it is printed in full (``repr``), so the two printed numbers keep the
    contract ``|value - J| <= error_estimate`` (an adversarial review: the
    text output of ``direct penalty`` rounded the value of ``cross`` to 7
    digits, 3.3e-9 off, beside an estimate printed as 1e-15).

    Parameters
    ----------
    x : float
        A non-negative number (an estimate, or an upper bound).
    digits : int, default 2
        Significant digits.

    Returns
    -------
    str
        The nearest decimal with ``digits`` significant digits that reads
        back as a float at least ``x`` (``repr(x)`` when ``x`` is 0,
        negative, or not finite).
    """
    if not np.isfinite(x) or x <= 0:
        return repr(float(x))
    text = f"{x:.{digits}g}"
    if float(text) < x:  # rounded down: one unit up in the last digit
        d = Decimal(text)
        text = f"{d + Decimal(1).scaleb(d.adjusted() - digits + 1):.{digits}g}"  # exact: not through a float
    return text


def domains(scene: Scene, crossings: list[Crossing]) -> list[Domain]:
    """The pieces of ``M x M`` that need curves, with their crossing points (see :mod:`direct.grid`).

    Every pair ``i <= j`` that carries crossing points, and every pair with a
    circle (its topological conditions may ask for curves without any
    crossing point); pairs of intervals without crossings are left out.
    For a circle with itself (the annulus) both points ``(x1, x2)`` and
    ``(x2, x1)`` of each crossing are in the domain, with opposite signs.
    """
    groups: dict[tuple[int, int], list[int]] = {}
    for k, c in enumerate(crossings):
        groups.setdefault(tuple(c.components), []).append(k)
    comps = scene.components
    pairs = set(groups)
    for i in range(len(comps)):
        for j in range(i, len(comps)):
            if comps[i].closed or comps[j].closed:
                pairs.add((i, j))
    out = []
    for i, j in sorted(pairs):
        ids = groups.get((i, j), [])
        pts = [crossings[k].params for k in ids]
        signs = [crossings[k].sign for k in ids]
        if i == j and comps[i].closed:
            pts += [crossings[k].params[::-1] for k in ids]
            signs += [-crossings[k].sign for k in ids]
            ids = ids + ids
        out.append(
            Domain((i, j), (comps[i], comps[j]), np.array(pts, dtype=float).reshape(-1, 2),
                   np.array(signs, dtype=int), np.array(ids, dtype=int))
        )
    return out


def _in_deformed_arclength(scene: Scene, crossings: list[Crossing]) -> tuple[Scene, list[Crossing]]:
    """The scene with its unevenly stretched components parametrized by deformed arclength, and its crossings there.

    ``J^G`` does not depend on the parametrization (Prop. 18), but the grids
    and the refinement do: a curve straight in the parameters bends, in the
    deformed arclength (where the length element of ``G`` is isotropic), on
    every vertex line where the speed ``|phi'|`` jumps.  Where the speeds of
    a component's segments span more than ``_SPREAD`` (largest over
    smallest), the component is parametrized by its deformed arclength:
    reference segments of 20 and 0.005 for deformed ones of 1.2 and 0.9 had
    the geodesic to the far side of the domain lose to one 2.7e-3 longer,
    with an estimate of 1.8e-6 (an adversarial review).  A component within
    that spread keeps its reference arclength: the studies validated the
    pipeline there, and the deformed arclength is no better everywhere
    (interval seed 138 of ``validation/default_tol.py``, speeds within 15:
    its grids then route a curve to the longer of two local geodesics across
    a crease, 7.7e-4 above, with an estimate of 8e-6 at ``tol=1e-5``).  A
    closed component goes into its deformed arclength whenever its speeds
    differ at all (``_CLOSED_SPREAD``): the grid of the annulus (the
    component with itself) is uniform in the reference arclength, whose
    unequal speeds squeeze its stencil's directions (a limaçon at 24
    vertices, speeds 1 and 12 on its two halves: 3.1e-3 above ``J`` with
    an estimate of 8.1e-7; a figure eight at 20, speeds alternating 1 and
    12, reversed: 4.8e-4 above, estimate 4.7e-5; an adversarial review at
    stop 30, ``test_a_closed_curve_in_uneven_reference_speeds``).  A
    segment shorter than ``_COLLAPSED`` times its component's mean deformed
    segment spans that much parameter; a component collapsed to a point
    keeps its reference arclength.  That floor is only for segments that
    have collapsed (length 0, or rounding): a floor of ``1e-3`` made a loop
    1e-7 across on an interval of length 2, listed with equal reference
    segments, come out 57 % above ``J`` with an estimate of 9e-4, without a
    warning (its two loop segments got 6.7e-4 of parameter each, speeds
    6,700 times apart again; a review at stop 48,
    ``test_a_tiny_loop_in_uneven_reference_speeds``).
    """
    comps = []
    for c in scene.components:
        d = np.linalg.norm(np.diff(c.deformed_ring, axis=0), axis=1)
        speed = d / c.segment_lengths
        moving = speed[speed > 0]
        spread = _CLOSED_SPREAD if c.closed else _SPREAD
        if moving.size and moving.max() > spread * moving.min():
            c = c.reparametrized(np.maximum(d, _COLLAPSED * float(d.mean())))
        comps.append(c)
    if not any(hasattr(c, "source") for c in comps):
        return scene, crossings
    moved = []
    for x in crossings:
        params = tuple(float(comps[i].params[k] + (p - scene.components[i].params[k])
                             * (comps[i].segment_lengths[k] / scene.components[i].segment_lengths[k]))
                       for i, k, p in zip(x.components, x.segments, x.params))
        moved.append(replace(x, params=params))
    return Scene(tuple(comps), name=scene.name), moved


#: a component whose segments' speeds |phi'| span more than this is computed in its deformed arclength (for G)
_SPREAD = 16.0
#: the same for a closed component: any spread beyond rounding (its annulus grid, see _in_deformed_arclength)
_CLOSED_SPREAD = 1.0 + 1e-9
#: the least parameter width of a segment in the deformed arclength, relative to its component's mean segment: a
#: collapsed one's (1e-3 distorted loops 1e-7 across, see _in_deformed_arclength; at 1e-9, loops 1e-11 across)
_COLLAPSED = 1e-12


def _crossing_point(crossing: Crossing, point: np.ndarray) -> tuple[float, float]:
    """The parameters of ``crossing`` in the order of a domain's ``point`` (its mirror image on an annulus)."""
    x = tuple(map(float, crossing.params))
    return x if point[0] <= point[1] or crossing.components[0] != crossing.components[1] else x[::-1]


def _to_reference(comps, path: np.ndarray, start, end) -> np.ndarray:
    """A polyline in the parameters of ``comps`` as the same curve in reference arclength.

    Its segments are cut where they cross a vertex line (the map is affine
    between them, so every piece stays straight), then mapped; the ends are
    set to the crossing points ``start`` / ``end`` when given.
    """
    if not any(hasattr(c, "source") for c in comps):
        return path
    P, Q = path[:-1], path[1:]
    edges, ts = [np.arange(len(P))], [np.zeros(len(P))]
    for axis, c in enumerate(comps):
        lo, hi = np.minimum(P[:, axis], Q[:, axis]), np.maximum(P[:, axis], Q[:, axis])
        vp = _vertex_params(c, float(lo.min()), float(hi.max())) if len(P) else np.empty(0)
        e, t = _breaks(vp, P[:, axis], Q[:, axis])
        edges.append(e)
        ts.append(t)
    e, t = np.concatenate(edges), np.concatenate(ts)
    order = np.lexsort((t, e))
    e, t = e[order], t[order]
    pts = np.vstack([P[e] + t[:, None] * (Q[e] - P[e]), path[-1:]])
    out = np.column_stack([comps[0].reference_arclength(pts[:, 0]), comps[1].reference_arclength(pts[:, 1])])
    for row, point in ((0, start), (-1, end)):
        if point is None:
            continue
        for axis, c in enumerate(comps):  # the crossing's parameter, as many turns on as the curve's end
            period = float(c.reference_arclength(c.length)) if c.closed else 0.0
            turns = np.round((out[row, axis] - point[axis]) / period) if period else 0.0
            out[row, axis] = point[axis] + turns * period
    return out


def _min_sine(domain: Domain, crossings: list[Crossing]) -> float:
    """The smallest ``|sin|`` of the angle between the deformed tangents at the crossings of a domain."""
    out = 1.0
    ci, cj = domain.comps
    for k in set(domain.crossing_ids.tolist()):
        a = ci.velocities[crossings[k].segments[0]]
        b = cj.velocities[crossings[k].segments[1]]
        out = min(out, abs(float(a[0] * b[1] - a[1] * b[0])) / (float(np.hypot(*a) * np.hypot(*b)) or 1.0))
    return out


def _period(domain: Domain, level: float) -> int:
    """Period of ``Phi_phi / 2 pi`` on the loop ``s -> (s, level)`` (local coordinates), minus the reference one.

    This is the winding number of ``r_phi`` along the loop minus that of ``r_j``
    (section 5.1.2: ``Phi_phi = grad theta_phi - grad theta_j``).
    """
    ci, cj = domain.comps
    kind = domain.kind
    if kind == "annulus":
        # near the diagonal r(s) ~ -v phi'(s): the turning number (Remark 10)
        tips = exact_reversals(ci.deformed)
        if tips.size:
            k = int(tips[0])
            raise DegenerateError(
                f"the deformed polyline of component {ci.name!r} turns exactly back on itself at vertex {k} (a "
                "spike, traversed out and back along the same line): its turning number depends on which side "
                "the generic perturbation puts the way back, and the crossings of the spike's base may be decided "
                f"otherwise (a rotation of the scene changed J from 0 to 14.5). Move vertex {k} off the line of its "
                "neighbours, by a little more than rounding."
            )
        return turning_number(ci.deformed, _polyline(ci, "deformed")) - turning_number(ci.reference,
                                                                                         _polyline(ci, "reference"))
    if kind == "torus" or domain.comps[0].closed:
        # s runs along circle i, x2 = level on component j
        p, q = cj.phi(level), cj.j(level)
        return (winding_number(ci.deformed, p, _polyline(ci, "deformed", cj, level))
                - winding_number(ci.reference, q, _polyline(ci, "reference", cj, level)))
    p, q = ci.phi(level), ci.j(level)  # s runs along circle j, x1 = level on interval i
    return (winding_number(cj.deformed, p, _polyline(cj, "deformed", ci, level))
            - winding_number(cj.reference, q, _polyline(cj, "reference", ci, level)))


def _polyline(comp, which: str, other=None, level: float | None = None) -> str:
    """How error messages of :mod:`direct.topology` name a polyline (and the point of another component)."""
    out = f"the {which} polyline of component {comp.name!r}"
    if other is not None:
        out += f" (the point is component {other.name!r} at reference arclength {other.reference_arclength(level):.6g})"
    return out


def _free_level(values: np.ndarray, period: float | None, length: float, on=None, other=None,
                gap: tuple[float, float] | None = None) -> float:
    """A level in the gap of ``values`` that contains 0 (periodic) or below all of them (not periodic).

    With ``gap`` (``(lo, hi)``, not periodic), in that gap instead (:func:`_interval_level`).

    Every level of the gap gives the same loop class, hence the same period
    of eq. (6), as long as the point it puts on one curve is off the other.
    With ``on`` and ``other`` (components: the level is a reference
    arclength of ``on``), the level is the one of ``_LEVEL_SAMPLES`` spread
    over the gap whose deformed point ``on.phi(level)`` lies farthest from
    ``other``'s deformed polyline: a level on a stretch where the two curves
    touch without crossing made the winding number a matter of rounding
    (touching triangles: 0 crossings and ``J = 267`` with no warning; an
    adversarial review), or raised a DegenerateError that depended only on
    which vertex a closed curve started at.  Where every level of the gap
    lies on the other curve, a DegenerateError is raised
    (:func:`_interval_level` then tries an interval's other gaps).
    """
    if gap is not None:
        lo, hi = gap
    elif len(values) == 0:
        lo, hi = 0.0, length
    elif period is None:
        lo, hi = 0.0, float(np.min(values))
    else:  # the gap across 0: from the largest value to the smallest one a period on (values lie in [0, period))
        lo, hi = float(np.max(values)), period + float(np.min(values))
    levels = lo + (hi - lo) * (np.arange(_LEVEL_SAMPLES) + 0.5) / _LEVEL_SAMPLES
    if period is not None:
        levels = np.mod(levels, period)
    if on is None:
        return float(levels[_LEVEL_SAMPLES // 2])
    curve = (shapely.linearrings if other.closed else shapely.linestrings)(np.asarray(other.deformed, dtype=float))
    room = shapely.distance(shapely.points(on.phi(levels)), curve)
    best = int(np.argmax(room))
    scale = max(float(np.abs(np.asarray(c.deformed, dtype=float)).max()) for c in (on, other))
    if not room[best] > _CLEAR * scale:
        # every level of the gap lies where the curves touch: the winding number would be rounding's choice
        raise DegenerateError(
            f"the deformed polyline of component {on.name!r} runs along that of component {other.name!r}, touching "
            "it without crossing, wherever the topological condition of this pair could be read (every stretch "
            "from its ends to its crossings and between them, or around the circle): it cannot be read off a "
            "point of it. Move one of the two curves off the other along one of those stretches."
        )
    return float(levels[best])


def _interval_level(domain: Domain, values: np.ndarray, length: float, on, other) -> tuple[float, int]:
    """A level of a cylinder's interval off the circle, and the sum of the ``s`` of the crossings below it.

    For :func:`boundary_conditions`: the period it needs is the one below
    all the crossings.  Where the interval's point crosses the circle, the
    winding number jumps by ``-s`` (``s = sign det(phi_i', phi_j')``, ``i``
    the interval), so that period is the one read at any level plus the
    sum of the ``s`` of the crossings below the level.  The gaps tried: below
    the first crossing (:func:`_free_level`'s own), then beyond the last,
    then between crossings, the widest first.  The first can lie on the
    circle: an interval that starts on it, a contact the perturbation may
    count as a crossing at 0 (refused in some listings only, a review at
    stop 49; with both ends on it, a code review).  Its DegenerateError
    stands where no gap has a level off the circle.
    """
    order = np.argsort(values, kind="stable")
    v = values[order]
    s = (domain.signs * (1 if on is domain.comps[0] else -1))[order]
    lows = np.concatenate([[0.0], v])  # gap k runs from lows[k] to highs[k], with the first k crossings below it
    highs = np.concatenate([v, [length]])
    first = None
    for k in list(dict.fromkeys([0, len(v)])) + sorted(range(1, len(v)), key=lambda k: (lows[k] - highs[k], k)):
        try:
            return _free_level(values, None, length, on, other, gap=(lows[k], highs[k])), int(s[:k].sum())
        except DegenerateError as err:
            first = first or err
    raise first


#: levels tried by _free_level for the one farthest from the other curve
_LEVEL_SAMPLES = 65
#: a level closer than this (relative to the coordinates' size) to the other curve lies on it, up to rounding
_CLEAR = 64 * np.finfo(float).eps


def boundary_conditions(domain: Domain) -> dict[str, Any]:
    """The topological conditions of eq. (6) on a domain with a circle.

    Returns
    -------
    dict
        For a cylinder or annulus: ``{"flux": F0}``, the net number of curves
        that leave boundary part 0 (``v = 0``).  For a torus:
        ``{"winds": (K1, K2)}``, the total signed number of times the curves
        cross the seams ``s = 0`` and ``v = 0``.  Empty for intervals.

    Notes
    -----
    The condition of eq. (6) on a loop ``c`` of ``M x M`` that avoids the
    crossing points says that the algebraic intersection number of ``gamma``
    with ``c`` is ``-1 / 2 pi`` times the period of ``Phi_phi`` on ``c``
    (the sign follows from Prop. 9 on a small loop around a crossing point,
    where the period is ``sign det grad r_phi = -s``).  With a loop
    ``s -> (s, v0)`` below every crossing point, oriented by ``s``, whose
    intersection with a curve going up is ``det(e_s, e_v)`` (the orientation
    of the local coordinates), the net number of curves leaving the
    boundary ``v = 0`` is ``F0 = -det(e_s, e_v) * period``.  For the circle
    with itself this reads ``F0 = #j - #phi`` (Prop. 11, eq. (10)).  On a
    torus the loops are the two seams.
    """
    kind = domain.kind
    if kind in ("rect", "triangle"):
        return {}
    st = domain.to_local(domain.points) if len(domain.points) else np.empty((0, 2))
    S, V = domain.local_lengths
    sign = round(float(np.linalg.det(domain.basis)))
    ci, cj = domain.comps
    if kind in ("cylinder", "annulus"):
        if kind == "cylinder":  # the interval's point at the level, away from the circle
            on, other = (cj, ci) if ci.closed else (ci, cj)
            v0, below = _interval_level(domain, st[:, 1], V, on, other)
        else:
            v0, below = _free_level(st[:, 1], None, V), 0
        level = domain.to_param(np.array([[0.0, v0]]))[0][1 if domain.basis[1, 1] else 0]
        return {"flux": -sign * (_period(domain, level) + below)}
    # torus: seam s = 0 is the loop v -> (s0, v); seam v = 0 the loop s -> (s, v0)
    s0 = _free_level(st[:, 0], S, S, ci, cj)
    v0 = _free_level(st[:, 1], V, V, cj, ci)
    k1 = (winding_number(cj.deformed, ci.phi(s0), _polyline(cj, "deformed", ci, s0))
          - winding_number(cj.reference, ci.j(s0), _polyline(cj, "reference", ci, s0)))
    k2 = -(winding_number(ci.deformed, cj.phi(v0), _polyline(ci, "deformed", cj, v0))
           - winding_number(ci.reference, cj.j(v0), _polyline(ci, "reference", cj, v0)))
    return {"winds": (int(k1), int(k2))}


def _settle(grid_costs: dict, solve, refine_keys, bias: float, finish=None, cache: dict | None = None,
            finished: set | None = None, complete=None, foresee=None, rough=None, roughly: dict | None = None):
    """Solve, refine the chosen curves, re-solve with refined lengths until the choice is refined.

    ``refine_keys(keys)`` refines the curves of several entries at once (one
    batch per round: :func:`direct.refinement.refine_many`).  Once the
    choice is made of refined entries, ``finish(keys, cache)`` may refine its
    entries again from more starts (``{key: RefinedPath}``, no longer than
    before; on a torus also entries not chosen, :func:`direct.starts._transplanted_starts`,
    which can change the choice) and the program is solved again until the
    choice is finished.

    Entries not refined yet enter as optimistic lower estimates: the grid
    length over ``bias``, or over the overestimate the grid showed on the
    entries refined so far, with a margin, when that is larger (coarse grids
    overestimate more than the stencil's bias), a short curve's counted partly
    as an amount (:func:`_grid_lower_bounds`); so a choice made of refined
    entries is not beaten by an unrefined one as long as these bounds hold.
    They are estimates drawn from the curves refined so far, not proofs (see
    :func:`_grid_lower_bounds` for one that failed, harmlessly).  From the second round on,
    the entries the next solves would ask for are refined in the same batch
    (:func:`_foreseen`, through ``foresee(costs)``, by default ``solve``; on
    a torus one pass of the program instead of
    :func:`direct.matching._two_stage`'s two).  ``cache`` and ``finished`` may bring entries
    refined, and finished, already; ``roughly`` entries refined at a looser
    tolerance (the chosen curves :func:`_solve_domain` refines again with the
    refined value's absolute tolerance), which enter as roughly refined ones
    (below) and are refined in full when a solve asks for them.

    ``finish(keys, cache, promote)`` gets a ``promote(wanted)`` that refines
    in full, into ``cache``, the roughly refined entries (below) for which
    ``wanted(key, rough_path)`` holds: its checks of entries not chosen (the
    shifted starts of curves between the grounds, the slid ends, the
    transplanted starts of a torus, the mirror images) look at the refined
    entries, and must see those the refinement of every entry in full would
    have given them (a code review of the first version).

    ``rough(keys)``, where given, refines entries at the looser
    ``_ROUGH_TOL``: after the first batch (refined in full), an entry a solve
    asks for is refined roughly, and enters the next solves at its rough
    length less ``_ROUGH_MARGIN`` times its estimate plus ``_ROUGH_TOL`` of
    it (:func:`_rough_cost`), an optimistic estimate of its full length; only
    an entry asked for again at that cost (by a solve, or a trial solve of
    :func:`_foreseen`) is refined in full.  Most entries
    that a loose lower bound brings in are long curves that lose the choice:
    on the star and wobbly circle (``validation/star_wobbly_circle.json``) at
    ``tol=1e-5`` the rough refinement costs a seventh of the full one.

    ``grid_costs`` may hold lower bounds for entries not searched yet (the
    closed curves of a torus, :func:`direct.geodesics.closed_curve_bounds`).
    Before entries are refined, ``complete(keys)`` replaces the bounds among
    them by grid lengths (in ``grid_costs``) and says whether it did; the
    round is then solved again.  A bound is at most the grid length, so as long as no solve picks a bounded entry, every
    choice is the one the grid lengths would give.
    """
    cache = {} if cache is None else dict(cache)
    finished = set() if finished is None else set(finished)
    roughly = {} if roughly is None else dict(roughly)  # entries refined at _ROUGH_TOL only (or a looser atol)
    first = True  # the first batch is refined in full (the grid's choice, most of it final)
    for _ in range(3 * len(grid_costs) + 2):
        # the grid's overestimate seen on the refined entries (roughly refined too), with a margin, bounds the others'
        # below
        todo = [k for k in grid_costs if k not in cache and k not in roughly]
        seen = [(grid_costs[k], rp.length) for k, rp in cache.items()]
        seen += [(grid_costs[k], rp.length) for k, rp in roughly.items() if k not in cache]
        lower = dict(zip(todo, _grid_lower_bounds(np.array([grid_costs[k] for k in todo]), seen, bias).tolist()))
        costs = {k: (cache[k].length if k in cache else _rough_cost(roughly[k]) if k in roughly else lower[k])
                 for k in grid_costs}
        value, chosen = solve(costs)
        missing = [k for k, _ in chosen if k not in cache]
        if missing:
            if cache:
                missing = _foreseen(missing, costs, cache, solve if foresee is None else foresee)
            if complete is not None and complete(missing):
                continue
            new = [] if rough is None or first else [k for k in missing if k not in roughly]
            full = [k for k in missing if k not in new]
            if full:
                cache.update(zip(full, refine_keys(full)))
            if new:
                roughly.update(zip(new, rough(new)))
            first = False
            continue
        todo = [k for k, _ in chosen if k not in finished] if finish is not None else []
        if not todo:
            return value, chosen, cache
        cache.update(finish(todo, cache, partial(_promote, cache, roughly, refine_keys)))
        finished.update(todo)
    raise DirectError("the choice of refined geodesics did not settle")  # pragma: no cover


def _promote(cache: dict, roughly: dict, refine_keys, wanted) -> None:
    """Refine in full, into ``cache``, the entries of ``roughly`` not in it for which ``wanted(key, rough)`` holds."""
    keys = [k for k, rp in roughly.items() if k not in cache and wanted(k, rp)]
    if keys:
        cache.update(zip(keys, refine_keys(keys)))


def _tolerances(tol: float, atol: float, rough: bool) -> tuple[float, float]:
    """``(tol, atol)`` of a refinement, or of a rough one (at ``_ROUGH_TOL``, ``atol`` scaled alike; see _settle)."""
    return (_ROUGH_TOL, atol * _ROUGH_TOL / tol) if rough else (tol, atol)


def _rough_cost(rp: RefinedPath) -> float:
    """An entry's optimistic length from its rough refinement (at ``_ROUGH_TOL``; see :func:`_settle`).

    Also that of an entry refined at a looser absolute tolerance, to be refined again (``_settle``'s
    ``roughly``, from :func:`_solve_domain`): a wider margin than its own estimate needs.

    The rough length less ``_ROUGH_MARGIN`` times its estimate plus
    ``_ROUGH_TOL`` of it, at least 0.  The full refinement starts again
    from the grid's route, runs its rounds to the finer tolerance and goes on
    through more levels, and can end lower than the rough estimate says
    (crossing vertex lines at finer kinks): on the star and wobbly circle by
    up to 0.39 of the estimate plus ``_ROUGH_TOL`` of the length, 3.8 times
    the estimate alone.  A measured margin, not a bound.
    """
    return max(rp.length - _ROUGH_MARGIN * (rp.error_estimate + _ROUGH_TOL * rp.length), 0.0)


def _grid_lower_bounds(grid: np.ndarray, refined: list, bias: float) -> np.ndarray:
    """Optimistic lengths of entries not refined yet, from their grid lengths and the refined entries' (see _settle).

    Parameters
    ----------
    grid : (m,) ndarray of float
        Grid lengths ``G`` of the entries to bound (``inf`` for none).
    refined : list of (float, float)
        ``(G_k, L_k)``: grid and refined length of each refined entry.
    bias : float
        The stencil's worst overestimate factor, with a margin (``1 + _STENCIL_BIAS + 0.05``).

    Returns
    -------
    (m,) ndarray of float
        ``max(G - A, 0) / b``, from the ratios ``r_k = G_k / L_k`` of the
        refined entries.  Those at least a ``_LENGTH_CLASS``-th as long as the
        entry (grid lengths) count whole: ``b`` is at least 1.02 times their
        largest ratio.  Those shorter count up to ``r_cap = 2 bias - 1``
        (1.155 with 16 neighbours) in ``b``, and the rest of their excess,
        ``G_k - r_cap L_k``, as an amount: ``A`` is 1.02 times the largest.
        ``b`` is never below ``bias``.  Every refined entry bounded this way,
        at its own grid length, gets at most its refined length over 1.02.

    Notes
    -----
    The grid overestimates a curve in two ways.  Along the curve its stencil,
    the cells of a coarse grid and the valleys of ``rho`` narrower than a cell
    add a fraction of the length, which carries over to curves of any length:
    a ratio (up to 1.10 on the second pass's grid of three quarters of the
    step, seed 172 of ``validation/default_tol.py`` at ``tol=1e-4``, on
    curves of all lengths).  Near a crossing point, where ``rho`` vanishes, the grid route
    cannot follow the geodesic within a cell or two, at a cost of the order
    of those cells: an amount, which makes the ratio of a curve much shorter
    than a cell large (4 on seed 244: 1.2e-4 refined, 4.6e-4 on the grid).
    Applied as a ratio to every entry, it made the program ask for the
    refinement of 39 entries where 9 settle the choice (21 s instead of
    3.8 s, the same value).  A short curve's ratio beyond ``2 bias - 1``
    (twice ``bias - 1``, the stencil's overestimate plus the 5 % margin for
    coarse grids) is not taken to come from the stencil or a coarse cell,
    and is passed on as the amount it costs; a short curve with a large excess in absolute terms (a
    valley) still lowers every longer entry's bound by that excess.  Like
    the single ratio it replaces, this is an estimate of the grid's error
    drawn from the curves refined so far, with a 2 % margin, not a proof:
    on seed 209 at ``tol=1e-4`` the second pass's grid put a curve 52 %
    over its refined length while the one longer refined curve showed 5 %,
    and the bound passed it over.  That curve runs along the boundary, as
    long (to 6e-8) as the two curves through the boundary that the program
    took instead: the value moved by 9.4e-10 (``validation/same_values.py``).
    """
    grid = np.asarray(grid, dtype=float)
    pts = [(G, L) for G, L in refined if L > 0 and np.isfinite(G)]
    if not pts:
        return grid / bias
    pts.sort()
    Gk = np.array([G for G, _ in pts])
    Lk = np.array([L for _, L in pts])
    ratio = Gk / Lk
    cap = 2.0 * bias - 1.0
    rest = np.maximum(Gk - cap * Lk, 0.0)
    # entries at least a class-th as long as G: a suffix of the sorted refined entries; the shorter ones: the prefix
    with np.errstate(invalid="ignore"):  # inf / inf (an unreached entry, _LENGTH_CLASS infinite): nan sorts last
        first = np.searchsorted(Gk, grid / _LENGTH_CLASS, side="left")
    long_ratio = np.append(np.maximum.accumulate(ratio[::-1])[::-1], 0.0)[first]
    short_ratio = np.concatenate([[0.0], np.maximum.accumulate(np.minimum(ratio, cap))])[first]
    b = np.maximum(bias, 1.02 * np.maximum(long_ratio, short_ratio))
    A = 1.02 * np.concatenate([[0.0], np.maximum.accumulate(rest)])[first]
    return np.maximum(grid - A, 0.0) / b


def _foreseen(missing: list, costs: dict, refined, solve, most: int = 8) -> list:
    """The missing entries and those the next solves would ask for, to refine in one batch.

    Once refined lengths have changed the choice, each round of
    :func:`_settle` may bring in new entries whose optimistic costs beat the
    refined ones: on a symmetric scene every point in turn (the 15-vertex
    star polygon of ``validation/failures.py``: 32 batches of refinement,
    6 with this).  This
    foresees them: the batch's entries get lengths 2 % above their optimistic
    costs (the margin of those costs) and the program is solved again, up to
    ``most`` times, collecting the unrefined entries each solve asks for.
    Only which entries are refined together changes, not the rule that makes
    the choice.
    """
    batch = new = list(missing)
    trial = dict(costs)
    for _ in range(most):
        for k in new:  # each entry's trial length is set once
            trial[k] = 1.02 * costs[k]
        _, chosen = solve(trial)
        new = [k for k in dict.fromkeys(k for k, _ in chosen) if k not in refined and k not in batch]
        if not new:
            break
        batch = batch + new
    return batch


def _rounding_errors(domain: Domain, metric: Metric, curves: list) -> tuple[np.ndarray, np.ndarray]:
    """Bounds on the rounding errors of each curve's length: ``(of r, of the sums)``, each ``(m,)``, length units.

    Of ``r = phi(x1) - phi(x2)``: :func:`direct.refinement.length_rounding`,
    ``2 (order + 1) eps scale / R`` of the length along a curve on which
    ``|r|`` grows to ``R``.  Negligible for a scene at the origin (about
    1e-15), it is what is left of the digits when the scene lies far from
    the origin (``cross60`` translated by 1e12: 1.8e-4 off, estimate 2.6e-6
    relative, before this term) or a crossing lies very close to the end of
    a component (``cross(1e-12, 1, 1, 1)`` with ``g``: 1.5e-4 off; an
    adversarial review).  Every curve also gets ``_ARITHMETIC`` of its
    length for the rounding of the sums themselves (the right angle with
    ``g``, computed exactly but for rounding: 5.6e-16 off with an estimate of
    2.8e-17 before these terms).
    """
    lengths = np.array([max(float(c[3]), 0.0) if np.isfinite(c[3]) else 0.0 for c in curves])
    arithmetic = _ARITHMETIC * lengths
    out = np.array([length_rounding(domain, metric, c[2], L) if L > 0 else 0.0 for c, L in zip(curves, lengths)])
    return out, arithmetic


def _solve_domain(domain: Domain, metric: Metric, settings: dict, backend: Backend, do_refine: bool):
    """Optimal family of curves on one domain: ``(value, grid_value, error, curves, refined_again)``.

    ``refined_again`` says whether the chosen curves were refined a second time with the refined value's
    absolute tolerance.  ``curves`` lists ``(start, end, polyline, length, error, closed)`` with
    ``start``/``end`` a point index, ``("ground", g)`` or ``None`` (closed curve).
    """
    # local refinement on the pieces of two intervals only: around a circle the coarse lattice changed which closed
    # geodesic the figure eight settles in (fig10 at 128 cells: 6.2e-5 higher than every other grid, beyond the
    # estimate of 1.8e-5, and twice as slow), so domains with a circle keep the uniform grid
    coarsen = settings["coarsen"] if domain.kind in ("rect", "triangle") else 1
    slid: set = set()  # entries refined again with their end slid along the diagonal (_slid_ends)
    shifted: set = set()  # curves between the grounds refined again from their family's shifts (finish)
    graph = build_graph(domain, metric, settings["resolution"], settings["neighbours"], coarsen=coarsen)
    cell = float(graph.cell.max())
    ng = domain.n_grounds
    pos = np.flatnonzero(domain.signs > 0)
    neg = np.flatnonzero(domain.signs < 0)
    tol = settings["tol"]
    bias = 1.0 + _STENCIL_BIAS.get(settings["neighbours"], 0.1) + 0.05
    cond = boundary_conditions(domain)

    if domain.kind == "torus":
        T, troute = torus_distances(graph, backend)
        K = cond["winds"]
        grid_costs = {
            (i, j, c): float(T[c][neg[j], pos[i]]) for c in T for i in range(len(pos)) for j in range(len(neg))
        }
        # closed curves enter at lower bounds of their grid lengths; the searches for them (most of the time on
        # a torus: 2.8 of 3.5 s on two overlapping 32-gons) run only once the program picks one (see _settle),
        # for the classes picked only
        grid_costs.update({("closed", c): b for c, b in closed_curve_bounds(graph).items()})
        loops: dict = {}

        def complete(keys):
            classes = sorted({k[1] for k in keys if k[0] == "closed" and k[1] not in loops})
            if not classes:
                return False
            margin = _STENCIL_BIAS.get(settings["neighbours"], 0.1) + _CLOSED_MARGIN
            if metric.deformed_grid:
                found = closed_curve_distances(graph, max_bases=_CLOSED_BASES, most=_CLOSED_STARTS, classes=classes,
                                               margin=margin)
            else:
                found = closed_curve_distances(graph, max_bases=_WIDE_BASES, lines=_WIDE_LINES,
                                               most=_WIDE_CANDIDATES, classes=classes, margin=margin)
            loops.update(_ranked_loops(domain, metric, found, _CLOSED_STARTS))
            for c, f in loops.items():
                grid_costs[("closed", c)] = min(g for g, _ in f)
            return True

        def solve(costs, guess=False):
            paths = {k: v for k, v in costs.items() if k[0] != "closed"}
            closed = {k[1]: v for k, v in costs.items() if k[0] == "closed"}
            return solve_torus(paths, closed, len(pos), len(neg), K, guess=guess)

        # _foreseen's trial solves: one pass of the program each (half of 53 s of 200 s of integer programs on the
        # star and ellipse of validation/star_ellipse.py, their relaxations fractional near ties)
        foresee = partial(solve, guess=True)

        def polyline(key):
            if key[0] == "closed":
                return loops[key[1]][0][1]
            i, j, c = key
            return troute(neg[j], pos[i], c)

        def refine_keys(keys, rough=False):
            jobs = [GeodesicJob(np.asarray(polyline(k), dtype=float), closed=k[0] == "closed") for k in keys]
            return refine_many(domain, metric, jobs, *_tolerances(tol, atol, rough))

        def finish(keys, cache, promote):
            # a chosen closed curve again from the grid's other closed curves of its class (closed_curve_distances)
            starts = {k: [GeodesicJob(np.asarray(p, dtype=float), closed=True) for _, p in loops[k[1]][1:]]
                      for k in keys if k[0] == "closed"}
            out = _more_starts(domain, metric, starts, cache, tol, atol, family=_CLOSED_FAMILY, by_bound=True)
            # a chosen curve between two crossing points, from its reflection across its chord (_chord_starts)
            held = {**cache, **out}
            chord = _chord_starts(domain, metric, [k for k in keys if k[0] != "closed"], held, cell)
            out.update(_restarted(domain, metric, chord, held, tol, atol, clearly=True))
            # and one that runs beside a vertex line, folded onto each side of it (_crease_starts)
            held = {**cache, **out}
            folded = {k: _crease_starts(domain, held[k], cell) for k in keys if k[0] != "closed"}
            out.update(_restarted(domain, metric, folded, held, tol, atol, clearly=True))
            # the entries a chosen curve competes with, from its route moved onto their ends (_transplanted_starts:
            # the program is solved again); those refined roughly that may be among them, in full first
            held = {**cache, **out}
            bar: dict = {}
            for k in keys:
                if k[0] != "closed":
                    bar[k[2]] = max(bar.get(k[2], 0.0), (1.0 + _TRANSPLANT) * held[k].length)
            promote(lambda o, rp: o[0] != "closed" and _rough_cost(rp) <= bar.get(o[2], -1.0))
            held = {**cache, **out}
            moved = _transplanted_starts(domain, metric, keys, held, lambda k: np.asarray(polyline(k))[[0, -1]])
            out.update(_restarted(domain, metric, moved, held, tol, atol, clearly=True))
            # and every chosen curve pinned at a corner of the cells from beside it (see _corner_starts)
            out.update(_leave_corners(domain, metric, keys, {**cache, **out},
                                      lambda k, X: GeodesicJob(X, closed=k[0] == "closed"), tol, atol))
            return out

        def ends(key):
            if key[0] == "closed":
                return None, None
            return int(neg[key[1]]), int(pos[key[0]])
    else:
        T, route = grid_distances(graph, backend, bound=_SEARCH_BOUND if backend == "scipy" else None)
        foresee = None  # _foreseen solves the program itself
        nt = ng + len(domain.points)
        supply = np.zeros(nt, dtype=int)
        supply[ng + neg] = 1
        supply[ng + pos] = -1
        if ng == 1:
            supply[0] = -supply[ng:].sum()
        else:
            supply[0] = cond["flux"]
            supply[1] = -(supply[0] + supply[ng:].sum())
        arcs = [(u, v) for u in range(nt) for v in range(nt) if u != v and np.isfinite(T[u, v])]
        grid_costs = {a: float(T[a]) for a in arcs}
        mirror = _mirror_of(domain, metric) if domain.kind == "annulus" else None

        if ng == 1:  # intervals: the paper's assignment program (34)

            def solve(costs):
                A_pm = np.array([[costs.get((1 + j, 1 + i), np.inf) for j in neg] for i in pos])
                A_pm = A_pm.reshape(len(pos), len(neg))
                A_p0 = np.array([costs[(0, 1 + i)] for i in pos])
                A_0m = np.array([costs[(1 + j, 0)] for j in neg])
                value, pairs = solve_assignment(A_pm, A_p0, A_0m)
                chosen = []
                for i, j in pairs:
                    u = 0 if j is None else 1 + int(neg[j])
                    v = 0 if i is None else 1 + int(pos[i])
                    chosen.append(((u, v), 1))
                return value, chosen
        else:

            def solve(costs):
                C = np.full((nt, nt), np.inf)
                for (u, v), c in costs.items():
                    C[u, v] = c
                value, flow = solve_flow(C, supply)
                return value, [((u, v), n) for u, v, n in flow]

        def refine_keys(keys, rough=False):
            # the jobs of every key at once: one curve, or for a point and the boundary every stretch of the
            # boundary that the grid cannot rule out (ranked by their coarse geodesics; the close ones refined)
            jobs, owner, ranked = [], [], []
            for n, (u, v) in enumerate(keys):
                if (u < ng) == (v < ng):  # point to point, or boundary to boundary
                    jobs.append(GeodesicJob(route(u, v), *_grounds((u, v), ng)))
                    owner.append(n)
                    continue
                a, g = (u, v) if v < ng else (v, u)
                polys = route.candidates(a, g, 1.0)
                if len(polys) > 1:
                    ranked.extend((n, g, poly) for poly in polys)
                else:
                    jobs.append(GeodesicJob(polys[0], end_ground=g))
                    owner.append(n)
            if ranked:
                coarse = coarse_geodesics(domain, metric, [GeodesicJob(p, end_ground=g) for _, g, p in ranked])
                shortest: dict[int, float] = {}
                for (n, _, _), (_, length) in zip(ranked, coarse):
                    shortest[n] = min(shortest.get(n, np.inf), length)
                for (n, g, _), (X, length) in zip(ranked, coarse):
                    if length <= 1.02 * shortest[n]:  # refine starts from the coarse geodesic
                        jobs.append(GeodesicJob(X, end_ground=g, coarse=True))
                        owner.append(n)
            refined = refine_many(domain, metric, jobs, *_tolerances(tol, atol, rough))
            out: list = [None] * len(keys)
            for n, rp in zip(owner, refined):
                if out[n] is None or rp.length < out[n].length:
                    out[n] = rp
            for n, (u, v) in enumerate(keys):
                if (u < ng) != (v < ng) and u < ng:  # from the boundary to a point: the curve runs backwards
                    out[n] = out[n].reversed()
            return out

        def with_images(changed, held):
            # the curves that starts replaced, each one's mirror image following where it is shorter than the image's
            # own curve and no start replaced that one (on an annulus: _mirror_of)
            if mirror is not None:
                for k, rp in list(changed.items()):
                    m, flip = _mirror_key(k, held, mirror[0])
                    if m != k and m in held and m not in changed and rp.length < held[m].length:
                        changed[m] = _mirrored(rp, mirror[1], flip)
            return changed

        def finish(keys, cache, promote):
            # a chosen curve with both ends free around a circle: rotations along the circle nearly preserve its
            # length, so it is refined again from its route shifted by fractions of an edge (see _family_shifts)
            starts: dict = {}
            if domain.periodic[0]:
                # every refined curve between the grounds, chosen or not: from its grid route alone it can lie far
                # above the family's minimum and lose the choice to curves it would beat (the star polygon of 9
                # vertices under a merge rule tried at stop 29: 11.78 from its route, 11.5667 from the shifted
                # starts; two curves to the diagonal at 5.84 and 5.835 were chosen instead, 4.8e-3 relative above J)
                def between_grounds(k, *_):
                    return k[0] < ng and k[1] < ng

                promote(between_grounds)  # those refined roughly, in full first
                grounded = [k for k in cache if between_grounds(k) and k not in shifted]
                shifted.update(grounded)
                starts = {k: [GeodesicJob(route(*k) + shift, start_ground=k[0], end_ground=k[1])
                              for shift in _family_shifts(domain)] for k in grounded}
            out = _more_starts(domain, metric, starts, cache, tol, atol)
            if settings["second_pass"] and domain.kind == "annulus":
                # the chosen curves to the diagonal, and those of the points that a chosen curve joins (a shorter
                # one to the diagonal can change the choice: the program is solved again)
                joined = {w for u, v in keys if u >= ng and v >= ng for w in (u, v)}
                def to_slide(k, *_):
                    return k not in slid and ((k[0] < ng) != (k[1] < ng)) and (k in keys or max(k) in joined)

                promote(to_slide)  # those refined roughly, in full first
                near = [k for k in cache if to_slide(k)]
                slid.update(near)
                out.update(_slid_ends(domain, metric, near, {**cache, **out}, grid_costs, tol, atol))
            # a chosen curve from a crossing point to the boundary, a few cells long: straight starts (_straight_starts)
            held = {**cache, **out}
            straight = {k: _straight_starts(domain, k, held[k], ng, cell) for k in keys}
            # and a chosen curve to the diagonal, from its reflection across the crossing point's antidiagonal
            # (_reflected_starts)
            for k in keys:
                straight[k] = straight[k] + _reflected_starts(domain, metric, k, held[k], ng)
            out.update(_restarted(domain, metric, straight, held, tol, atol))
            # a chosen curve between two crossing points, along the grid's other routes between them
            # (_alternative_starts: the other side of a hill of the metric)
            held = {**cache, **out}
            other = _alternative_starts(domain, metric, keys, held, route, ng, bias - 1.0)
            # and from its reflection across its chord (_chord_starts: the other side of a narrow ring valley)
            for k, jobs in _chord_starts(domain, metric, [k for k in keys if k[0] >= ng and k[1] >= ng], held,
                                         cell).items():
                other[k] = other.get(k, []) + jobs
            # and a chosen curve to a side, with its end in the neighbouring strips between vertex lines
            # (_strip_starts: a local minimum of the length in each)
            for k, jobs in _strip_starts(domain, metric, keys, held, ng).items():
                other[k] = other.get(k, []) + jobs
            out.update(with_images(_restarted(domain, metric, other, held, tol, atol, clearly=True), held))
            # and one that runs beside a vertex line, folded onto each side of it (_crease_starts; they count only
            # where one beats the curve by more than its estimate)
            held = {**cache, **out}
            folded: dict = {}
            # one curve of each mirror pair, the longer (fig10: 12 starts, twice the time), its image following
            for k in sorted(keys, key=lambda k: -held[k].length):
                if mirror is None or _mirror_key(k, held, mirror[0])[0] not in folded:
                    folded[k] = _crease_starts(domain, held[k], cell, *_grounds(k, ng))
            out.update(with_images(_restarted(domain, metric, folded, held, tol, atol, clearly=True), held))
            # a chosen curve pinned at a corner of the cells, again from beside it (see _corner_starts)
            out.update(_leave_corners(domain, metric, keys, {**cache, **out}, lambda k, X: GeodesicJob(
                X, *_grounds(k, ng)), tol, atol))
            if settings["route_check"]:
                out.update(_second_routes(keys, {**cache, **out}))
            if mirror is not None:
                images = {(mirror[0][u], mirror[0][v]) for u, v in keys}  # refined roughly: in full first
                promote(lambda k, _: k in images or k[::-1] in images)
                out.update(_mirror_pairs(keys, {**cache, **out}, *mirror))
            return out

        second: dict = {}

        def _second_routes(keys, cache):
            # the chosen curves' routes on a second grid (three quarters of the step): where a crease of the metric
            # splits a valley, grids of different steps may route a curve on different sides of it, and the
            # refinement settles on the side it starts from. Each route is straightened at the coarse scale
            # (cheap); one clearly shorter than the refined curve leads to another local geodesic and is refined
            if "graph" not in second:
                second["graph"] = build_graph(domain, metric, second_resolution(settings["resolution"]),
                                              second_neighbours(settings["neighbours"], metric), coarsen=coarsen)
            # searches from one end of each curve (the point, when the other end is the boundary), stopped at twice
            # its length on the first grid: far enough for the routes to the boundary within that factor
            searches: dict = {}
            for u, v in keys:
                a = u if u >= ng or v < ng else v
                searches[a] = max(searches.get(a, 0.0), _ROUTE_CHECK_REACH * grid_costs[u, v])
            T2, route2 = grid_distances(second["graph"], backend, searches=searches)
            ranked = []  # (key, job from the point when one end is a point and the other the boundary)
            for k in keys:
                u, v = k
                if not np.isfinite(T2[(u, v) if u >= ng or v < ng else (v, u)]):  # beyond reach on the second grid
                    continue
                if (u < ng) == (v < ng):
                    ranked.append((k, GeodesicJob(route2(u, v), *_grounds((u, v), ng))))
                    continue
                a, g = (u, v) if v < ng else (v, u)
                ranked.extend((k, GeodesicJob(p, end_ground=g)) for p in route2.candidates(a, g, 1.0))
            if not ranked:
                return {}
            coarse = coarse_geodesics(domain, metric, [job for _, job in ranked], rounds=1, more=0)
            todo = []
            for (k, job), (X, length) in zip(ranked, coarse):
                # a real curve shorter than the refined one (measured on 38 random scenes: 276 of 277 chosen
                # curves came out at least as long, the one shorter by 35 %, seed 138 of multistart.py)
                if length < cache[k].length:
                    todo.append((k, GeodesicJob(X, job.start_ground, job.end_ground, coarse=True)))
            if not todo:
                return {}
            found: dict = {}
            for (k, _), rp in zip(todo, refine_many(domain, metric, [job for _, job in todo], tol=tol, atol=atol)):
                if k[0] < ng <= k[1]:  # from the boundary to a point: the curve runs backwards
                    rp = rp.reversed()
                found.setdefault(k, []).append(rp)
            return {k: _best_of_starts([cache[k]] + rps) for k, rps in found.items()}

        def polyline(key):
            return route(*key)

        def complete(keys):  # every entry is a grid length already
            return False

        def ends(key):
            u, v = key
            return (("ground", u) if u < ng else u - ng), (("ground", v) if v < ng else v - ng)

    grid_value, grid_chosen = solve(grid_costs)
    while complete([k for k, _ in grid_chosen]):  # a closed curve picked at its bound: searched, solved again
        grid_value, grid_chosen = solve(grid_costs)
    atol = 0.1 * tol * grid_value / max(1, len(domain.points))
    loose: list = []
    if do_refine:
        # at a fine tol, the entries asked for after the first batch are refined roughly first (see _settle)
        rough = partial(refine_keys, rough=True) if tol <= _ROUGH_TOL / 10 else None
        value, chosen, cache = _settle(grid_costs, solve, refine_keys, bias, finish, complete=complete,
                                       foresee=foresee, rough=rough)
        # the absolute tolerance (a curve much shorter than the others needs no relative accuracy of its own) came
        # from the grid's value, which overestimates J many times over where the grid cannot follow a narrow valley
        # (a hairpin of the deformed curve: 61 times at 96 cells, 6.2 at 128, on the built-in scene hairpin; validation/
        # random_closed.py); the chosen curves that stopped on it, short of their relative tolerance, are refined
        # again with the refined value's, when the grid's was more than twice as large (below that the sum of the
        # absolute tolerances stays within a fifth of tol * J)
        loose_atol = 0.1 * tol * value / max(1, len(domain.points))
        if atol > 2 * loose_atol:
            loose = [k for k, _ in chosen
                     if k in cache and max(tol * cache[k].length, loose_atol) < cache[k].error_estimate <= atol]
        if loose:
            atol = loose_atol
            stale = set(loose)
            slid.difference_update(stale)  # refined afresh from the grid: slid again
            shifted.difference_update(stale)  # and shifted again (an adversarial review)
            # the stale entries enter as roughly refined ones, at the optimistic cost of their first refinement, not
            # at their grid lengths' lower bounds: a curve in a thin lens between four crossings (g, p = 2) was 17.7
            # times shorter than its grid length, beyond every other entry's ratio, and lost the choice to curves
            # 7.4e-5 (relative) longer at tol=1e-5, with an estimate of 4e-6 (an adversarial review)
            value, chosen, cache = _settle(grid_costs, solve, refine_keys, bias, finish,
                                           cache={k: v for k, v in cache.items() if k not in stale},
                                           finished={k for k, _ in chosen if k not in stale}, complete=complete,
                                           foresee=foresee, rough=rough, roughly={k: cache[k] for k in stale})
    else:
        value, chosen, cache = grid_value, grid_chosen, {}
    curves = []
    err = 0.0
    for key, count in chosen:
        if key in cache:
            rp = cache[key]
            poly, length, e = rp.points, rp.length, rp.error_estimate
        else:
            poly, length, e = polyline(key), grid_costs[key], np.nan  # a grid length: no estimate
        start, end = ends(key)
        for _ in range(count):
            curves.append((start, end, np.asarray(poly, dtype=float), float(length), float(e), key[0] == "closed"))
            err += e
    return value, grid_value, err, curves, bool(loose)


def penalty(
    scene: Scene | str,
    metric: MetricName | Metric = "G",
    *,
    power: float | None = None,
    tol: float = 1e-3,
    resolution: int = _DEFAULT_RESOLUTION,
    neighbours: int = 16,
    backend: Backend = "scipy",
    refine: bool = True,
    second_pass: bool | None = None,
    coarsen: int = 4,
    workers: int = 1,
) -> Penalty:
    r"""The penalty ``J(phi)`` of a deformation, by the direct method (section 5.1.1).

    Parameters
    ----------
    scene : Scene or str
        The body M with its reference embedding and deformation; a JSON file
        path or a built-in scene name is accepted too (an existing file
        first: :func:`direct.scenes.resolve`).
    metric : {"G", "g", "euclid"} or Metric, default "G"
        ``"G"``: ``G(y1, y2) = |y1 - y2|^4 Id`` (Example 14); ``"g"``: the
        non-degenerate family ``g(s) = s^p`` of section 3.4.2; ``"euclid"``:
        the heuristic metric of section 3.1.  See :mod:`direct.metric`.
    power : float, optional
        ``q`` of ``G = |y1 - y2|^(2q) Id`` or ``p`` of ``g(s) = s^p`` (both default 2).
    tol : float, default 1e-3
        Relative tolerance of each refined geodesic length; a curve much
        shorter than the others stops once its estimate is below ``tol / 10``
        of its piece's value shared among the piece's points (taken from the
        refined value when the grid's was more than twice as large: see
        ``settings["refined_again"]``).  The levels of the refinement double
        the segments of each curve up to 512 (2,048 below ``tol = 1e-6``,
        where a smooth curve needs two more levels per decade): much below
        1e-7 a curve can stop short of ``tol``, and the result says so
        (``ToleranceWarning``).
    resolution : int, default 128
        Grid cells along the longer side of each pair domain at the step of
        the patches around crossing points (in deformed arclength for ``G``,
        see :func:`direct.grid.build_graph`).  With
        refinement the grid only routes the geodesics and ranks them; their
        lengths, hence the tolerance, come from the refinement.  But the
        routes decide which points are joined and which local geodesic each
        curve settles in, which the estimate does not measure: below the
        default the second pass runs on the default grid as well
        (``second_pass``), so a coarser grid saves no time.  At most 8192:
        the grid's memory grows as the square (2.2 GB at 4096 cells).
    neighbours : {8, 16, 32}, default 16
        Grid stencil.
    backend : {"scipy", "networkx"}, default "scipy"
        Shortest-path implementation of the grid stage.
    refine : bool, default True
        Refine the grid geodesics continuously (without it, ``value`` is the
        biased grid value).
    second_pass : bool, optional
        Solve every domain a second time from the routes of another grid
        (:func:`second_resolution`: three quarters of ``resolution``, or
        the default 128 cells below it), keep the better family and add
        the difference of the two values to ``error_estimate``.  The
        refinement finds the local geodesic near each route; where a
        geodesic rides a crease of the metric (a vertex line along which
        ``rho`` has a kink) or where several local geodesics compete, two
        starts can settle 1e-5 to 1e-4 apart, a spread the discretization
        estimate alone does not see.  Default: when ``tol <= 1e-4``, when
        ``resolution`` is below the default (a coarse grid can pair the
        points otherwise than the default's, or route a curve into a longer
        local geodesic: 10 % above ``J`` with an estimate of 3e-4 on a
        random scene at 4 to 24 cells; the second pass is then the default
        computation itself, route check included), and always for a degenerate metric
        (``euclid``).  The second grid (the second pass's, and the route
        check's) has at least 16 neighbours, and for a degenerate metric
        another stencil than the first (32 neighbours, or 16 from 32):
        :func:`second_neighbours`.  A
        domain with a grazing crossing (the sine of the angle between the
        deformed tangents below 0.1) gets the second pass at every
        tolerance unless ``second_pass=False``.  Without the full second
        pass, the chosen curves (on every piece of ``M x M`` but the tori)
        are checked against the routes of the second grid: each is
        straightened at the coarse scale, and one shorter than the refined
        curve (another local geodesic, across a crease) is refined too and
        the shorter kept (``settings["route_check"]``; about 15 % of the
        time).  ``second_pass=False`` refuses every second start: one grid's
        routes, nothing else (the starts from the refined curves themselves
        stay: around a circle, beside a corner of the cells; see
        :func:`direct.starts._corner_starts`).
    coarsen : int, default 4
        Local refinement of the grid: the step of ``resolution`` only in a
        patch reaching two coarse cells around each crossing point (where ``rho``
        vanishes and the geodesics choose their way out), a lattice
        ``coarsen`` times coarser elsewhere (see
        :func:`direct.grid.build_graph`); refined too where ``rho`` varies by
        more than a factor 4 across a coarse cell (along the diagonal, and
        where two pieces of the curve come close).  Domains with a circle
        keep the uniform grid.  1 gives the uniform grid of ``resolution``
        cells everywhere; otherwise at least 4 (larger than every stencil)
        and at most ``resolution // 2`` (the coarse lattice has two cells a
        side at least).
    workers : int, default 1
        Processes that refine the curves of each batch (-1: one per CPU).
        The curves of a batch are refined independently, so the result is
        the same as with one process, bit for bit for ``G`` with ``q = 2``
        and ``g`` with ``p = 1``; with the other metrics, whose quadrature
        sums depend on the batch in the last bit, within the estimates
        (:mod:`direct.parallel`).  It pays where the refinement takes
        seconds: circles 1.6 times faster on two cores, random interval
        scenes 1.09 times (``python validation/workers.py``).  Worker
        processes start at the first call and stay for the session, with the
        code of that moment (:func:`direct.parallel.shutdown` stops them); off
        Linux they start by ``spawn``, so a script needs an ``if __name__ ==
        "__main__":`` guard.  Where no worker can take a part (a metric
        built on a lambda, no processes allowed), the rest of the call runs
        in this process, with a ``RuntimeWarning``.  ``settings["workers"]``
        records ``workers`` above 1 (and ``settings["workers_failed"]`` why
        they were not used).

    Returns
    -------
    Penalty
        ``value`` is ``J`` over all of ``M x M`` (eq. (34)): each geometric
        crossing contributes its two points ``(x1, x2)`` and ``(x2, x1)``.

    Warns
    -----
    ToleranceWarning
        When ``error_estimate`` exceeds ``tol * value``: the value is
        returned, with the warning that the tolerance was not reached.
    DegenerateMetricWarning
        Always, for a degenerate metric (``euclid``) when ``J > 0``, with or
        without ``refine``, instead of the above:
        the estimate cannot cover the choice of routes (a subclass of
        :class:`ToleranceWarning`).
    RuntimeWarning
        With ``workers`` above 1, once, where no worker could take a part:
        the rest of the call ran in this process (the message says why).

    Raises
    ------
    SceneError
        For an invalid scene, or one whose lengths would overflow or
        underflow in floating point (the message says how to rescale).
    DegenerateError
        For contacts the generic-perturbation rule cannot decide.
    DirectError
        For an invalid argument (``tol`` not a number in ``(0, 1)``, an
        unknown ``metric`` or ``backend``, a ``power`` the metric refuses,
        ``resolution`` below 4, above 8192 or not whole, ``neighbours`` not 8, 16 or 32,
        ``coarsen`` not 1 or at least 4 or above ``resolution // 2``, ``refine`` not a bool,
        ``second_pass`` not a bool or None, ``workers`` not a whole number from
        1 to 1024 or -1).  Every error raised on purpose is
        a :class:`DirectError`; the two above are subclasses.

    Examples
    --------
    >>> import direct
    >>> res = direct.penalty(direct.scenes.cross(0.3, 0.5, 0.4, 0.6))
    >>> abs(res.value - 2 * 0.3**3 / 3) < 1e-3 * res.value
    True
    """
    n = parallel.resolve_workers(workers)
    with _one_blas_thread(), parallel.using(n) as processes:
        result = _penalty(scene, metric, power, tol, resolution, neighbours, backend, refine, second_pass, coarsen)
    if n > 1:
        result.settings["workers"] = n
        if processes.failure is not None:
            result.settings["workers_failed"] = processes.failure
            warnings.warn(f"direct: {processes.failure}; the rest of this call ran in one process, as with "
                          "workers=1", RuntimeWarning, stacklevel=2)
    return result


_THREADPOOLS: ThreadpoolController | None = None


def _one_blas_thread():
    """Context that keeps BLAS on one thread: the linear algebra here is thousands of tiny problems.

    Threaded BLAS only adds synchronization to them; on a loaded 2-core machine
    it made one scene's refinement 3 times slower (L-BFGS-B, measured with
    cProfile).
    """
    global _THREADPOOLS
    if _THREADPOOLS is None:
        _THREADPOOLS = ThreadpoolController()
    return _THREADPOOLS.limit(limits=1, user_api="blas")


def second_resolution(resolution: int) -> int:
    """Cells of the second grid (the route check, the second pass): three quarters of the step, or the default.

    From the default resolution (128 cells) up, the second grid has three
    quarters of the first's cells: another step, whose routes may run on
    the other side of a crease.  Below it, the second grid is the default
    one: a first grid coarse enough to route a curve into a longer local
    geodesic would route it there again at three quarters of its step, and
    the estimate, which measures the refinement, cannot see that (an
    adversarial review, this stop: interval seed 100 at 64 cells and
    ``tol=1e-5`` 1.35e-3 above the exact length of the default's curves with
    an estimate of 3e-6; closed polygon 13 at 24 cells 85 % above, no
    warning).

    Parameters
    ----------
    resolution : int
        Cells of the first grid along the longer side (``direct.penalty``'s ``resolution``).

    Returns
    -------
    int
    """
    return (3 * int(resolution)) // 4 if resolution >= _DEFAULT_RESOLUTION else _DEFAULT_RESOLUTION


#: the range of ``log10(extent ** (order + 1))`` (deformed extent in length units, ``order`` the metric's power of
#: ``|r|``): the scale of the lengths, within which they neither overflow nor lose their digits to underflow
_SCALE_RANGE = (-250.0, 250.0)


def second_neighbours(neighbours: int, metric: Metric) -> int:
    """The stencil of the second grid (the route check's, and the second pass's): at least 16 moves.

    Parameters
    ----------
    neighbours : int
        The first grid's stencil: 8, 16 or 32 moves.
    metric : Metric
        The metric; a degenerate one (``euclid``) gets another stencil than
        the first, since its directions decide which routes win.

    Returns
    -------
    int
        The second grid's moves.  With 8 moves the grid's bias reaches 8.2 %,
        more than the gap between some local geodesics: on a polygon
        symmetric about an axis through its crossing the straight curve from
        the crossing point along ``(-1, 1)`` is a move of the stencil and a
        local geodesic, which the grid weighs exactly while the shortest
        curves beside it cost up to 8.2 % more (the figure eight ``(sin t,
        sin t cos t)`` at 12 vertices: 4.9 % above ``J`` with 8 moves in both
        grids, no warning).  A second grid of 16 moves routes to the shorter
        one.
    """
    if metric.degenerate:
        return 32 if neighbours < 32 else 16
    return max(neighbours, 16)


#: the largest ``resolution`` accepted: memory grows as its square (measured on ``cross`` with ``refine=False``:
#: 0.23 GB at 1024 cells, 0.66 at 2048, 2.2 at 4096, 8.6 at 8192)
_MAX_RESOLUTION = 8192


def _inside(scene: Scene, crossings: list[Crossing]) -> int:
    """How many crossings lie inside ``M x M``: all but the contacts at an end of an open component.

    Such a contact (an end on the other curve) is decided by the perturbation rule (``exact=False``) and its
    parameter is the end's; a transversal crossing (``exact=True``), however close to an end, lies inside.
    An end whose last segments have collapsed onto one point (the same deformed vertex) reaches back to the
    first of them: from a crossing there a curve runs to the end along ``r = 0``, and ``J = 0`` is right
    (a review at stop 48: a false warning).
    """
    def at_end(comp, x):
        if comp.closed:
            return False
        X = np.asarray(comp.deformed, dtype=float)
        same = np.all(X == X[0], axis=1).cumprod().astype(bool)  # vertices equal to the first, from the start
        first = float(comp.params[int(same.sum()) - 1])
        same = np.all(X == X[-1], axis=1)[::-1].cumprod().astype(bool)
        last = float(comp.params[len(X) - int(same.sum())])
        return x <= first + 1e-12 * comp.length or x >= last - 1e-12 * comp.length

    return sum(c.exact or not any(at_end(scene.components[i], x) for i, x in zip(c.components, c.params))
               for c in crossings)


def _degree(met) -> float:
    """The power of the deformed scene's size by which ``J`` scales: ``q + 1`` for ``G``, ``2 p`` for ``g``.

    ``g``'s length element is in the reference arclength, which a rescaling
    of the deformation leaves alone; ``G``'s and ``euclid``'s are in the
    deformed one.
    """
    return float(met.order) if met.name == "g" else float(met.order) + 1.0


def _check_scale(scene: Scene, met) -> None:
    """Refuse a scene whose lengths would overflow or underflow in floating point (see ``_SCALE_RANGE``).

    ``J^G`` scales as the cube of the deformed scene's size: a scene 1e110
    across overflowed, and one 1e-110 across would underflow to ``J = 0``.
    """
    pts = np.vstack([np.asarray(c.deformed, dtype=float) for c in scene.components])
    extent = float(np.ptp(pts, axis=0).max()) if len(pts) else 0.0
    if not extent > 0.0:
        return
    degree = _degree(met)
    size = degree * np.log10(extent)
    lo, hi = _SCALE_RANGE
    if not lo <= size <= hi:
        raise SceneError(
            f"the deformed scene is {extent:.3g} across: lengths of the metric {met.name} (of degree {degree:g} in "
            f"the size) would {'overflow' if size > hi else 'underflow'} in floating point. Rescale the deformed "
            f"coordinates (J^{met.name} scales as the power {degree:g} of the size of the deformation)."
        )
    for comp in scene.components:  # |phi'| enters squared: deformed over reference lengths within 1e+-100
        speed = np.linalg.norm(comp.velocities, axis=1)
        bad = np.flatnonzero((speed > 0) & ((speed > 1e100) | (speed < 1e-100)))
        if bad.size:
            k = int(bad[0])
            raise SceneError(
                f"component {comp.name!r}, segment {k} (vertices {k} and {(k + 1) % comp.n_vertices}): its deformed "
                f"length is {speed[k]:.3g} times its reference length, beyond what floating point can square. "
                "Rescale the reference or the deformation (J^G does not depend on the reference's scale, J^g does)."
            )


def _penalty(scene, metric, power, tol, resolution, neighbours, backend, refine, second_pass, coarsen) -> Penalty:
    t0 = time.perf_counter()
    scene = resolve(scene)
    met = get_metric(metric, power)
    if not is_real_number(tol) or not (0 < tol < 1):
        raise DirectError(f"tol must be a real number in (0, 1), got {tol!r}")
    if not isinstance(refine, (bool, np.bool_)):
        raise DirectError(f"refine must be True or False, got {refine!r}")
    if second_pass is not None and not isinstance(second_pass, (bool, np.bool_)):
        raise DirectError(f"second_pass must be True, False or None (chosen by tol), got {second_pass!r}")
    refine = bool(refine)
    second_pass = None if second_pass is None else bool(second_pass)
    if not is_real_number(resolution) or not float(resolution).is_integer() or int(resolution) < 4:
        raise DirectError(f"resolution must be a whole number of grid cells, at least 4, got {resolution!r}")
    if resolution > _MAX_RESOLUTION:
        raise DirectError(
            f"resolution={resolution!r} is above {_MAX_RESOLUTION} cells: the grid's memory grows as its square "
            f"(4096 cells took 2.2 GB on 'cross'). The refinement, not the grid, sets the accuracy: ask for a "
            f"smaller tol instead")
    if backend not in ("scipy", "networkx"):
        raise DirectError(f"backend must be 'scipy' or 'networkx', got {backend!r}")
    if neighbours not in (8, 16, 32):
        raise DirectError(f"neighbours must be 8, 16 or 32, got {neighbours!r}")
    if not is_real_number(coarsen) or not np.isfinite(coarsen) or int(coarsen) != coarsen or not (
            coarsen == 1 or coarsen >= 4):
        raise DirectError(f"coarsen must be 1 (a uniform grid) or an integer of at least 4, got {coarsen!r}")
    if coarsen > max(4, resolution // 2):
        raise DirectError(f"coarsen={coarsen!r} is above half of resolution={resolution!r}: the coarse lattice needs "
                          f"two cells a side, so the fine one would grow to 2 * coarsen cells a side (and the patches "
                          f"around the crossing points with it); use at most resolution // 2, or the default 4")
    settings: dict[str, Any] = dict(met.describe())
    allow_second = second_pass is not False  # grazing domains get a second pass unless it is refused
    coarse = int(resolution) < _DEFAULT_RESOLUTION  # the default computation runs too (second_resolution)
    if second_pass is None:
        second_pass = tol <= _SECOND_PASS_TOL or met.degenerate or coarse
    settings.update(tol=float(tol), resolution=int(resolution), neighbours=int(neighbours), coarsen=int(coarsen),
                    backend=backend,
                    refine=bool(refine), second_pass=bool(second_pass and refine))
    # without the full second pass, the chosen curves are checked against the routes of a second grid
    # below the default resolution the second pass is the default computation itself, route check included
    # (interval seed 138 at 64 cells: both grids, 64 and 128 cells, route a curve into a valley 62 % longer, and
    # only the default's check on 96 cells finds the shorter one; without it 7.7e-4 above J, estimate 3.8e-5)
    settings["route_check"] = bool(refine and allow_second and (not settings["second_pass"] or coarse))
    _check_scale(scene, met)
    crossings = find_crossings(scene)
    names = [c.name for c in scene.components]
    total = grid_total = err_total = rounding_total = 0.0
    pairs: list[Pair] = []
    # the metrics that do not depend on the parametrization are computed in the deformed arclength (not the
    # degenerate euclid, whose refinement keeps Euclidean normals in the reference arclength: _speed_lookup)
    invariant = met.reparametrization_invariant and not met.degenerate
    work, work_crossings = _in_deformed_arclength(scene, crossings) if invariant else (scene, crossings)
    if work is not scene:  # for the record: the components computed in their deformed arclength
        settings["deformed_arclength"] = [c.name for c in work.components if hasattr(c, "source")]
    for dom in domains(work, work_crossings):
        if len(dom.points) == 0 and not any(boundary_conditions(dom).values()):
            continue  # nothing to join: J = 0 on this piece
        # a grazing crossing's geodesic runs down a narrow valley into a corner of the domain and turns onto a side
        # there; the refinement can settle short of that turn with a small estimate, so such domains always get a
        # second start (measured: 1.3e-3 off with an estimate of 1.5e-5 at 0.003 rad and tol 1e-3 without it)
        grazing = refine and allow_second and _min_sine(dom, work_crossings) < _GRAZING
        value, grid_value, err, curves, again = _solve_domain(dom, met, settings, backend, refine)
        if grazing and not settings["second_pass"]:
            settings["grazing_second_pass"] = settings.get("grazing_second_pass", 0) + 1  # domains, for the record
        if settings["second_pass"] or grazing:
            other = dict(settings, resolution=second_resolution(settings["resolution"]),
                         neighbours=second_neighbours(settings["neighbours"], met))
            value2, _, err2, curves2, again2 = _solve_domain(dom, met, other, backend, refine)
            again += again2
            spread = abs(value2 - value)
            if value2 < value:
                value, curves = value2, curves2
            err = max(err, err2) + spread
        if again:  # domain solves, for the record
            settings["refined_again"] = settings.get("refined_again", 0) + int(again)
        m = dom.multiplicity
        of_r, of_sums = _rounding_errors(dom, met, curves)
        rounding = of_r + of_sums
        total += m * value
        grid_total += m * grid_value
        err_total += m * (err + float(rounding.sum()))
        rounding_total += m * float(of_r.sum())
        ni, nj = names[dom.pair[0]], names[dom.pair[1]]
        exact = polyline_lengths(dom, met, [c[2] for c in curves])
        for (start, end, path, length, perr, closed), plen, rerr in zip(curves, exact.tolist(), rounding.tolist()):
            perr += rerr
            a = start if isinstance(start, (int, np.integer)) else None
            b = end if isinstance(end, (int, np.integer)) else None
            sc = None if a is None else int(dom.crossing_ids[a])
            ec = None if b is None else int(dom.crossing_ids[b])
            sp_ = None if a is None else _crossing_point(crossings[sc], dom.points[a])
            ep_ = None if b is None else _crossing_point(crossings[ec], dom.points[b])
            path = _to_reference(dom.comps, path, sp_, ep_)
            pairs.append(Pair((ni, nj), sp_, ep_, sc, ec, length, perr, path, closed, plen))
            if m == 2:
                # mirror image in M_j x M_i: coordinates swapped, signs (hence orientation) reversed
                pairs.append(Pair((nj, ni), None if ep_ is None else ep_[::-1], None if sp_ is None else sp_[::-1],
                                  ec, sc, length, perr, path[::-1, ::-1].copy(), closed, plen))
    if total > 0 and met.degenerate:
        if refine:
            told = (f"J^{met.name} = {total:.7g} with an error estimate of {rounded_up(err_total)} "
                    f"({err_total / total:.1e} relative, tol={tol:g})")
            covers = ("the estimate covers their refinement and the spread between two grids, not the routes "
                      "neither grid found (validation/euclid.py).")
        else:
            told = f"J^{met.name} = {total:.7g} from the grid alone (refine=False: no estimate)"
            covers = "the grid value also carries the stencil's bias; refine=True gives an estimate."
        warnings.warn(
            f"{told}: this metric is degenerate, and its grids may route a curve towards a longer local geodesic "
            "than the shortest. upper_bound, the exact length of the curves returned, bounds J from above; "
            + covers,
            DegenerateMetricWarning,
            stacklevel=3,
        )
    elif refine and total < np.finfo(float).tiny and (inside := _inside(scene, crossings)):
        # a contact at the end of an open component (an end on the other curve) lies on the boundary of M x M, where
        # J = 0 is right; a crossing inside M x M (at a vertex too) gives J > 0
        warnings.warn(
            f"J = {total:.3g} with {inside} crossing(s) inside M x M: the lengths of their "
            "curves fall below the smallest normal floating-point number (J > 0 for a crossing inside M x M). "
            f"Rescale the deformed coordinates (J^{met.name} scales as the power {_degree(met):g} of the size), "
            "or lower the power.",
            ToleranceWarning,
            stacklevel=3,
        )
    elif refine and rounding_total > 0.5 * err_total > 0.5 * tol * max(total, 0.0):
        warnings.warn(
            f"J = {total:.7g} has an error estimate of {rounded_up(err_total)}, above the requested tol={tol:g}, "
            "mostly from rounding: r = phi(x1) - phi(x2) is formed from deformed coordinates much larger than the "
            "curves reach (a scene far from the origin, a crossing very close to the end of a component, or a "
            "loop a few thousand roundings across). The estimate bounds the first-order rounding only: with so "
            "few digits left the value can be off by more (a loop 1e-13 across at coordinates near 1: 73 % off, "
            "estimate 3.5 %). Translate the scene to the origin; features below about 1e-12 of its size are beyond "
            "double precision.",
            ToleranceWarning,
            stacklevel=3,
        )
    elif refine and err_total > tol * max(total, 0.0):  # J = 0 with a positive estimate: no relative accuracy
        relative = f"{err_total / total:.1e} relative" if total > 0 else "J = 0 with a positive estimate"
        warnings.warn(
            f"J = {total:.7g} has an error estimate of {rounded_up(err_total)} ({relative}), above the "
            f"requested tol={tol:g}: the refinement found geodesics that settle apart from different starts (a "
            "geodesic along a crease of the metric, or a grazing crossing) or did not converge within its "
            "levels. Read the value with its error_estimate"
            + (", or try another resolution." if settings["second_pass"] or settings.get("grazing_second_pass")
               else ", or try second_pass=True or another resolution."),
            ToleranceWarning,
            stacklevel=3,
        )
    return Penalty(
        value=float(total),
        error_estimate=float(err_total),
        grid_value=float(grid_total),
        upper_bound=float(sum(p.polyline_length for p in pairs)),
        crossings=crossings,
        pairs=pairs,
        settings=settings,
        seconds=time.perf_counter() - t0,
    )
