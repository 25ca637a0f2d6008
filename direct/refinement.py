r"""Continuous refinement of grid geodesics: exact lengths, multilevel, batched.

The second stage of the geodesic distances of section 5.1.1 (the first,
grid Dijkstra, is :mod:`direct.geodesics`).  Grid distances keep a
metrication bias that refining the grid never removes (``shared/NUMERICS.md``),
so each grid route becomes a polyline whose exact metric length
(:func:`direct.metric.segment_lengths`) is minimized:

* A coarse pass first (16 segments, each across many cells, where the kinks
  of the length are small ripples) settles the large-scale shape, and
  slides the free ends into place: three rounds, then more while a curve
  still shortens (:func:`coarse_geodesics`).
* The polyline then gets a vertex wherever it crosses a vertex parameter of
  either component (the metric's norm jumps there and the geodesic
  refracts), sliding along that line, so that every segment lies in one
  cell where its length is smooth.  Free vertices move across the curve
  only (along the polyline's normals: moves along it barely change the
  length and make the problem singular; only the L-BFGS-B pass of a closed
  curve moves them along it too); ends slide on their boundary, with
  a geometric grading of vertices next to them and the freedom to change
  side at a corner.
* A damped Newton method (Levenberg-Marquardt with Marquardt's scaling,
  steps limited to half a segment) uses the exact gradient and a Hessian
  from central differences of it, tridiagonal in the unknowns of an open
  curve; an L-BFGS-B pass takes over where Newton stalls on a kink.
* The number of segments doubles, three levels at least, until the length
  changes by less than the tolerance; the value is Richardson-extrapolated
  (error ``~ n^-2``).  The error estimate is the whole last change, at least
  a quarter of the change before it, plus what further rounds of the last
  level could still gain, extrapolated from the ratio of its rounds'
  successive gains (a level whose optimization was cut short, or that
  creeps towards a corner along a narrow valley, has not reached its
  minimum).

All the curves of a domain are refined together (:func:`refine_many`): their
polylines are stacked into one vectorized problem, so each Newton iteration
evaluates the metric once for every curve, and a curve that converges
drops out while the others go on.  The arithmetic of each curve is that of
refining it alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property, partial

import numpy as np
import scipy.sparse as sp
from scipy.linalg import LinAlgError
from scipy.linalg.lapack import dgtsv
from scipy.optimize import minimize
from scipy.sparse.linalg import spsolve

from . import parallel
from .grid import Domain, deformed_speeds
from .metric import Metric, _breaks, _vertex_params, segment_lengths

__all__ = ["refine", "refine_many", "coarse_geodesic", "coarse_geodesics", "RefinedPath", "GeodesicJob",
           "length_rounding"]



@dataclass(frozen=True)
class RefinedPath:
    """A refined geodesic: its polyline, length, and convergence record.

    Attributes
    ----------
    points : (n + 1, 2) ndarray
        Vertices in parameter space ``(x1, x2)`` (reference arclength), unwrapped.
    length : float
        Richardson-extrapolated length.
    upper : float
        Exact length of ``points`` (a real curve: an upper bound of the distance).
    error_estimate : float
        ``|L_n - L_{n/2}|`` (three times the Richardson correction applied),
        at least ``|L_{n/2} - L_{n/4}| / 4``: a level that stalls after one
        that moved has not converged.
    segments : int
        Number of segments of the final level.
    """

    points: np.ndarray
    length: float
    upper: float
    error_estimate: float
    segments: int

    def reversed(self) -> "RefinedPath":
        """The same geodesic run the other way (its points reversed, a copy)."""
        return RefinedPath(self.points[::-1].copy(), self.length, self.upper, self.error_estimate, self.segments)


def _resample(poly: np.ndarray, n: int) -> np.ndarray:
    """``n + 1`` points evenly spaced by Euclidean arclength along a polyline."""
    seg = np.linalg.norm(np.diff(poly, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] == 0:
        return np.repeat(poly[:1], n + 1, axis=0)
    u = np.linspace(0.0, s[-1], n + 1)
    return np.column_stack([np.interp(u, s, poly[:, 0]), np.interp(u, s, poly[:, 1])])


def _side(domain: Domain, ground: int, q: np.ndarray):
    """The boundary line through the end point ``q`` (parameters) of ground ``ground``.

    Returns ``(base, direction, (lo, hi))`` in parameters: the end slides on
    ``base + tau direction`` with ``lo <= tau <= hi``.
    """
    S, V = domain.local_lengths
    if domain.kind in ("cylinder", "annulus"):
        v = 0.0 if ground == 0 else V
        base = domain.to_param(np.array([[0.0, v]]))[0]
        e = domain.basis[:, 0] / np.linalg.norm(domain.basis[:, 0])
        return base, e, (-np.inf, np.inf)
    _, base, direction, rng = min(_sides(domain, q), key=lambda c: c[0])
    return base, direction, rng


def _sides(domain: Domain, q: np.ndarray) -> list:
    """The sides of a rectangle or triangle domain: ``(distance from q, base, direction, (lo, hi))`` each."""
    L1, L2 = domain.lengths
    out = [
        (abs(q[0]), np.array([0.0, 0.0]), np.array([0.0, 1.0]), (0.0, L2)),
        (abs(q[0] - L1), np.array([L1, 0.0]), np.array([0.0, 1.0]), (0.0, L2)),
        (abs(q[1]), np.array([0.0, 0.0]), np.array([1.0, 0.0]), (0.0, L1)),
        (abs(q[1] - L2), np.array([0.0, L2]), np.array([1.0, 0.0]), (0.0, L1)),
    ]
    if domain.kind == "triangle":
        out.append((abs(q[1] - q[0]) / np.sqrt(2), np.array([0.0, 0.0]), np.array([1.0, 1.0]) / np.sqrt(2),
                    (0.0, L1 * np.sqrt(2))))
    return out


#: the least central-difference step of the Hessian (:func:`_segment_derivatives`), relative to the domain: a few
#: thousand roundings of its coordinates (see :func:`_least_steps`)
_FD_FLOOR = 1e-12


def _least_steps(seg: np.ndarray, length: np.ndarray, scale: float) -> np.ndarray:
    """The central-difference steps of the Hessian for segments ``seg`` of curves ``length`` long (parameters).

    A step is 1e-3 of its segment, at most 1e-6 of the domain (``scale``),
    and at least 1e-9 of it: the rule every study validated.  A curve
    shorter than 1e-3 of the domain lowers that least step in proportion,
    down to ``_FD_FLOOR``: a least step of 1e-9 of the domain held the steps
    of a loop 1e-10 across at 200 times its segments, and its Newton
    stalled, 1.3e-3 (relative) above ``J`` with an estimate of 8.5e-4 (a
    pentagon loop with collinear vertices on an interval of length 2; a loop
    1 across on tails 1e10 long, 5e-4 above: a review at stop 48).  The
    proportional floor leaves every curve at least 1e-3 of its domain long
    as it was, bit for bit (lowering the floor to ``_FD_FLOOR`` everywhere
    moved most values of the studies, within their estimates, and made the
    built-in scenes slower: ``validation/same_values.py``).
    """
    least = np.maximum(1e-9 * scale * np.minimum(1.0, length / (1e-3 * scale)), _FD_FLOOR * scale)
    return np.minimum(1e-6 * scale, np.maximum(1e-3 * seg, least))


def _segment_derivatives(metric: Metric, comps, P: np.ndarray, Q: np.ndarray, step: float,
                         hessian: bool = True):
    """Length, gradient (m, 4) and Hessian (m, 4, 4) of each segment in its end coordinates ``(P1, P2, Q1, Q2)``.

    The gradient is exact (:func:`direct.metric.segment_lengths`); the Hessian
    is its central difference with step ``step``, symmetrized.
    """
    if not hessian:
        f, g = segment_lengths(metric, comps, P, Q, gradient=True)
        return f, g, None
    m = len(P)
    U = np.hstack([P, Q])
    st = np.broadcast_to(np.asarray(step, dtype=float), (m,))[:, None]  # one step per segment
    E = np.eye(4)
    Us = np.vstack([U] + [U + st * e for e in E] + [U - st * e for e in E])
    f, g = segment_lengths(metric, comps, Us[:, :2], Us[:, 2:], gradient=True)
    g = g.reshape(9, m, 4)
    H = np.stack([(g[1 + k] - g[5 + k]) / (2 * st) for k in range(4)], axis=1)  # H[:, k, :] = d grad / d u_k
    H = 0.5 * (H + H.transpose(0, 2, 1))
    return f[:m], g[0], H


def _clip(a, lo, hi, out=None):
    """``np.clip(a, lo, hi)`` as its two ufuncs, without its Python overhead (hot paths; a -0.0 may come out +0.0)."""
    return np.minimum(np.maximum(a, lo), hi, out=out)


def _row_norms(d: np.ndarray) -> np.ndarray:
    """``np.linalg.norm(d, axis=1)``, the same numbers, without its Python overhead (hot paths)."""
    return np.sqrt(np.add.reduce(d * d, axis=1))


def _project(domain: Domain, X: np.ndarray) -> np.ndarray:
    """Put polyline vertices (parameters, unwrapped) back into the closed domain."""
    if domain.kind == "torus":
        return X
    st = domain.to_local(X, wrap=False)
    S, V = domain.local_lengths
    ps, _ = domain.periodic
    if not ps:
        _clip(st[:, 0], 0.0, S, out=st[:, 0])
    _clip(st[:, 1], 0.0, V, out=st[:, 1])
    X = domain.to_param(st)
    if domain.kind == "triangle":
        low = X[:, 1] < X[:, 0]
        X[low] = 0.5 * (X[low, 0] + X[low, 1])[:, None]
    return X


FIXED, FREE, SLIDE = 0, 1, 2


class _Modes:
    """How each vertex of a polyline may move, as arrays (one row per vertex).

    ``kind[k]`` is ``FIXED`` (a crossing point), ``FREE`` (two unknowns) or
    ``SLIDE``: the vertex slides on the line ``base[k] + tau e[k]`` with
    ``lo[k] <= tau <= hi[k]`` (one unknown): a free end on the boundary, or a
    refraction point on a line where the metric's norm jumps.  ``base``,
    ``e``, ``lo`` and ``hi`` mean nothing on the other rows.
    """

    __slots__ = ("kind", "base", "e", "lo", "hi")

    def __init__(self, kind, base, e, lo, hi):
        self.kind, self.base, self.e, self.lo, self.hi = kind, base, e, lo, hi

    @classmethod
    def free(cls, n: int) -> _Modes:
        """``n`` free vertices."""
        return cls(np.full(n, FREE, dtype=np.int8), np.zeros((n, 2)), np.zeros((n, 2)), np.full(n, -np.inf),
                   np.full(n, np.inf))

    @classmethod
    def concat(cls, parts) -> _Modes:
        return cls(*(np.concatenate([getattr(m, a) for m in parts]) for a in cls.__slots__))

    def __len__(self) -> int:
        return len(self.kind)

    def __getitem__(self, idx) -> _Modes:
        """The modes of some vertices (a slice, an index array or a mask), as a new object."""
        return _Modes(*(getattr(self, a)[idx] for a in self.__slots__))

    def copy(self) -> _Modes:
        return _Modes(*(getattr(self, a).copy() for a in self.__slots__))

    def insert(self, at: np.ndarray, other: _Modes) -> _Modes:
        """``other``'s rows inserted before rows ``at`` (in order where ``at`` repeats), as :func:`numpy.insert`."""
        return _Modes(*(np.insert(getattr(self, a), at, getattr(other, a), axis=0) for a in self.__slots__))

    def doubled(self) -> _Modes:
        """The modes after a free midpoint is put in every segment."""
        n = len(self.kind)
        out = _Modes.free(2 * n - 1)
        for a in self.__slots__:
            getattr(out, a)[0::2] = getattr(self, a)
        return out

    def hold(self, k: np.ndarray, axis: np.ndarray, coord: np.ndarray) -> None:
        """Let vertices ``k`` slide (in place) on the lines ``x_axis = coord`` (vertex lines, no bounds)."""
        self.kind[k] = SLIDE
        self.e[k] = 0.0
        self.e[k, 1 - axis] = 1.0
        self.base[k] = 0.0
        self.base[k, axis] = coord
        self.lo[k], self.hi[k] = -np.inf, np.inf

    def set(self, k: int, kind: int, base=None, e=None, lo: float = -np.inf, hi: float = np.inf):
        """Set the mode of vertex ``k`` in place."""
        self.kind[k] = kind
        if kind == SLIDE:
            self.base[k], self.e[k], self.lo[k], self.hi[k] = base, e, lo, hi


class _Parametrization:
    """Vertices of a polyline as an affine function ``X = X0 + M z`` of the unknowns ``z``.

    ``modes`` (a :class:`_Modes`) says how each vertex moves: fixed, free
    (two unknowns) or sliding on a line (one unknown).  For a closed curve
    (``shift`` given) the last vertex is the first plus ``shift``.
    """

    def __init__(self, X: np.ndarray, modes: _Modes, shift=None):
        n = len(X) - 1
        self.n = n
        self.X0 = X.copy()
        if shift is None and not (modes.kind == FREE).any():
            self._sliding(modes)
            return
        rows, cols, vals = [], [], []
        nz = 0
        slides = []
        last = n - 1 if shift is not None else n
        first_cols = None
        for k in range(last + 1):
            kind = modes.kind[k]
            if kind == FIXED:
                continue
            self.X0[k] = 0.0
            if kind == FREE:
                rows.extend([2 * k, 2 * k + 1])
                cols.extend([nz, nz + 1])
                vals.extend([1.0, 1.0])
                entries = [(0, nz, 1.0), (1, nz + 1, 1.0)]
                nz += 2
            else:
                e, lo, hi = modes.e[k], float(modes.lo[k]), float(modes.hi[k])
                self.X0[k] = modes.base[k]
                rows.extend([2 * k, 2 * k + 1])
                cols.extend([nz, nz])
                vals.extend([e[0], e[1]])
                entries = [(0, nz, e[0]), (1, nz, e[1])]
                slides.append((nz, lo, hi))
                nz += 1
            if k == 0:
                first_cols = entries
        if shift is not None:
            self.X0[n] = self.X0[0] + shift
            for axis, col, val in first_cols or []:
                rows.append(2 * n + axis)
                cols.append(col)
                vals.append(val)
        self.nv = nz
        self._triplets = (rows, cols, vals)
        # one unknown per vertex at most, in vertex order, open curve: the Hessian in z is tridiagonal
        r, c, v = np.asarray(rows, dtype=int), np.asarray(cols, dtype=int), np.asarray(vals, dtype=float)
        vert = r // 2
        self.banded = bool(shift is None and nz > 0 and len(r) == 2 * nz and np.all(vert[0::2] == vert[1::2])
                           and np.all(np.diff(vert[0::2]) > 0) and np.all(c[0::2] == np.arange(nz))
                           and np.all(c[1::2] == c[0::2]))
        if self.banded:
            self.vertex = vert[0::2]  # vertex of each unknown
            self.E = np.column_stack([v[0::2], v[1::2]])  # its direction (rows 2k, 2k + 1 come in pairs)
            self._diag = (self.E * self.E).sum(axis=1)
        else:
            self._diag = np.asarray(self.M.multiply(self.M).sum(axis=0)).ravel()
        arr = np.array(slides, dtype=float).reshape(-1, 3)
        self._slide_idx, self._lo, self._hi = arr[:, 0].astype(int), arr[:, 1], arr[:, 2]

    def _sliding(self, modes: _Modes):
        """The common case, built with arrays: an open curve whose vertices are fixed or slide on lines.

        One unknown per moving vertex, in vertex order: the Hessian in ``z`` is tridiagonal.
        """
        k = np.flatnonzero(modes.kind == SLIDE)
        nz = len(k)
        self.nv = nz
        self.X0[k] = modes.base[k]
        self.E = modes.e[k]
        self.vertex = k
        self._diag = (self.E * self.E).sum(axis=1)
        self._slide_idx, self._lo, self._hi = np.arange(nz), modes.lo[k], modes.hi[k]
        self.banded = nz > 0
        rows = np.column_stack([2 * k, 2 * k + 1]).ravel()
        cols = np.repeat(np.arange(nz), 2)
        self._triplets = (rows, cols, self.E.ravel())

    @cached_property
    def M(self) -> sp.csr_matrix:
        """The matrix of ``X = X0 + M z`` (vertices flattened as ``x1, x2`` pairs)."""
        rows, cols, vals = self._triplets
        return sp.csr_matrix((vals, (rows, cols)), shape=(2 * (self.n + 1), max(self.nv, 1)))

    def pack(self, X: np.ndarray) -> np.ndarray:
        """Least-squares unknowns of vertices ``X`` (exact when ``X`` is of the form ``X0 + M z``).

        Each row of ``M`` has at most one entry, so ``M^T M`` is diagonal.
        """
        if self.nv == 0:
            return np.zeros(0)
        if self.banded:
            return self.clip(((X - self.X0)[self.vertex] * self.E).sum(axis=1) / self._diag)
        return self.clip((self.M.T @ (X - self.X0).ravel()) / self._diag)

    def clip(self, z):
        """Keep sliding vertices within their stretch of line."""
        k = self._slide_idx
        if k.size:
            z[k] = _clip(z[k], self._lo, self._hi)
        return z

    def unpack(self, z: np.ndarray) -> np.ndarray:
        if self.banded:
            X = self.X0.copy()
            X[self.vertex] += z[:, None] * self.E
            return X
        return self.X0 + (self.M @ z).reshape(-1, 2)


def _speed_lookup(domain: Domain, metric: Metric):
    """``at(X) -> (|phi'(x1)|, |phi'(x2)|)`` per vertex, for the metrics isotropic in the deformed arclength; else None.

    Speeds as in the grid coordinate (:func:`direct.grid.deformed_speeds`),
    tabulated once per domain.  Not for a degenerate metric (``euclid``),
    which is not isotropic there: with the normals of :func:`_normal_modes`
    in the deformed arclength, one of the random scenes of
    ``validation/euclid.py`` (interval seed 10) settled in a local geodesic
    2.0e-3 longer, beyond its estimate.
    """
    if not metric.deformed_grid or metric.degenerate:
        return None
    tables = [deformed_speeds(comp) for comp in domain.comps]

    def at(X: np.ndarray) -> np.ndarray:
        out = np.empty((len(X), 2))
        for k, comp in enumerate(domain.comps):
            x = np.mod(X[:, k], comp.length) if comp.closed else X[:, k]
            out[:, k] = tables[k][comp.segment_index(x)]
        return out

    return at


def _normal_modes(X: np.ndarray, modes: _Modes, closed: bool, speed_at=None) -> _Modes:
    """Let each free vertex move only across the polyline, along its normal.

    Moving vertices along a geodesic barely changes its length (not at all
    where it is straight), so with both coordinates free the Hessian is
    nearly singular and Newton creeps; the normal offsets alone are well
    conditioned.  The spacing of the vertices stays that of the resampled
    route and its midpoint refinements, the family Richardson extrapolation
    assumes (but where the L-BFGS-B polish, after a round Newton left
    unconverged, moves them along it: :func:`_settle`).

    With ``speed_at`` (:func:`_speed_lookup`), on the free vertices next to
    an end that slides on the boundary (up to the first vertex held on a
    vertex line), the normal is that of the deformed arclengths ``sigma_k``,
    in which ``G`` is isotropic, mapped back to the parameters:
    ``(-s2^2 t2, s1^2 t1)`` for a tangent ``t``.  A geodesic meets the
    boundary at a right angle in ``sigma`` (the free end of eq. (9)), so the
    end slides along its neighbours' normals.  With the Euclidean normal of
    the parameters, two arms whose speeds differ 14 times made that angle
    shallow in the parameters, the end slid along the curve against
    neighbours that could only move across it, and stuck: 2.2e-4 relative
    too long at ``tol=1e-5`` with an estimate of 2.8e-5
    (``tests/test_references.py``).  Elsewhere the Euclidean normal stays:
    with the normal in ``sigma`` on whole curves, curves that cross many
    vertex lines where the speed jumps settled in other local geodesics,
    one of the random scenes of ``validation/default_tol.py`` (seed 203)
    7.0e-4 too long at ``tol=1e-3``, beyond its estimate.
    """
    if closed:
        prev = np.roll(X[:-1], 1, axis=0)
        nxt = np.roll(X[:-1], -1, axis=0)
        prev[0] = X[-2] - (X[-1] - X[0])
        tangent = np.vstack([nxt - prev, [[0.0, 0.0]]])
    else:
        tangent = np.zeros_like(X)
        tangent[1:-1] = X[2:] - X[:-2]
    across = np.column_stack([-tangent[:, 1], tangent[:, 0]])
    if speed_at is not None and not closed:
        near = np.zeros(len(X), dtype=bool)
        slide = np.flatnonzero(modes.kind == SLIDE)
        if modes.kind[0] == SLIDE:  # an end on the boundary: the free run up to the first break
            stop = slide[slide > 0]
            near[: (stop[0] if stop.size else len(X))] = True
        if modes.kind[-1] == SLIDE:
            stop = slide[slide < len(X) - 1]
            near[(stop[-1] + 1 if stop.size else 0):] = True
        if near.any():
            speeds = speed_at(X[near])
            across[near, 0] *= (speeds[:, 1] / speeds[:, 0]) ** 2
    norm = np.hypot(across[:, 0], across[:, 1])
    safe = np.where(norm > 0, norm, 1.0)
    normal = np.where((norm > 0)[:, None], across / safe[:, None], np.array([1.0, 0.0]))
    free = modes.kind == FREE
    out = modes.copy()
    out.kind[free] = SLIDE
    out.base[free], out.e[free] = X[free], normal[free]
    out.lo[free], out.hi[free] = -np.inf, np.inf
    return out


def _on_ground(domain: Domain, ground: int, X: np.ndarray) -> np.ndarray:
    """Whether each vertex lies on boundary part ``ground`` (to rounding)."""
    st = domain.to_local(X, wrap=False)
    S, V = domain.local_lengths
    eps = 1e-12 * max(S, V)
    if domain.kind in ("cylinder", "annulus"):
        return np.abs(st[:, 1] - (0.0 if ground == 0 else V)) <= eps
    on = (np.abs(st[:, 1]) <= eps) | (np.abs(st[:, 1] - V) <= eps)
    on |= (np.abs(st[:, 0]) <= eps) | (np.abs(st[:, 0] - S) <= eps)
    if domain.kind == "triangle":
        on |= np.abs(X[:, 1] - X[:, 0]) <= eps
    return on


def _grade_ends(domain: Domain, X: np.ndarray, modes: _Modes, start_ground, end_ground, scale: float):
    """Free vertices at ``1/2, 1/4, 1/8, ...`` of the segment next to an end that slides on the boundary.

    A geodesic may bend sharply just before it reaches the boundary: a grazing
    crossing's narrow valley runs into a corner and the curve turns onto a
    side within a distance of the order of the angle.  Uniform doubling
    would need thousands of segments to see the turn; a geometric grading
    sees it with a dozen vertices (down to ``1e-6`` of the domain).
    """
    for at_start, ground in ((True, start_ground), (False, end_ground)):
        if ground is None or len(X) < 2:
            continue
        end, nb = (X[0], X[1]) if at_start else (X[-1], X[-2])
        length = float(np.linalg.norm(nb - end))
        depth = int(np.clip(np.floor(np.log2(max(length, 1e-300) / (1e-6 * scale))), 0, 14))
        if depth < 2:
            continue
        frac = 0.5 ** np.arange(1, depth + 1)  # distance from the end, as a fraction of the segment
        pts = end[None, :] + frac[:, None] * (nb - end)[None, :]
        if at_start:
            X = np.vstack([X[:1], pts[::-1], X[1:]])
            modes = _Modes.concat([modes[:1], _Modes.free(depth), modes[1:]])
        else:
            X = np.vstack([X[:-1], pts, X[-1:]])
            modes = _Modes.concat([modes[:-1], _Modes.free(depth), modes[-1:]])
    return X, modes


def _corner_switch(domain: Domain, metric: Metric, X: np.ndarray, modes: _Modes, k: int) -> _Modes:
    """Let an end held at a corner of the boundary slide on the other side if that is cheaper.

    An end slides on one side of a rectangle or triangle; the optimizer
    stops it at the corner where that side ends, even when the geodesic
    wants to go on along the other side (a grazing crossing, whose narrow
    valley runs into the corner).  Try a small step along every side through
    that corner and keep the side of the cheapest.
    """
    if modes.kind[k] != SLIDE or domain.kind in ("cylinder", "annulus", "torus"):
        return modes
    q = X[k]
    tiny = 1e-12 * max(domain.lengths)
    through = [sd for sd in _sides(domain, q) if sd[0] <= tiny]
    if len(through) < 2:
        return modes
    nb = X[k - 1] if k > 0 else X[1]
    step = 1e-3 * float(np.linalg.norm(q - nb))

    def cost(p):
        return float(segment_lengths(metric, domain.comps, nb[None, :], p[None, :])[0])

    best, best_mode = cost(q), None
    for _, base, e, (lo, hi) in through:
        tau = float((q - base) @ e)
        for sgn in (1.0, -1.0):
            t = tau + sgn * step
            if lo <= t <= hi:
                c = cost(base + t * e)
                if c < best:
                    best, best_mode = c, (base, e, lo, hi)
    if best_mode is None:
        return modes
    out = modes.copy()
    out.set(k, SLIDE, *best_mode)
    return out


def _truncate_at_boundary(domain: Domain, ground: int, X: np.ndarray, modes: _Modes) -> tuple[np.ndarray, _Modes]:
    """End a curve bound for the boundary where it first reaches it.

    The rest of the polyline runs on or back from the boundary, where the
    curve could have stopped at no cost (eq. (9) lets it end anywhere there);
    cutting it only shortens it and frees the optimizer, which cannot move
    vertices held on the boundary by the projection.
    """
    on = _on_ground(domain, ground, X)
    on[0] = False
    hit = np.flatnonzero(on)
    if hit.size == 0 or hit[0] == len(X) - 1:
        return X, modes
    k = int(hit[0])
    X = X[: k + 1].copy()
    base, e, (lo, hi) = _side(domain, ground, X[k])
    modes = modes[: k + 1].copy()
    modes.set(k, SLIDE, base, e, lo, hi)
    return X, modes


def _truncate_ends(domain: Domain, X: np.ndarray, modes: _Modes, start_ground, end_ground) -> tuple[np.ndarray, _Modes]:
    """:func:`_truncate_at_boundary` at each end that slides on the boundary (a start as the end of the reversed curve).

    A curve from the boundary to a crossing point starts where it last
    leaves the boundary: vertices held there by the projection (a run of
    dozens of them on the diagonal, where ``G`` vanishes and moving them
    changes no length) otherwise pin its start where the coarse pass left
    it.  Measured on the figure eight of
    ``test_figure_eight_crossing_on_vertices_in_every_listing``, refined
    from beside its straight curve (a local geodesic 6.7 % longer): the
    curve stopped 5.4 % above the shortest with an estimate of 3.1e-6;
    with the cut, 4.6 % above with 2.1e-3 (the start creeps along the
    diagonal, a level at a time: better, not right;
    ``test_a_curve_from_the_boundary_starts_where_it_last_leaves_it``).
    """
    if end_ground is not None:
        X, modes = _truncate_at_boundary(domain, end_ground, X, modes)
    if start_ground is not None:
        Xr, mr = _truncate_at_boundary(domain, start_ground, X[::-1], modes[::-1])
        if len(Xr) < len(X):
            X, modes = Xr[::-1].copy(), mr[::-1]
    return X, modes


def _unfold(domain: Domain, metric: Metric, routes: list[np.ndarray], max_passes: int = 50) -> list[np.ndarray]:
    """Cut the folds out of grid routes: drop a vertex where the route turns back, if that shortens it.

    On a grid that is coarse beside the scene's features a route may leave a
    crossing point towards a grid node behind it and come back (the metric
    nearly vanishes there, so the detour costs the grid little).  The
    refinement moves vertices across the curve only, so it can straighten
    bends but never pull such a fold out: it would settle on a curve longer
    than the geodesic (measured: 0.4 % on the 100-crossing zigzag at
    resolution 128) with a small estimate.  Each pass drops, on every route
    at once, the vertices where the route turns by more than 90 degrees and
    whose removal shortens its exact length (not two neighbours in one
    pass).  A chord between two vertices stays in the domain (its local
    coordinates are convex and routes are unwrapped across seams) and keeps
    the curve's homotopy class.  Ends are kept, and so is the first vertex of
    a closed route.
    """
    routes = [np.asarray(r, dtype=float) for r in routes]
    todo = [i for i, r in enumerate(routes) if len(r) >= 3]
    for _ in range(max_passes):
        if not todo:
            break
        rs = [routes[i] for i in todo]
        sizes = np.array([len(r) - 2 for r in rs])
        A = np.vstack([r[:-2] for r in rs])
        B = np.vstack([r[1:-1] for r in rs])
        C = np.vstack([r[2:] for r in rs])
        back = ((B - A) * (C - B)).sum(axis=1) < 0  # turns by more than 90 degrees
        gain = np.zeros(len(B))
        if back.any():
            k = np.flatnonzero(back)
            two = segment_lengths(metric, domain.comps, np.vstack([A[k], B[k]]), np.vstack([B[k], C[k]]))
            one = segment_lengths(metric, domain.comps, A[k], C[k])
            both = two[: len(k)] + two[len(k):]
            gain[k] = np.where(both - one > 1e-12 * both, both - one, 0.0)  # above rounding
        still = []
        off = 0
        for i, r, m in zip(todo, rs, sizes):
            g = gain[off:off + m]
            off += m
            # not two neighbours at once: each dropped vertex gains more than the ones beside it
            drop = (g > 0) & (g >= np.concatenate([[0.0], g[:-1]])) & (g > np.concatenate([g[1:], [0.0]]))
            if drop.any():
                routes[i] = np.vstack([r[:1], r[1:-1][~drop], r[-1:]])
                if len(routes[i]) >= 3:
                    still.append(i)
        todo = still
    return routes


def _resampled_with_ends(domain: Domain, route: np.ndarray, n: int, start_ground, end_ground, closed: bool):
    """``n`` segments evenly along the route; ends fixed (crossing points) or sliding on their boundary."""
    X = _resample(route, n)
    return X, _end_modes(domain, X, start_ground, end_ground, closed)


def _end_modes(domain: Domain, X: np.ndarray, start_ground, end_ground, closed: bool) -> _Modes:
    """Free vertices, the ends fixed (crossing points) or sliding on their boundary."""
    n = len(X) - 1
    modes = _Modes.free(n + 1)
    if not closed:
        for k, ground in ((0, start_ground), (n, end_ground)):
            if ground is None:
                modes.set(k, FIXED)
            else:
                base, e, (lo, hi) = _side(domain, ground, X[k])
                modes.set(k, SLIDE, base, e, lo, hi)
    return modes


def _initial_polyline(domain: Domain, route: np.ndarray, start: int, start_ground, end_ground, closed: bool):
    """First polyline of the refinement: the vertices of ``route`` and its crossings with the cell lines.

    ``route`` is a coarse geodesic (or a grid route, where that is shorter).
    Each segment then lies in one cell, where the length is a smooth function
    of its ends.  The route's own vertices stay, so the polyline has exactly
    the route's length: resampling it evenly cut its corners, and where the
    metric vanishes along whole lines (a multiple cover, ``fig13``) the cut
    corners left the curve in a worse local minimum (measured: 1.5e-4
    relative too high at 96 cells, with an estimate of 5e-6).  Segments are
    halved until there are at least ``start``.
    """
    X = np.asarray(route, dtype=float)
    while len(X) - 1 < start:
        X = _midpoints(X)
    return _insert_breaks(domain, X, _end_modes(domain, X, start_ground, end_ground, closed))


#: a segment shorter than this fraction of its curve's mean segment has collapsed (see _merge_collapsed)
_COLLAPSED = 1e-4


def _merge_collapsed(X: np.ndarray, modes: _Modes, rel: float = _COLLAPSED) -> tuple[np.ndarray, _Modes]:
    """Merge the vertices that have landed on each other.

    A refraction vertex on a vertex line met at a shallow angle (a valley of
    the metric's norm) can slide onto its free neighbours.  The very short
    segments left between them are kinks that neither Newton nor L-BFGS can
    cross, each doubling splits them again, and the levels then converge, at
    the expected rate, to a pinned curve: the error estimate misses it.
    Measured on the limaçon ``r = 0.7 + cos t`` at 32 vertices: four free
    vertices 1.6e-8 to 6.3e-8 of a cell from a line vertex (segments of about
    2e-8 of a cell; 2e-6 of the mean in a rerun of the same kind, above the
    threshold of ``1e-6`` this had then) held a curve 3.6e-6 relative above
    the geodesic of its own sequence of cells, with an estimate of 3.4e-8, at
    ``tol=1e-5``.

    Each run of two or more consecutive segments shorter than ``rel`` times
    the mean segment is merged into one vertex: its vertices on lines (or
    fixed) stay, its free vertices go (one stays where the run has no other),
    and :func:`_insert_breaks` puts back a refraction vertex where the curve
    still crosses a line.  A single short segment merges only below ``1e-6``
    of the mean (the old threshold): merging those from ``1e-4`` made seed 3 of
    ``test_local_refinement_and_the_uniform_grid_agree_within_their_estimates``
    2.5 times slower (81 s against 32 s at ``tol=1e-5``) and 3e-6 higher, and
    let two curves of the star polygon of 9 vertices creep over 1,000
    segments.  A run at an end of the curve is the geometric grading of an
    end that slides on the boundary (:func:`_grade_ends`, down to ``1e-6`` of
    the domain), and stays unless its segments are shorter than ``1e-6`` of
    the mean.
    """
    n = len(X)
    if n <= 3:
        return X, modes
    seg = np.linalg.norm(np.diff(X, axis=0), axis=1)
    mean = seg.mean()
    tiny = seg < rel * mean
    if not tiny.any():
        return X, modes
    # runs of tiny segments: segments a..b join vertices a..b + 1
    edges = np.diff(np.concatenate([[0], tiny.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    keep = np.ones(n, dtype=bool)
    for a, b in zip(starts, stops):
        if a == 0 or b == n - 2:  # the grading of a sliding end: only what has collapsed within it
            for s in range(a, b + 1):
                if seg[s] < 1e-6 * mean and keep[s] and keep[s + 1]:
                    movable = [k for k in (s + 1, s) if 0 < k < n - 1 and modes.kind[k] != FIXED]
                    free = [k for k in movable if modes.kind[k] == FREE]
                    if movable:
                        keep[(free or movable)[0]] = False
            continue
        if b == a and seg[a] >= 1e-6 * mean:
            continue
        run = np.arange(a, b + 2)
        free = run[modes.kind[run] == FREE]
        if len(free) == len(run):
            free = free[1:]  # one vertex stays
        keep[free] = False
    return X[keep], modes[keep]


def _drop_folds(X: np.ndarray, modes: _Modes) -> tuple[np.ndarray, _Modes]:
    """Drop free vertices where the polyline turns back on itself (by more than 120 degrees).

    A geodesic is smooth between the lines where the metric's norm jumps, and
    refracts there by less than a right angle, so such a turn is a fold: a
    few vertices overshot along the curve and the curve runs back over them.
    Moves across the curve (the only ones Newton makes) cannot undo it, and
    the doubling keeps it at every level (a crossing near a corner: a fold of
    5e-5 next to the crossing point, the length 8.1e-5 too long with an
    estimate of 3.0e-5).  One vertex per fold goes at a time, until none is left.
    """
    for _ in range(len(X)):
        if len(X) <= 3:
            break
        d = np.diff(X, axis=0)
        norm = np.linalg.norm(d, axis=1)
        # at interior vertex k + 1; a geodesic that turns onto a side just before a corner makes turns of up to
        # about 100 degrees at a coarse level, which are not folds (dropping them cost 2.2e-4 on a random scene)
        turn = (d[:-1] * d[1:]).sum(axis=1) < -0.5 * norm[:-1] * norm[1:]
        free = modes.kind[1:-1] == FREE
        fold = np.flatnonzero(turn & free) + 1
        if fold.size == 0:
            break
        drop = fold[np.concatenate([[True], np.diff(fold) > 1])]  # not two neighbours at once
        keep = np.ones(len(X), dtype=bool)
        keep[drop] = False
        X, modes = X[keep], modes[keep]
    return X, modes


def _on_lines(modes: _Modes) -> tuple[np.ndarray, np.ndarray]:
    """Which vertices slide on a vertex line, and the coordinate that is constant on it (0: ``x1``, 1: ``x2``).

    Interior vertices only: the ends of a curve are crossing points, or slide
    on the boundary (whose sides are lines of constant ``x1`` or ``x2`` too).
    """
    e = modes.e
    on = (modes.kind == SLIDE) & (e[:, 0] * e[:, 1] == 0)
    on[[0, -1]] = False
    return on, np.where(e[:, 0] == 0.0, 0, 1)


def _held_segments(X: np.ndarray, modes: _Modes) -> np.ndarray:
    """Which segments have both ends held on the same vertex line (a stretch on a crease, :func:`_hold_on_lines`)."""
    on, axis = _on_lines(modes)
    k = np.arange(len(X) - 1)
    return on[:-1] & on[1:] & (axis[:-1] == axis[1:]) & (X[k, axis[:-1]] == X[k + 1, axis[:-1]])


def _prune_breaks(X: np.ndarray, modes: _Modes) -> tuple[np.ndarray, _Modes]:
    """Drop refraction vertices whose neighbours are on the same side of their line, and those inside a stretch.

    Such a vertex only touches the line: the curve no longer crosses it there,
    and holding a vertex on it would keep the curve in a sequence of cells it
    has left.  :func:`_insert_breaks` adds back the crossings that remain.  A
    vertex inside a stretch held on its line (both neighbours on the line,
    :func:`_hold_on_lines`) goes too: the straight segment between its
    neighbours is the same curve.  One at an end of a stretch (one neighbour
    on the line) stays.  A neighbour within 1e-9 of its segment of the line
    is on it: a free midpoint 1e-14 off the line beside the end of a stretch
    0.026 long, taken for a touch, dropped the end, and the segment that
    replaced the two cut across the crease, 2.2e-5 longer (4e-4 relative;
    interval seed 263 of ``validation/tol_1e5.py``, its estimate 1.0e-4).

    Setting a touching vertex free instead, where dropping it made the curve
    longer, left a free vertex on the line, on the kink of the length: on the
    torus of two 128-gons 0.6 apart of ``validation/closed_searches.py`` the
    value came out 9.5e-7 (relative) higher, with an estimate of 3.7e-5
    against 1.5e-5, in 7.7 s against 2.9 s (not kept).
    """
    if len(X) < 3:
        return X, modes
    on, axis = _on_lines(modes)
    on_line, axis = on[1:-1], axis[1:-1]
    k = np.arange(1, len(X) - 1)
    c = X[k, axis]
    before, after = X[k - 1, axis] - c, X[k + 1, axis] - c
    seg = np.linalg.norm(np.diff(X, axis=0), axis=1)
    on_before, on_after = np.abs(before) <= 1e-9 * seg[:-1], np.abs(after) <= 1e-9 * seg[1:]
    touch = on_line & (((before * after > 0) & ~on_before & ~on_after) | (on_before & on_after))
    if not touch.any():
        return X, modes
    keep = np.ones(len(X), dtype=bool)
    keep[1:-1] = ~touch
    return X[keep], modes[keep]


def _through(metric: Metric, comps, A: np.ndarray, B: np.ndarray, Ms: list) -> np.ndarray:
    """Lengths of ``A -> M -> B`` for each array of points ``M`` in ``Ms``, in one evaluation: ``(len(Ms), m)``."""
    k = len(Ms)
    L = segment_lengths(metric, comps, np.concatenate([A] * k + list(Ms)), np.concatenate(list(Ms) + [B] * k))
    L = L.reshape(2, k, len(A))
    return L[0] + L[1]


def _ranges(start: np.ndarray, count: np.ndarray) -> np.ndarray:
    """``start[i], start[i] + 1, ..., start[i] + count[i] - 1`` for every ``i``, concatenated."""
    return np.repeat(start - np.cumsum(count) + count, count) + np.arange(count.sum())


def _off_line(metric: Metric, comps, A: np.ndarray, M: np.ndarray, B: np.ndarray, axis: np.ndarray,
              step: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Probe each vertex ``M`` (between ``A`` and ``B``) off its line: ``(shorter, where)``.

    ``M`` is moved by ``step`` across its line of constant ``x_axis``, either
    way; ``shorter`` says whether ``A -> M -> B`` gets shorter on the better
    side, and ``where`` is the moved vertex on that side.
    """
    off = np.zeros((len(M), 2))
    off[np.arange(len(M)), axis] = step
    L = _through(metric, comps, A, B, [M, M - off, M + off])
    where = M + np.where(np.argmin(L[1:], axis=0) == 0, -1.0, 1.0)[:, None] * off
    return L[1:].min(axis=0) < L[0], where


def _hold_on_lines(metric: Metric, comps, X: np.ndarray, modes: _Modes, near: float = 1e-3,
                   probe: float = 1e-5) -> tuple[np.ndarray, _Modes]:
    """Hold on its vertex line a stretch of the polyline that runs along it; let go where leaving it is shorter.

    Where a corner of a component points towards the other point, the
    metric's norm has a crease along the vertex line, a valley with slopes on
    both sides, and the geodesic runs in it.  Newton leaves the free
    vertices of such a stretch a hair off the line on either side (1e-10 of
    a cell, on seed 123 of ``validation/tol_1e5.py``), and
    :func:`_insert_breaks` puts a vertex at every crossing: 617 of the 2,027
    vertices of its chosen curve were on one line, each level grew three
    times, and the starts made from the curve took 38 s of its 59 s.

    Hold: the vertices between two consecutive vertices held on the same
    line are put on it and slide on it (free ones, and those held on the
    lines it crosses) when every one of them is within ``near`` times the
    run's chord over its number of segments of the line and the run's exact
    length does not grow; :func:`_prune_breaks` then
    drops the vertices inside the stretch, whose straight segment is the
    same curve, and neither :func:`_insert_breaks` nor :func:`_doubled` put
    vertices back on it.

    Let go: the midpoint of each segment between two vertices held on the
    same line is moved off the line by ``probe`` times the segment, on
    either side; where that is shorter, the line is no valley there, and
    the moved midpoint is put in, free, for the next round to carry on.
    Then the stretches grow and shrink at their ends by a vertex a round
    (:func:`_grow_stretches`, :func:`_unzip_ends`).  Every move is measured
    with the exact lengths and taken only where the curve gets no longer.

    A vertex that moves across the crease (a free one on it, or one held on
    a line it crosses) sits on the kink of the length, where Newton's
    finite-difference Hessian is huge: a level of 515 segments "converged"
    without moving, its length equal to the level's before, with a
    Richardson estimate (1.7e-6) below the curve's error (2.1e-6; interval
    seed 105 of ``validation/tol_1e5.py``, while the vertices on the lines
    the stretch crosses still slid across it).  The stretch holds none.
    """
    n = len(X)
    if n < 3:
        return X, modes
    on, axis = _on_lines(modes)
    a, b = [], []
    for ax in (0, 1):  # consecutive vertices held on lines of constant x_ax (those on the others may lie between)
        idx = np.flatnonzero(on & (axis == ax))
        same = X[idx[:-1], ax] == X[idx[1:], ax]
        a.append(idx[:-1][same])
        b.append(idx[1:][same])
    a, b = np.concatenate(a), np.concatenate(b)
    if not len(a):
        return X, modes
    # let go: segments on a line (consecutive held vertices)
    seg_on = np.flatnonzero(_held_segments(X, modes))
    insert_at, insert_pts = np.empty(0, dtype=int), np.empty((0, 2))
    if len(seg_on):
        P, Q = X[seg_on], X[seg_on + 1]
        leave, where = _off_line(metric, comps, P, 0.5 * (P + Q), Q, axis[seg_on],
                                 probe * np.linalg.norm(Q - P, axis=1))
        insert_at, insert_pts = seg_on[leave] + 1, where[leave]
    # hold: runs of vertices near the line between two held vertices of it
    gap = b > a + 1
    a, b = a[gap], b[gap]
    Y, new = X, modes
    if len(a):
        count = b - a - 1
        inner = _ranges(a + 1, count)
        run = np.repeat(np.arange(len(a)), count)
        ax = axis[a][run]
        v = X[a, axis[a]][run]
        kind = modes.kind[inner]
        movable = (kind == FREE) | ((kind == SLIDE) & (modes.e[inner, 1 - ax] == 0.0) & (modes.e[inner, ax] != 0.0))
        h = np.linalg.norm(X[b] - X[a], axis=1) / (b - a)  # the run's chord over its number of segments
        close = np.abs(X[inner, ax] - v) <= near * h[run]
        # runs that share a vertex (a curve that turns at a cell corner from one line onto the other), or move
        # the end of another run or of a segment let go, are left as they are: each run taken is then measured
        # alone, and a vertex slides on one line only
        ends = np.zeros(n, dtype=bool)
        ends[a] = ends[b] = True
        ends[insert_at - 1] = ends[insert_at] = True
        alone = (np.bincount(inner, minlength=n)[inner] == 1) & ~ends[inner]
        ok = np.ones(len(a), dtype=bool)
        np.logical_and.at(ok, run, movable & close & alone)
        Y = X.copy()
        Y[inner[ok[run]], ax[ok[run]]] = v[ok[run]]
        # a run is taken only if its segments (a .. b - 1) are not longer on the line
        n_seg = b - a
        owner = np.repeat(np.arange(len(a)), n_seg)
        segs = _ranges(a, n_seg)
        before = np.bincount(owner, segment_lengths(metric, comps, X[segs], X[segs + 1]), minlength=len(a))
        after = np.bincount(owner, segment_lengths(metric, comps, Y[segs], Y[segs + 1]), minlength=len(a))
        ok &= after <= before
        take = ok[run]
        Y[inner[~take], ax[~take]] = X[inner[~take], ax[~take]]
        new = modes.copy()
        # every vertex put on the line slides on it (one held on a crossing line, a cell corner, would move across
        # the crease, where the length has a kink); inside the stretch they go (:func:`_prune_breaks`), and no
        # vertex is put back where the stretch crosses lines (:func:`_insert_breaks`)
        new.hold(inner[take], ax[take], v[take])
    Y, new = _grow_stretches(metric, comps, Y, new)
    Y, new = _unzip_ends(metric, comps, Y, new, probe, insert_at - 1)
    if len(insert_at):
        Y = np.insert(Y, insert_at, insert_pts, axis=0)
        new = new.insert(insert_at, _Modes.free(len(insert_at)))
    return Y, new


def _unzip_ends(metric: Metric, comps, X: np.ndarray, modes: _Modes, probe: float,
                busy=()) -> tuple[np.ndarray, _Modes]:
    """Set free, moved off its line, the end of a stretch held on a line, where that makes the curve shorter.

    The other half of :func:`_grow_stretches`.  Two vertices held on the same
    line can also come from a curve that crosses it at a shallow angle (a
    vertex line crossed twice in a row, at a coarser level); the midpoint
    probe of :func:`_hold_on_lines` cannot see that the segment should turn
    (one end to either side), and the curve stayed on the line: on the torus
    of two 128-gons 0.6 apart of ``validation/closed_searches.py`` (default
    ``tol``) the value came out 2.2e-5 (relative) above the exact length of
    the curves found with this, beyond its estimate (1.9e-5); on the one of
    two 128-gons 0.3 apart, 1.2e-5 above (estimate 1.2e-4).  Each
    round, an end (one neighbour held on the same line, the other not) is
    moved off the line by ``probe`` times its held segment, to the side where
    its two segments are shorter, and set free; the stretch then shrinks by
    a vertex at each end where the curve does not follow the crease.  Not
    the ends of the segments ``busy`` (whose midpoints leave the line).
    """
    n = len(X)
    if n < 3:
        return X, modes
    held = _held_segments(X, modes)
    before, after = np.concatenate([[False], held]), np.concatenate([held, [False]])  # per vertex
    end = before ^ after
    end[0] = end[-1] = False
    busy = np.asarray(busy, dtype=int)
    end[busy] = end[busy + 1] = False
    k = np.flatnonzero(end)
    if not len(k):
        return X, modes
    _, axis = _on_lines(modes)
    ax = axis[k]
    h = np.where(before[k], np.linalg.norm(X[k] - X[k - 1], axis=1), np.linalg.norm(X[k + 1] - X[k], axis=1))
    take, where = _off_line(metric, comps, X[k - 1], X[k], X[k + 1], ax, probe * h)
    take[1:] &= ~(take[:-1] & (np.diff(k) == 1))  # not both ends of one held segment at once
    if not take.any():
        return X, modes
    X = X.copy()
    X[k[take]] = where[take]
    modes = modes.copy()
    modes.kind[k[take]] = FREE
    return X, modes


def _grow_stretches(metric: Metric, comps, X: np.ndarray, modes: _Modes) -> tuple[np.ndarray, _Modes]:
    """Put on the line the free vertex beside a vertex held on it, where that makes the curve shorter.

    A geodesic joins a crease tangentially, so the free vertices beside the
    end of a stretch approach the line only slowly, and the end itself
    slides along it where the length barely changes.  Each round, the free
    neighbour of a vertex held on a line (not between two vertices held on
    it: :func:`_hold_on_lines`' runs) is put on that line if its two
    segments get shorter (exact lengths); the stretch then grows by a vertex
    at each end where the curve follows the crease (:func:`_unzip_ends`
    shrinks it).  Without this, at ``tol=1e-5``: interval seed 203 of
    ``validation/tol_1e5.py`` took 3.9 s against 1.8 s, its estimate 7.3e-6
    against 3.5e-6 (relative), seed 218 warned (1.6e-5 against 1.0e-5), and
    the torus of two 128-gons 0.6 apart of ``validation/closed_searches.py``
    (default ``tol``) came out 1.8e-6 higher, its curves' exact length too.
    """
    n = len(X)
    if n < 3:
        return X, modes
    on, axis = _on_lines(modes)
    j = np.arange(1, n - 1)
    tries, cands = [], []
    for nb in (j - 1, j + 1):  # a neighbour held on a line: the free vertex put on that line
        other = 2 * j - nb
        ax = axis[nb]
        v = X[nb, ax]
        cands.append((modes.kind[j] == FREE) & on[nb] & ~(on[other] & (axis[other] == ax) & (X[other, ax] == v)))
        Y = X[j].copy()
        Y[np.arange(n - 2), ax] = v
        tries.append(Y)
    some = cands[0] | cands[1]
    if not some.any():
        return X, modes
    j = j[some]
    tries = [Y[some] for Y in tries]
    L = _through(metric, comps, X[j - 1], X[j + 1], [X[j]] + tries)
    gain = np.where(np.vstack([c[some] for c in cands]), L[0] - L[1:], 0.0)
    pick = np.argmax(gain, axis=0)
    take = gain.max(axis=0) > 0.0
    take[1:] &= ~(take[:-1] & (np.diff(j) == 1))  # not two neighbours at once (they share a segment)
    if not take.any():
        return X, modes
    k = j[take]
    Y = np.where((pick[take] == 0)[:, None], tries[0][take], tries[1][take])
    ax = np.where(pick[take] == 0, axis[k - 1], axis[k + 1])
    X = X.copy()
    X[k] = Y
    modes = modes.copy()
    modes.hold(k, ax, X[k, ax])
    return X, modes


def _insert_breaks(domain: Domain, X: np.ndarray, modes: _Modes) -> tuple[np.ndarray, _Modes]:
    """Add a sliding vertex where the polyline crosses a vertex parameter of either component.

    There the metric's norm jumps and the geodesic refracts; with a vertex on
    the line, every segment stays in one cell, where the length is smooth.
    Not on a segment held on a vertex line (a stretch on a crease,
    :func:`_hold_on_lines`): it only moves along its line, its length is
    smooth in its ends, and a vertex where it crosses another line would
    slide across the crease, on the kink of the length.
    """
    P, Q = X[:-1], X[1:]
    held = _held_segments(X, modes)  # a stretch on a crease: exact as it is (:func:`_hold_on_lines`)
    new_t, new_seg, new_axis = [], [], []
    for axis, comp in enumerate(domain.comps):
        u0, u1 = P[:, axis], Q[:, axis]
        vp = _vertex_params(comp, float(min(u0.min(), u1.min())), float(max(u0.max(), u1.max())))
        seg, t = _breaks(vp, u0, u1)
        keep = (t > 1e-9) & (t < 1 - 1e-9) & ~held[seg]
        new_t.append(t[keep])
        new_seg.append(seg[keep])
        new_axis.append(np.full(keep.sum(), axis))
    t = np.concatenate(new_t)
    if t.size == 0:
        return X, modes
    seg = np.concatenate(new_seg)
    axis = np.concatenate(new_axis)
    order = np.lexsort((t, seg))
    t, seg, axis = t[order], seg[order], axis[order]
    # one vertex per crossing point (a cell corner is crossed by two lines at once)
    dup = np.zeros(len(t), dtype=bool)
    dup[1:] = (seg[1:] == seg[:-1]) & (t[1:] - t[:-1] < 1e-9)
    t, seg, axis = t[~dup], seg[~dup], axis[~dup]
    pts = P[seg] + t[:, None] * (Q[seg] - P[seg])
    lines = _Modes.free(len(seg))
    lines.hold(np.arange(len(seg)), axis, pts[np.arange(len(seg)), axis])  # along the line of constant x_axis
    return np.insert(X, seg + 1, pts, axis=0), modes.insert(seg + 1, lines)


def _newton(par, unpack, length, assemble, z, max_iter, rtol=1e-11, max_move=np.inf, kinks=None):
    """Damped Newton (Levenberg-Marquardt) with backtracking on one curve: ``(X, converged)``.

    The general form, with a sparse Hessian (closed curves); open curves go
    through :func:`_newton_many`, which follows the same rules.  Converged
    when the Newton decrement (the model's decrease, about twice the length
    still to gain) is at most ``rtol`` times the length.  ``assemble(X)``
    returns the length, its gradient and its sparse Hessian in the unknowns.

    The line search starts from a step that moves no vertex more than
    ``max_move`` (parameters).  Where the length is nearly flat (the
    degenerate ``euclid`` metric on ``nested`` at 64 cells) the Newton step
    moved vertices by 2e6 periods, and measuring the trial polyline, split on
    every vertex line it crosses, took 24 GB.

    ``kinks(X, X_trial)``, where given, names the unknowns beside the
    segments whose lengths grew beyond the quadratic model at a rejected
    trial step (:func:`_kinked_unknowns`).  Those unknowns get a damping of
    their own (``_KINK_DAMPING`` times their own diagonal entries of the
    Hessian, a hundred times more at each repeat, a tenth of it after each
    accepted step) and the step is solved again, up to ``_KINK_SOLVES``
    times, before the step is cut back; a damped step whose decrease is
    below the convergence threshold (or not a descent) gives way to the
    step solved before it, which is cut back (a code review: scaled by the
    Hessian's largest entry, such damping froze the kinked unknowns, and a
    curve could go through every iteration without a step).  One kink, a
    free vertex beside a tiny segment against a refraction vertex, crossing
    the vertex line, held the whole step of a
    closed curve of 330 vertices to 2.4e-4 of its Newton step, where every
    other segment followed the model (``g`` with ``p = 2``,
    ``validation/rugged_closed_g.py``); with the kinks damped, full steps
    are taken.  A decrement computed with such damping is smaller than the
    undamped one, so convergence is declared only without it.
    """
    X = unpack(z)
    f, grad, H = assemble(X)
    lam = 1e-8
    eye = sp.identity(par.nv, format="csc")
    damp = np.zeros(par.nv)  # the unknowns' own damping beside kinks, in units of their own diagonal entries
    for _ in range(max_iter):
        diag = np.abs(H.diagonal())
        hscale = max(float(diag.max()), 1e-300)
        previous = None  # the step solved before the latest damping (its trial rejected)
        for solve in range(_KINK_SOLVES + 1):
            A = H + lam * hscale * eye
            if damp.any():
                A = A + sp.diags(damp * np.maximum(diag, 1e-12 * hscale), format="csc")
            dz = spsolve(A, -grad)
            decrease = -float(dz @ grad)
            if not np.all(np.isfinite(dz)) or decrease <= 0 or decrease <= rtol * f:
                if previous is not None:  # damped into a step that says nothing: the one before, cut back below
                    dz, decrease, t, X_new, f_new = previous
                break
            move = 0.0
            if np.isfinite(max_move):
                move = float(np.sqrt(np.square(par.M @ dz).reshape(-1, 2).sum(axis=1).max()))
            t = min(1.0, max_move / move) if move > 0 else 1.0
            X_new = unpack(par.clip(z + t * dz))
            f_new = length(X_new)
            if f_new <= f or kinks is None or solve == _KINK_SOLVES:
                break
            bad = kinks(X, X_new)
            if not len(bad):
                break
            previous = (dz, decrease, t, X_new, f_new)
            damp[bad] = np.maximum(damp[bad] * 100.0, _KINK_DAMPING)
        if not np.all(np.isfinite(dz)) or decrease <= 0:
            lam = max(lam * 100, 1e-6)
            if lam > 1e8:
                return X, False
            continue
        if decrease <= rtol * f:
            if damp.any():  # the damped decrement: solve again without the kinks' damping
                damp[:] = 0.0
                continue
            return X, True
        accepted = f_new <= f
        for _ls in range(11):
            if accepted:
                break
            t *= 0.5
            X_new = unpack(par.clip(z + t * dz))
            f_new = length(X_new)
            accepted = f_new <= f
        if not accepted:
            lam *= 100
            if lam > 1e8:
                return X, False
            continue
        z = par.pack(X_new)
        stalled = f - f_new <= 1e-13 * f and decrease <= 1e-8 * f  # converged to rounding
        X, f = X_new, f_new
        if stalled and not damp.any():
            return X, True
        lam = max(lam / 10, 1e-12)
        damp /= 10.0
        damp[damp < 1e-6 * _KINK_DAMPING] = 0.0
        f, grad, H = assemble(X)
    return X, False


#: the damping of an unknown beside a kink of the length, in units of its own diagonal entry of the Hessian
_KINK_DAMPING = 1.0
#: how many times :func:`_newton` solves a step again with more damping beside kinks before cutting it back
_KINK_SOLVES = 3


def _kinked_unknowns(par: _Parametrization, X: np.ndarray, f: np.ndarray, gl: np.ndarray, Hl: np.ndarray,
                     X_trial: np.ndarray, f_trial: np.ndarray) -> np.ndarray:
    """The unknowns beside the segments whose lengths grew beyond their quadratic models from ``X`` to ``X_trial``.

    ``f``, ``gl``, ``Hl`` are each segment's length, gradient and Hessian at
    ``X`` (:func:`_segment_derivatives`), ``f_trial`` its length at ``X_trial``.  A segment whose length exceeds its
    model by more than a tenth of the largest such excess is kinked (a
    vertex crossed a vertex line, or a segment collapsed); the unknowns that
    move its two ends are returned (empty when no segment exceeds its model).
    """
    dU = np.hstack([X_trial[:-1] - X[:-1], X_trial[1:] - X[1:]])
    model = (gl * dU).sum(axis=1) + 0.5 * np.einsum("si,sij,sj->s", dU, Hl, dU)
    excess = f_trial - f - model
    top = float(excess.max())
    if not top > 0.0:
        return np.empty(0, dtype=np.intp)
    segs = np.flatnonzero(excess > 0.1 * top)
    rows = np.concatenate([2 * segs, 2 * segs + 1, 2 * segs + 2, 2 * segs + 3])
    return np.unique(par.M.tocsr()[rows].indices)


#: a domain whose longer side exceeds its shorter this many times bounds the polish axis by axis (see _lbfgs_polish)
_ANISOTROPIC = 1e3


def _lbfgs_polish(domain: Domain, metric: Metric, par: _Parametrization, X: np.ndarray, scale: float) -> np.ndarray:
    """Quasi-Newton (L-BFGS-B) on the exact gradient from ``X``: robust where the length has kinks."""
    comps = domain.comps
    n = par.n
    k = np.arange(n)
    loc = np.column_stack([2 * k, 2 * k + 1, 2 * k + 2, 2 * k + 3])

    def unpack(z):
        return _project(domain, par.unpack(z))

    z = par.pack(X)
    f0 = max(float(segment_lengths(metric, comps, X[:-1], X[1:]).sum()), 1e-300)
    Mt = par.M.T.tocsr()  # once, not at every evaluation

    def fun(zz):
        XX = unpack(par.clip(zz.copy()))
        fl, gl, _ = _segment_derivatives(metric, comps, XX[:-1], XX[1:], 1e-6 * scale, hessian=False)
        gX = np.bincount(loc.ravel(), weights=gl.ravel(), minlength=2 * (n + 1))
        return float(fl.sum()) / f0, (Mt @ gX) / f0

    wide = 10.0 * scale
    lengths = np.asarray(domain.lengths, dtype=float)
    if lengths.max() > _ANISOTROPIC * lengths.min():
        # each unknown moves its vertex at most 10 of each axis's own length: a circle 6e-8 long beside one of
        # 6.3 let the box of 10 * scale span 1e9 of its periods, and the lengths of a trial curve built its
        # vertex lines over all of them (15 GiB; a review at stop 48)
        rows, cols = np.asarray(par._triplets[0], dtype=int), np.asarray(par._triplets[1], dtype=int)
        vals = np.abs(np.asarray(par._triplets[2], dtype=float))
        moves = vals > 0
        wide = np.full(len(z), wide)
        np.minimum.at(wide, cols[moves], 10.0 * lengths[rows[moves] % 2] / vals[moves])
    bounds = np.column_stack([z - wide, z + wide])
    k = par._slide_idx
    bounds[k, 0] = np.maximum(par._lo, bounds[k, 0])
    bounds[k, 1] = np.minimum(par._hi, bounds[k, 1])
    res = minimize(fun, z, jac=True, method="L-BFGS-B", bounds=bounds,
                   options={"maxiter": 100, "ftol": 1e-12, "gtol": 1e-14, "maxcor": 30})
    Y = unpack(par.clip(res.x))
    # the unknowns of X itself may map to another polyline (X projected onto the domain, off its normals): the
    # polish then starts from that one and can end above X (4 of 280 polishes on 30 random interval scenes, by
    # up to 1.2e-3 relative); X is a curve of the class too, so the shorter is kept (res.fun is Y's length / f0)
    return X if res.fun > 1.0 else Y


def _optimize_level(domain: Domain, metric: Metric, X0: np.ndarray, modes: _Modes, shift, scale: float,
                    max_iter: int = 20, polish: bool = True, polish_modes: _Modes | None = None
                    ) -> tuple[np.ndarray, bool]:
    """Minimize the exact length of one polyline over its free coordinates: ``(X, converged)``.

    The general (sparse) form, for closed curves and any parametrization;
    open curves go through :func:`_optimize_many`, which stacks them.
    Damped Newton (Levenberg-Marquardt with Marquardt's diagonal scaling) with
    a backtracking line search; where it stalls (lengths that are not smooth,
    such as the degenerate norm of the euclid metric) an L-BFGS-B polish takes
    over, unless ``polish`` is False (the coarse pass, which only needs the
    shape of the curve).  The polish moves the vertices as ``polish_modes``
    say, when given (:func:`_settle` gives the curve's own modes: its
    vertices free in both coordinates, not only along the normals).
    """
    comps = domain.comps
    par = _Parametrization(X0, modes, shift)
    if par.nv == 0:
        return X0, True
    n = par.n
    k = np.arange(n)
    loc = np.column_stack([2 * k, 2 * k + 1, 2 * k + 2, 2 * k + 3])

    def unpack(z):
        return _project(domain, par.unpack(z))

    measured: list = [None, None]  # the latest polyline measured and its segments' lengths (for kinks)

    def length(X):
        seg = segment_lengths(metric, comps, X[:-1], X[1:])
        measured[:] = [X, seg]
        return float(seg.sum())

    def assemble(X):
        seg = np.linalg.norm(X[1:] - X[:-1], axis=1)
        steps = _least_steps(seg, float(seg.sum()), scale)  # short segments get short steps
        f, gl, Hl = _segment_derivatives(metric, comps, X[:-1], X[1:], steps)
        at[:] = [X, f, gl, Hl]
        gX = np.bincount(loc.ravel(), weights=gl.ravel(), minlength=2 * (n + 1))
        r = np.repeat(loc, 4, axis=1).ravel()
        c = np.tile(loc, (1, 4)).ravel()
        HX = sp.csr_matrix((Hl.ravel(), (r, c)), shape=(2 * (n + 1), 2 * (n + 1)))
        M, Mt = par.M, par.M.T.tocsr()
        return float(f.sum()), Mt @ gX, (Mt @ HX @ M).tocsc()

    at: list = [None, None, None, None]  # the polyline of the latest assemble and its segments' derivatives

    def kinks(X, X_trial):
        if at[0] is not X:
            return np.empty(0, dtype=np.intp)
        trial = measured[1] if measured[0] is X_trial else segment_lengths(metric, comps, X_trial[:-1], X_trial[1:])
        return _kinked_unknowns(par, X, at[1], at[2], at[3], X_trial, trial)

    z = par.pack(X0)
    X, converged = _newton(par, unpack, length, assemble, z, max_iter, rtol=1e-11 if polish else 1e-7,
                           max_move=scale, kinks=kinks)
    if converged or not polish:
        return X, converged
    if polish_modes is not None:
        par = _Parametrization(X, polish_modes, shift)
    return _lbfgs_polish(domain, metric, par, X, scale), False


class _Stack:
    """Open polylines with banded parametrizations (one unknown per vertex) stacked into one system.

    Vertices, segments and unknowns of all curves are concatenated; every
    quantity of a curve is a slice, and per-curve sums are ``bincount``s.
    The Hessian of the total length is block tridiagonal, one block per curve.
    """

    def __init__(self, domain: Domain, metric: Metric, pars: list[_Parametrization], scale: float):
        self.domain, self.metric, self.scale = domain, metric, scale
        C = len(pars)
        self.C = C
        nv = np.array([p.n + 1 for p in pars])
        ns = nv - 1
        nu = np.array([p.nv for p in pars])
        self.voff = np.concatenate([[0], np.cumsum(nv)])
        soff = np.concatenate([[0], np.cumsum(ns)])
        uoff = np.concatenate([[0], np.cumsum(nu)])
        self.v_curve = np.repeat(np.arange(C), nv)
        self.s_curve = np.repeat(np.arange(C), ns)
        self.u_curve = np.repeat(np.arange(C), nu)
        self.n_seg = ns
        # segment k of curve c joins vertices voff[c] + k and voff[c] + k + 1
        self.seg_p = np.arange(soff[-1]) - soff[:-1][self.s_curve] + self.voff[:-1][self.s_curve]
        self.X0 = np.vstack([p.X0 for p in pars])
        local = np.concatenate([p.vertex for p in pars])
        self.u_vertex = local + self.voff[:-1][self.u_curve]
        self.E = np.vstack([p.E for p in pars])
        self.ediag = np.concatenate([p._diag for p in pars])
        self.lo = np.full(uoff[-1], -np.inf)
        self.hi = np.full(uoff[-1], np.inf)
        for c, p in enumerate(pars):
            self.lo[uoff[c] + p._slide_idx] = p._lo
            self.hi[uoff[c] + p._slide_idx] = p._hi
        # the segments before and after each unknown's vertex (clamped at the ends of its curve)
        self.u_prev = soff[:-1][self.u_curve] + np.maximum(local - 1, 0)
        self.u_next = soff[:-1][self.u_curve] + np.minimum(local, ns[self.u_curve] - 1)
        # the Hessian couples unknowns k and k + 1 when they sit on adjacent vertices of one curve
        self.adjacent = (np.diff(self.u_vertex) == 1) & (self.u_curve[1:] == self.u_curve[:-1])
        self.Ev = np.zeros((len(self.X0), 2))
        self.Ev[self.u_vertex] = self.E

    def clip(self, z):
        return _clip(z, self.lo, self.hi)

    def pack(self, X):
        return self.clip(((X - self.X0)[self.u_vertex] * self.E).sum(axis=1) / self.ediag)

    def unpack(self, z):
        X = self.X0.copy()
        X[self.u_vertex] += z[:, None] * self.E
        return _project(self.domain, X)

    def _segments(self, X, curves):
        s = np.flatnonzero(curves[self.s_curve])
        p = self.seg_p[s]
        return s, X[p], X[p + 1]

    def trials(self, z, dz, t, curves, k):
        """The selected curves moved by the steps ``t, t / 2, ..., t / 2^(k - 1)`` along ``dz``: ``(v, X, f)``.

        ``v`` lists the selected curves' vertices (indices into the stack),
        ``X`` is ``(k, len(v), 2)``, their positions after each step, and
        ``f`` the ``(k, C)`` lengths (zeros for the curves not selected), all
        from one call of :func:`direct.metric.segment_lengths`: a line
        search's trial steps at once, for small stacks whose cost is the
        call's, not the segments' (a coarse curve of 16 segments).  The same
        numbers as :meth:`unpack` and :func:`polyline_lengths` step by step, bit for
        bit where the metric's piece integrals have a closed form (``G`` with
        ``q = 2``, ``g`` with ``p = 1``: every operation is per vertex or per
        segment); with Gauss-Legendre quadrature, whose weighted sums are a
        BLAS product over the batch, to the last bit (as the stepwise search
        already was, its batch of curves changing from step to step).
        """
        v = np.flatnonzero(curves[self.v_curve])
        u = np.flatnonzero(curves[self.u_curve])
        ts = t[self.u_curve[u]] * 0.5 ** np.arange(k)[:, None]  # halving is exact: the line search's own steps
        Z = _clip(z[u] + ts * dz[u], self.lo[u], self.hi[u])
        X = np.repeat(self.X0[v][None], k, axis=0)
        X[:, np.searchsorted(v, self.u_vertex[u])] += Z[:, :, None] * self.E[u]
        X = _project(self.domain, X.reshape(-1, 2)).reshape(k, len(v), 2)
        s = np.flatnonzero(curves[self.s_curve])
        p = np.searchsorted(v, self.seg_p[s])  # a segment's first vertex, among v; the next one follows it
        f = segment_lengths(self.metric, self.domain.comps, X[:, p].reshape(-1, 2), X[:, p + 1].reshape(-1, 2))
        rows = (np.arange(k)[:, None] * self.C + self.s_curve[s]).ravel()
        return v, X, np.bincount(rows, weights=f, minlength=k * self.C).reshape(k, self.C)

    def assemble(self, X, curves):
        """Lengths, gradients, and the tridiagonal Hessian ``(diag, off)`` in the unknowns of the selected curves.

        The unknowns move each vertex along its direction ``E`` only, so the
        Hessian is needed only along those directions: central differences
        of the exact gradient with each segment's ends moved along ``E``
        (four gradient evaluations per segment besides the one at ``X``,
        against eight for the full 4 x 4 block).
        """
        s, P, Q = self._segments(X, curves)
        m = len(s)
        seg = _row_norms(Q - P)
        curve = self.s_curve[s]
        length = np.bincount(curve, weights=seg, minlength=self.C).take(curve)
        h = _least_steps(seg, length, self.scale)[:, None]  # short segments get short steps
        p = self.seg_p[s]
        Ep, Eq = self.Ev[p], self.Ev[p + 1]
        Ps = np.vstack([P, P + h * Ep, P - h * Ep, P, P])
        Qs = np.vstack([Q, Q, Q, Q + h * Eq, Q - h * Eq])
        f, g = segment_lengths(self.metric, self.domain.comps, Ps, Qs, gradient=True)
        f = f[:m]
        g = g.reshape(5, m, 4)
        gl = g[0]
        dP = (g[1] - g[2]) / (2 * h)  # d grad / d(P along E_p)
        dQ = (g[3] - g[4]) / (2 * h)  # d grad / d(Q along E_q)
        gV = np.zeros_like(X)
        gV[p] += gl[:, :2]
        gV[p + 1] += gl[:, 2:]  # a vertex ends one segment and starts the next: two separate sums
        dV = np.zeros(len(X))
        dV[p] += (dP[:, :2] * Ep).sum(axis=1)
        dV[p + 1] += (dQ[:, 2:] * Eq).sum(axis=1)
        oV = np.zeros(len(X))
        oV[p] = 0.5 * ((dP[:, 2:] * Eq).sum(axis=1) + (dQ[:, :2] * Ep).sum(axis=1))  # vertex k with vertex k + 1
        uv = self.u_vertex
        grad = (gV[uv] * self.E).sum(axis=1)
        off = np.where(self.adjacent, oV[uv[:-1]], 0.0)
        return np.bincount(self.s_curve[s], weights=f, minlength=self.C), grad, dV[uv], off

    def step_limits(self, X, dz, curves):
        """Largest step fraction per curve that moves no vertex more than half its shorter segment."""
        seg = _row_norms(X[self.seg_p + 1] - X[self.seg_p])
        mean = np.bincount(self.s_curve, weights=seg, minlength=self.C) / np.maximum(self.n_seg, 1)
        room = np.minimum(seg[self.u_prev], seg[self.u_next])
        room = np.maximum(room, 0.25 * mean[self.u_curve])  # a vertex beside a tiny segment may still move
        ratio = np.abs(dz) * np.sqrt(self.ediag) / np.maximum(room, 1e-300)
        worst = np.zeros(self.C)
        on = curves[self.u_curve]
        np.maximum.at(worst, self.u_curve[on], ratio[on])
        return np.where(worst > 0, np.minimum(1.0, 0.5 / np.where(worst > 0, worst, 1.0)), 1.0)


def _symmetric_tridiagonal_solve(diag: np.ndarray, off: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``x`` with ``T x = rhs``, ``T`` symmetric tridiagonal (``diag``, ``off``): LAPACK's ``dgtsv``.

    The routine ``scipy.linalg.solve_banded((1, 1), ...)`` calls, with the same
    arguments (so the same numbers), without its checks and batching wrapper:
    the stacked Newton solves tens of thousands of small systems, whose cost
    is the call's.  Raises ``LinAlgError`` when ``T`` is singular and has
    two unknowns or more; one unknown is a division, as there (``inf`` or
    NaN, with numpy's warning, for a zero diagonal).
    """
    if diag.size == 1:  # as solve_banded: one division (dgtsv's wrapper wants off-diagonals of length >= 1)
        return rhs / diag
    _, _, _, x, info = dgtsv(off.copy(), diag.copy(), off.copy(), rhs.copy(), True, True, True, True)
    if info > 0:
        raise LinAlgError("singular matrix")
    if info < 0:
        raise ValueError(f"illegal value in argument {-info} of dgtsv")
    return x


def _solve_tridiagonal(stack: _Stack, diag, off, rhs, active_u):
    """Solve the block tridiagonal system on the active unknowns; not finite for a curve whose block is singular."""
    idx = np.flatnonzero(active_u)
    dz = np.zeros(len(rhs))
    if idx.size == 0:
        return dz
    try:
        dz[idx] = _symmetric_tridiagonal_solve(diag[idx], np.where(idx[1:] == idx[:-1] + 1, off[idx[:-1]], 0.0),
                                               rhs[idx])
        if np.isfinite(dz[idx]).all():
            return dz
    except (LinAlgError, ValueError):
        pass
    # one block is singular, or not finite (which would spread through the whole elimination): solve curve by
    # curve, the blocks being independent, so that no curve's step depends on the others in its batch
    for c in np.unique(stack.u_curve[idx]):
        k = idx[stack.u_curve[idx] == c]
        try:
            dz[k] = _symmetric_tridiagonal_solve(diag[k], np.where(k[1:] == k[:-1] + 1, off[k[:-1]], 0.0), rhs[k])
        except (LinAlgError, ValueError):
            dz[k] = np.nan
    return dz


#: the stacked Newton's line search tries up to 4 steps at once while they make at most this many segments
_TRIALS_AT_ONCE = 256


def _newton_many(stack: _Stack, X_start: np.ndarray, max_iter: int, rtol: float):
    """Damped Newton (Levenberg-Marquardt) with backtracking on every curve of a stack at once.

    Each curve follows the rules of :func:`_newton` with its own damping,
    step and line search; a curve leaves when it converges (Newton decrement
    at most ``rtol`` times its length, or no progress above rounding) or
    fails, and the iterations go on for the others.

    Returns
    -------
    X : (n_vertices, 2) ndarray
        The stacked vertices.
    converged : (C,) ndarray of bool
    """
    C = stack.C
    u_curve, v_curve = stack.u_curve, stack.v_curve
    z = stack.pack(X_start)
    X = stack.unpack(z)
    everyone = np.ones(C, dtype=bool)
    f, G, D, off = stack.assemble(X, everyone)
    lam = np.full(C, 1e-8)
    done = np.zeros(C, dtype=bool)
    conv = np.zeros(C, dtype=bool)
    for _ in range(max_iter):
        act = ~done
        if not act.any():
            break
        absD = np.abs(D)
        dmax = np.zeros(C)
        np.maximum.at(dmax, u_curve, absD)
        damp = np.maximum(absD, 1e-12 * np.maximum(dmax, 1e-300)[u_curve])  # Marquardt scaling
        dz = _solve_tridiagonal(stack, D + lam[u_curve] * damp, off, -G, act[u_curve])
        finite = np.isfinite(dz)
        bad_u = np.bincount(u_curve, weights=(~finite).astype(float), minlength=C) > 0
        dec = -np.bincount(u_curve, weights=np.where(finite, dz * G, 0.0), minlength=C)
        bad = act & (bad_u | (dec <= 0))
        lam[bad] = np.maximum(lam[bad] * 100, 1e-6)
        done |= bad & (lam > 1e8)
        cv = act & ~bad & (dec <= rtol * f)
        done |= cv
        conv |= cv
        stepping = act & ~bad & ~cv
        if not stepping.any():
            continue
        dz = np.where(finite, dz, 0.0)
        t = stack.step_limits(X, dz, stepping)
        searching = stepping.copy()
        accepted = np.zeros(C, dtype=bool)
        X_new, f_new = X.copy(), f.copy()
        tried = 0
        while tried < 12 and searching.any():  # halving steps, the first that does not lengthen the curve taken
            # a few steps at once when the stack is small (one call of the lengths costs about as much as four)
            k = min(12 - tried, max(1, _TRIALS_AT_ONCE // max(int(searching[stack.s_curve].sum()), 1)), 4)
            v, Xs, fs = stack.trials(z, dz, t, searching, k)
            for Xt, ft in zip(Xs, fs):
                tried += 1
                ok = searching & (ft <= f)
                if ok.any():
                    sv = ok[v_curve[v]]
                    X_new[v[sv]] = Xt[sv]
                    f_new[ok] = ft[ok]
                    accepted |= ok
                searching &= ~ok
                if not searching.any():
                    break
                t[searching] *= 0.5
        failed = stepping & ~accepted
        lam[failed] *= 100
        done |= failed & (lam > 1e8)
        if not accepted.any():
            continue
        sv, su = accepted[v_curve], accepted[u_curve]
        z[su] = stack.pack(X_new)[su]
        stalled = accepted & (f - f_new <= 1e-13 * f) & (dec <= 1e-8 * f)  # converged to rounding
        X[sv] = X_new[sv]
        f[accepted] = f_new[accepted]
        done |= stalled
        conv |= stalled
        moved = accepted & ~stalled
        lam[moved] = np.maximum(lam[moved] / 10, 1e-12)
        if moved.any():
            f2, G2, D2, off2 = stack.assemble(X, moved)
            mu = moved[u_curve]
            f[moved], G[mu], D[mu] = f2[moved], G2[mu], D2[mu]
            off[mu[:-1]] = off2[mu[:-1]]
    return X, conv


def _optimize_many(domain: Domain, metric: Metric, items: list, scale: float, max_iter: int = 20,
                   polish: bool = True) -> list[tuple[np.ndarray, bool]]:
    """Minimize the exact lengths of several polylines over their free coordinates: ``[(X, converged), ...]``.

    ``items`` lists ``(X0, modes, shift)`` or ``(X0, modes, shift,
    polish_modes)`` (see :class:`_Parametrization`).  Open curves with one
    unknown per vertex (every curve but closed ones) are stacked and solved
    together by :func:`_newton_many`; the others go one by one through
    :func:`_optimize_level`.  Curves that Newton leaves unconverged get an
    L-BFGS-B polish, unless ``polish`` is False (the coarse pass, which only
    needs the shape of the curves): in ``polish_modes`` where given and not
    None, else in ``modes``.
    """
    out: list = [None] * len(items)
    stacked, pars = [], []
    for i, (X0, modes, shift, *free) in enumerate(items):
        par = _Parametrization(X0, modes, shift)
        polish_modes = free[0] if free else None
        if par.nv == 0:
            out[i] = (X0, True)
        elif par.banded:
            stacked.append((i, shift, polish_modes))
            pars.append(par)
        else:
            out[i] = _optimize_level(domain, metric, X0, modes, shift, scale, max_iter=max_iter, polish=polish,
                                     polish_modes=polish_modes)
    if stacked:
        stack = _Stack(domain, metric, pars, scale)
        X, conv = _newton_many(stack, np.vstack([items[i][0] for i, _, _ in stacked]), max_iter,
                               rtol=1e-11 if polish else 1e-7)
        for c, ((i, shift, polish_modes), par) in enumerate(zip(stacked, pars)):
            Xc = X[stack.voff[c]:stack.voff[c + 1]].copy()
            if not conv[c] and polish:
                if polish_modes is not None:
                    par = _Parametrization(Xc, polish_modes, shift)
                Xc = _lbfgs_polish(domain, metric, par, Xc, scale)
            out[i] = (Xc, bool(conv[c]))
    return out


def polyline_lengths(domain: Domain, metric: Metric, polylines: list[np.ndarray]) -> np.ndarray:
    """Exact lengths of several polylines, in one evaluation of the metric.

    Parameters
    ----------
    domain : Domain
        The pair domain whose components the parameters refer to.
    metric : Metric
        The metric on M x M.
    polylines : list of (k, 2) ndarray
        Polylines in parameters ``(x1, x2)`` (reference arclength; unwrapped
        across seams on a circle).

    Returns
    -------
    (len(polylines),) ndarray
        Their exact lengths in the metric (:func:`direct.metric.segment_lengths`
        of every segment, summed per polyline), in length units raised to the
        metric's homogeneity (for ``G`` with ``q = 2``, length^3).
    """
    if not polylines:
        return np.empty(0)
    sizes = [len(X) - 1 for X in polylines]
    P = np.vstack([X[:-1] for X in polylines])
    Q = np.vstack([X[1:] for X in polylines])
    f = segment_lengths(metric, domain.comps, P, Q)
    return np.bincount(np.repeat(np.arange(len(polylines)), sizes), weights=f, minlength=len(polylines))


@dataclass(frozen=True)
class GeodesicJob:
    """One curve to refine: a grid route and how its ends are held.

    Attributes
    ----------
    route : (k, 2) ndarray
        Grid route in parameters (unwrapped across seams).
    start_ground, end_ground : int, optional
        Ground (boundary part) on which the first / last point slides: a
        curve ``gamma`` ending freely on the boundary or the diagonal
        (eq. (9)).  ``None``: the end is a fixed crossing point.
    closed : bool, default False
        A closed curve (section 3.3.4): ``route[-1] - route[0]`` is a period
        shift and every vertex is free.
    coarse : bool, default False
        ``route`` is already a coarse geodesic (from :func:`coarse_geodesics`):
        :func:`refine_many` starts from it without a coarse pass of its own.
    """

    route: np.ndarray
    start_ground: int | None = None
    end_ground: int | None = None
    closed: bool = False
    coarse: bool = False

    @property
    def shift(self):
        """The period shift of a closed curve (parameters), else None."""
        return np.asarray(self.route[-1] - self.route[0], dtype=float) if self.closed else None


def coarse_geodesics(domain: Domain, metric: Metric, jobs: list[GeodesicJob], n: int = 16,
                     rounds: int = 3, more: int = 9, gain: float = 1e-4) -> list[tuple[np.ndarray, float]]:
    """Straighten grid routes at a coarse scale: ``n`` segments, each across many cells.

    The first stage of :func:`refine_many`.  At that scale the kinks of the length (where segments cross vertex
    lines) are small ripples, so the large-scale shape of each geodesic
    settles quickly; the fine levels then only adjust it locally.  Cheap,
    and enough to rank routes that lead to different local geodesics.

    ``rounds`` rounds of normal moves first, then up to ``more`` further
    rounds for the curves whose last round shortened them by more than
    ``gain`` of their length.  A curve that reaches the boundary at a
    shallow angle, far from where its end belongs, slides its end along the
    side by about a segment per round: the fine levels, whose vertices are
    graded towards that end, can hardly move it at all (seed 279 of
    ``validation/default_tol.py``: after 3 rounds an end 0.034 up the side
    from where the geodesic meets it, and a curve refined from there 7.4 %
    too long with an estimate of 2.6e-4; after 10 rounds the end is in place).

    Parameters
    ----------
    domain : Domain
        The piece of ``M x M`` the curves lie in.
    metric : Metric
        The metric whose exact length is minimized.
    jobs : list of GeodesicJob
        The grid routes (parameters, reference arclength) and how their ends
        are held (fixed crossing points, or free on a ground: eq. (9)).
    n : int, default 16
        Segments of each coarse curve.
    rounds, more : int, default 3 and 9
        Rounds of normal moves for every curve, then further rounds for the
        curves still moving.
    gain : float, default 1e-4
        A curve goes on while its last round shortened it by more than this
        fraction of its length.

    Returns
    -------
    list of (polyline, length)
        Each coarse geodesic (parameters) and its exact length.
    """
    scale = float(max(domain.lengths))
    routes = _unfold(domain, metric, [j.route for j in jobs])
    state = [_resampled_with_ends(domain, r, n, j.start_ground, j.end_ground, j.closed) for r, j in zip(routes, jobs)]
    todo = list(range(len(jobs)))
    lengths = None  # from the last of the first rounds on: each curve's length before the round
    speed_at = _speed_lookup(domain, metric)
    for r in range(rounds + more):
        if more and r == rounds - 1:
            lengths = polyline_lengths(domain, metric, [X for X, _ in state])
        outs = _optimize_many(domain, metric, [(state[i][0], _normal_modes(*state[i], jobs[i].closed, speed_at),
                                                jobs[i].shift)
                                               for i in todo], scale, max_iter=20, polish=False)
        for i, (X, _) in zip(todo, outs):
            modes = state[i][1]
            X, modes = _truncate_ends(domain, X, modes, jobs[i].start_ground, jobs[i].end_ground)
            state[i] = (X, modes)
        if lengths is not None:  # the curves that this round still shortened go on
            after = polyline_lengths(domain, metric, [state[i][0] for i in todo])
            moving = lengths[todo] - after > gain * after
            lengths[todo] = after
            todo = [i for i, m in zip(todo, moving) if m]
            if not todo:
                break
    Xs = [X for X, _ in state]
    return list(zip(Xs, polyline_lengths(domain, metric, Xs).tolist()))


def coarse_geodesic(
    domain: Domain, metric: Metric, route: np.ndarray, end_ground: int | None = None
) -> tuple[np.ndarray, float]:
    """The coarse geodesic near one route (see :func:`coarse_geodesics`) and its exact length.

    Parameters
    ----------
    domain : Domain
        The piece of ``M x M`` the route lies in.
    metric : Metric
        The metric whose exact length is minimized.
    route : (k, 2) array_like of float
        The grid route in parameters (reference arclength), from a fixed
        crossing point.
    end_ground : int, optional
        The ground its last point slides on (eq. (9)); ``None``: fixed.

    Returns
    -------
    polyline : (k, 2) ndarray
        The coarse geodesic in parameters (about 16 segments).
    length : float
        Its exact length (the metric's length units).
    """
    return coarse_geodesics(domain, metric, [GeodesicJob(np.asarray(route, dtype=float), end_ground=end_ground)])[0]


class _Curve:
    """The state of one curve during :func:`refine_many`."""

    def __init__(self, job: GeodesicJob, X, modes, fine: bool = False, above: float | None = None):
        self.job, self.X, self.modes = job, X, modes
        self.fine = fine  # its route is as fine as a last level already: its levels go down (_levels_down)
        self.history: list[float] = []  # the length reached at each level
        self.length = 0.0  # the length after the latest round of the current level
        self.gains: list[float] = []  # what each round of the current level gained (see _remaining_gain)
        self.result: RefinedPath | None = None
        self.above = above  # a length it need not be refined below (refine_many's ``above``)
        self.clear = 0  # the levels in a row at which it lay clearly above ``above`` (see _given_up)


#: a round gaining more than this fraction of ``tol`` (relative) is followed by another, which measures the ratio
_RATIO_ROUND = 1e-4
#: the largest ratio of successive rounds' gains taken as converging (a geometric tail of at most 19 more gains)
_MAX_RATIO = 0.95
#: a round of a closed curve whose optimization did not converge and that gained less than this fraction of the round
#: before stalled, rather than converged: its level gets one more round, for each such round, within ``max_rounds``
#: (see :func:`_settle`)
_STALL_RATIO = 0.05


def _remaining_gain(gains: list[float]) -> float:
    """What further rounds of a level could still gain, from what its rounds gained so far.

    The rounds of a level converge about geometrically: each moves the vertices
    along the normals of the polyline it starts from, and the next one, with
    new normals, takes a fraction ``r`` of what is left (where the curve creeps
    along a narrow valley towards a corner, ``r`` comes near 1).  With the last
    two gains ``g_{k-1}, g_k`` the tail is ``g_k r / (1 - r)``, ``r = g_k /
    g_{k-1}`` (``r`` capped at ``_MAX_RATIO``); never less than ``g_k`` itself
    (one round: ``r = 1/2`` assumed; no round: nothing).
    """
    if not gains:
        return 0.0
    g = gains[-1]
    if len(gains) < 2 or g <= 0.0:
        return g
    r = min(g / gains[-2], _MAX_RATIO) if gains[-2] > 0.0 else _MAX_RATIO
    return max(g, g * r / (1.0 - r))


def _settle(domain: Domain, metric: Metric, curves: list[_Curve], scale: float, tol: float, max_rounds: int):
    """Rounds of moves at the current level (Newton along the normals, recomputed each time) until the lengths settle.

    One round cannot carry a vertex past the centre of curvature of the
    polyline.  The rounds go on while what they could still gain
    (:func:`_remaining_gain`, from the ratio of successive gains) exceeds
    ``tol / 100`` of the length, and a round that gained more than
    ``_RATIO_ROUND * tol`` is always followed by one more, so that the ratio
    is measured.  Sets each curve's ``X``, ``modes``, ``length`` and
    ``gains``.

    Newton moves the vertices along the normals; where it stalls, the
    L-BFGS-B polish moves them in both coordinates (the curve's own modes:
    refraction vertices still slide on their lines, ends on their grounds).
    Along the normals a refraction vertex can slide only about a segment per
    round, as its neighbours cannot follow it along the curve.  On a closed
    curve whose Newton converged in no round (``g`` with ``p = 2`` on the
    8-gon nested in a 16-gon, ``nested_8_16_g`` of
    ``validation/listings_scenes.json``), the curve crossed a vertex line 0.26
    from where the shortest curve does; at ``tol=1e-3`` its levels' rounds
    gained 5.2e-3, 2.8e-5, 8.8e-7 (76 segments) and 2.3e-3, 5.0e-6 (148),
    each level stopped on that ratio, and the curve ended 1.0e-2 too long,
    8.9 times its estimate (at ``tol=1e-4`` the rounds of 146 segments went
    on: 2.3e-3, 5.0e-6, 2.2e-4, 4.3e-6, 4.8e-3;
    ``validation/rugged_closed_g.py``).  With the polish in both coordinates
    the five grid starts refine at ``tol=1e-5`` to within 1.5e-6 (relative)
    of each other but the first, another local geodesic 3.0e-4 above (the
    default BLAS threads; with one thread the five spread over 4.4e-4, the
    second start 2.9e-5 above the least with an estimate of 3.2e-6: single
    starts can still settle apart, the whole run takes the shortest).  Open
    curves get the same polish: against the polish along the normals, on the
    175 interval scenes of ``validation/same_values.py --families intervals``,
    the mean distance to the scene's ``tol=1e-5`` value fell from 2.8e-6 to
    1.9e-6 (relative) at ``tol=1e-3`` and from 4.9e-7 to 4.1e-7 at ``1e-4``,
    at the same cost; no value lay farther from it than its estimate, where
    one had (seed 160 at ``tol=1e-3``: 8.7e-5 off, estimate 4.3e-5; now
    2.8e-6 off).
    """
    for c in curves:
        c.gains = []
    todo = list(curves)
    speed_at = _speed_lookup(domain, metric)
    for _round in range(max_rounds):
        outs = _optimize_many(domain, metric, [(c.X, _normal_modes(c.X, c.modes, c.job.closed, speed_at), c.job.shift,
                                                c.modes) for c in todo], scale)
        for c, (X, _) in zip(todo, outs):
            X, modes = _hold_on_lines(metric, domain.comps, *_merge_collapsed(*_drop_folds(X, c.modes)))
            X, modes = _insert_breaks(domain, *_prune_breaks(X, modes))
            X, modes = _truncate_ends(domain, X, modes, c.job.start_ground, c.job.end_ground)
            if c.job.end_ground is not None:
                modes = _corner_switch(domain, metric, X, modes, len(X) - 1)
            if c.job.start_ground is not None:
                modes = _corner_switch(domain, metric, X, modes, 0)
            c.X, c.modes = X, modes
        L_new = polyline_lengths(domain, metric, [c.X for c in todo])
        more = []
        for c, L, (_, converged) in zip(todo, L_new, outs):
            c.gains.append(max(c.length - L, 0.0))
            c.length = L
            if _remaining_gain(c.gains) > 1e-2 * tol * L or (len(c.gains) == 1 and c.gains[0] > _RATIO_ROUND * tol * L):
                more.append(c)
            elif (c.job.closed and not converged and len(c.gains) >= 2 and c.gains[-1] < _STALL_RATIO * c.gains[-2]
                  and c.gains[-2] > _RATIO_ROUND * tol * L):
                more.append(c)  # a stalled round says nothing of what is left: one more (per stalled round)
        todo = more
        if not todo:
            break


def _grade_and_measure(domain: Domain, metric: Metric, curves: list[_Curve], scale: float) -> None:
    """Grade the free ends of the open curves (:func:`_grade_ends`) and set every curve's ``length``."""
    for c in curves:
        if not c.job.closed:
            c.X, c.modes = _grade_ends(domain, c.X, c.modes, c.job.start_ground, c.job.end_ground, scale)
    for c, L in zip(curves, polyline_lengths(domain, metric, [c.X for c in curves])):
        c.length = L


def length_rounding(domain: Domain, metric: Metric, path: np.ndarray, length: float) -> float:
    """A bound on the rounding error of the length of a polyline in a pair domain.

    ``r = phi(x1) - phi(x2)`` is formed from the deformed coordinates of the
    domain's two components, as large as ``scale``, so it carries an absolute
    error of a few ``eps * scale``; the length of a curve weighs ``|r|`` to
    the metric's ``order``.  Along a curve on which ``|r|`` grows to ``R``,
    the relative error of the length is then about ``(order + 1) delta / R``;
    this takes ``2 (order + 1) eps scale / R`` (``delta = 2 eps scale``), at
    most the whole length.  A ``G``-family metric of another ``h`` counts as
    order 4; ``euclid``, which does not weigh ``|r|``, gives 0.  The
    estimate of :func:`direct.penalty` adds it to every curve's
    (``penalty._rounding_errors``), and :func:`refine_many` stops doubling a
    curve whose levels differ by less than it: they measure rounding there,
    not the discretization.

    Parameters
    ----------
    domain : Domain
        The pair domain whose components the parameters refer to.
    metric : Metric
        The metric on M x M.
    path : (k, 2) array_like of float
        The polyline, in parameters ``(x1, x2)`` (reference arclength).
    length : float
        Its length (length units raised to the metric's homogeneity, as
        :func:`polyline_lengths` gives it).

    Returns
    -------
    float
        The bound, in the units of ``length``: 0 for a length of 0 or for
        ``euclid``.
    """
    order = float(metric.order) if float(metric.order) > 0 else (0.0 if metric.name == "euclid" else 4.0)
    if not (order > 0 and length > 0):
        return 0.0
    ci, cj = domain.comps
    scale = max(float(np.abs(np.asarray(c.deformed, dtype=float)).max()) for c in (ci, cj))
    path = np.asarray(path, dtype=float)
    reach = float(np.linalg.norm(ci.phi(path[:, 0]) - cj.phi(path[:, 1]), axis=-1).max())
    return length * (min(1.0, 2.0 * (order + 1.0) * np.finfo(float).eps * scale / reach) if reach > 0 else 1.0)


def _finish(c: _Curve, tol: float, atol: float, last: bool = True, rounding=None) -> bool:
    """Set ``c.result`` from its levels' lengths ``c.history`` if they meet ``tol`` (or ``last``): whether it did.

    Richardson: with an error ~ n^-2, ``L_n - L_inf ~ (L_{n/2} - L_n) / 3``.
    The estimate is the whole last difference, three times that
    correction: the first levels are not always asymptotic.  ``rounding``
    (``(X, L) -> float``, :func:`length_rounding` of the domain) also stops
    a curve whose estimate lies below the rounding of its own length: its
    levels differ by rounding there, and further ones would measure nothing
    (its estimate, to which :func:`direct.penalty` adds that rounding, then
    exceeds ``tol`` times its length).
    """
    Ln, diff, estimate = _level_estimate(c)
    # three levels at least: the change between the first two is often not yet in the asymptotic range (measured:
    # 3.8e-3 off at tol 1e-3 after two), and the third checks it through the ratio
    met = estimate <= max(tol * abs(Ln), atol)
    if not met and rounding is not None and len(c.history) >= 3:
        # an interval along a triangle's edge, its curves where the metric vanishes (J about 2e-31): levels of
        # 1.1e-31, 1.7e-31, 1.4e-31, ... went on to 1,856 segments, and its corner starts alike (19 s)
        met = estimate <= rounding(c.X, Ln)
    if not ((met and len(c.history) >= 3) or last):
        return False
    # the extrapolation stays within [0, Ln]: Ln is the exact length of a curve of the class
    c.result = RefinedPath(c.X, min(max(Ln - diff / 3.0, 0.0), Ln), Ln, estimate, len(c.X) - 1)
    return True


def _level_estimate(c: _Curve) -> tuple[float, float, float]:
    """``(L_n, L_{n/2} - L_n, estimate)`` of a curve from its levels' lengths ``c.history`` (see :func:`_finish`)."""
    h = c.history
    Ln = h[-1]
    diff = h[-2] - h[-1]
    estimate = abs(diff)
    if len(h) >= 3:
        # a level that barely moves after one that moved a lot has stalled (a kink it cannot cross), not converged:
        # with an error ~ n^-2 each change is about a quarter of the one before
        prev = abs(h[-3] - h[-2])
        estimate = max(estimate, prev / 4.0)
        if abs(diff) <= prev:
            # changes shrinking slower than n^-2 (a valley narrower than the segments: hairpin with g, ratio 0.74,
            # was 1.1e-3 off at tol=1e-3 with an estimate of 6.2e-4): their geometric tail, the same as for the
            # rounds' gains (above the last change only when it is more than half the one before)
            estimate = max(estimate, _remaining_gain([prev, abs(diff)]))
    # what further rounds could still gain: the optimization of the last level may not have finished
    estimate += _remaining_gain(c.gains)
    return Ln, diff, estimate


#: a curve refined with a bound (refine_many's ``above``) is given up once its extrapolated length lies above the
#: bound by more than this many times its estimate ...
_GIVE_UP_ESTIMATES = 10.0
#: ... and by more than this fraction of the bound ...
_GIVE_UP_GAP = 1e-2
#: ... at this many levels in a row
_GIVE_UP_LEVELS = 2


def _given_up(c: _Curve) -> bool:
    """Whether a curve with a bound ``c.above`` has lain clearly above it at its last levels (see :func:`refine_many`).

    At ``_GIVE_UP_LEVELS`` levels in a row, from the third: a start bent by 30 % of its chord read 49 % above the
    curve it checked at its third level, with an estimate of 0.4 %, and went on to 8e-9 below it (a code review;
    the starts of :func:`direct.starts._bent_starts` bend by 1 % and 10 %).
    """
    if c.above is None or len(c.history) < 3:
        return False
    Ln, diff, estimate = _level_estimate(c)
    gap = min(max(Ln - diff / 3.0, 0.0), Ln) - c.above
    c.clear = c.clear + 1 if gap > _GIVE_UP_ESTIMATES * estimate and gap > _GIVE_UP_GAP * abs(c.above) else 0
    return c.clear >= _GIVE_UP_LEVELS


def _halved(domain: Domain, X: np.ndarray, modes: _Modes) -> tuple[np.ndarray, _Modes]:
    """Every other vertex of a polyline (both ends kept), with vertices where it now crosses a vertex line."""
    keep = np.zeros(len(X), dtype=bool)
    keep[::2] = True
    keep[-1] = True
    return _insert_breaks(domain, *_prune_breaks(X[keep], modes[keep]))


def _levels_down(domain: Domain, metric: Metric, curves: list[_Curve], scale: float, tol: float,
                 max_rounds: int, levels: int = 3) -> None:
    """The levels of curves whose routes are as fine as a last level: their own, then halved (and up again).

    Such a route is a start made from a refined curve (:mod:`direct.penalty`
    moves a refined curve off a corner of the cells, folds it across a
    crease, ...).  Each curve settles first at its own vertices, where it
    finds the local geodesic it leads to; then every other vertex is
    dropped and the coarser polyline settles, ``levels - 1`` times.  Their
    lengths are the levels of the Richardson extrapolation (``c.history``,
    coarsest first) and the curve is its own level's, unless a coarser
    level settled shorter than its own: its own level stopped short of its
    geodesic (it could follow the coarser polyline), so it goes back up from
    the coarsest, a free midpoint in every segment as :func:`refine_many`
    doubles, and the levels on the way up are its history.

    Such routes first went on doubling through every level, like a grid
    route (one of the limaçon and ellipse's folded starts, 1,861 vertices, to
    119,874 in 187 s: ``validation/folded_starts.py``), then stopped at their
    third level.  Doubling from the route (three levels up from its own) cost
    seven times a level at its size and made each start four times as long
    as the curve it came from: on seed 123 of ``validation/tol_1e5.py`` the
    starts beside a corner of a curve of 2,027 segments settled at 2,780,
    6,160 and 13,286, and those of the second pass, from a curve of 4,243,
    at 5,318, 12,414 and 28,711 (74 s of 101 s; its seeds 158 and 187 the
    same).  Down only (the curve always its own level's) left starts short
    of their geodesic: on ``fig10`` with ``g`` at ``tol=1e-5`` a start beside
    a corner settled at 789 segments 2.9e-6 (relative) above the same start
    at 314, and the corner starts' spread took the estimate from 5.4e-6 to
    1.0e-5 relative (a warning).  Always back up (a V-cycle) grew the curves
    that cross many vertex lines again (seed 123's second pass to 8,889
    segments, 81 s).
    """
    _grade_and_measure(domain, metric, curves, scale)
    _settle(domain, metric, curves, scale, tol, max_rounds)
    own = [(c.X, c.modes, c.length, c.gains) for c in curves]
    for c in curves:
        c.history = [c.length]
    for _ in range(levels - 1):
        for c in curves:
            c.X, c.modes = _halved(domain, c.X, c.modes)
        _grade_and_measure(domain, metric, curves, scale)
        _settle(domain, metric, curves, scale, tol, max_rounds)
        for c in curves:
            c.history.insert(0, c.length)
    back = [min(c.history[:-1]) < c.history[-1] for c in curves]  # a coarser level settled shorter
    for c, (X, modes, L, gains), b in zip(curves, own, back):
        if b:
            c.history = [c.length]  # the coarsest level's, on the way up
        else:
            c.X, c.modes, c.length, c.gains = X, modes, L, gains
    up = [c for c, b in zip(curves, back) if b]
    for _ in range(levels - 1 if up else 0):
        for c in up:
            c.X, c.modes = _doubled(c.X, c.modes)
        _grade_and_measure(domain, metric, up, scale)
        _settle(domain, metric, up, scale, tol, max_rounds)
        for c in up:
            c.history.append(c.length)


def _midpoints(X: np.ndarray) -> np.ndarray:
    """The polyline with the midpoint of every segment put in."""
    Y = np.empty((2 * len(X) - 1, 2))
    Y[0::2], Y[1::2] = X, 0.5 * (X[:-1] + X[1:])
    return Y


def _doubled(X: np.ndarray, modes: _Modes) -> tuple[np.ndarray, _Modes]:
    """The polyline with a free midpoint in every segment (:meth:`_Modes.doubled`) but those held on a line.

    A segment whose two ends are held on the same vertex line lies on a crease
    (:func:`_hold_on_lines`, which tests whether it should leave the line): it
    is exact as it is, and a free midpoint on it would sit on the kink of the
    length.
    """
    Y, doubled = _midpoints(X), modes.doubled()
    held = _held_segments(X, modes)
    if not held.any():
        return Y, doubled
    keep = np.ones(len(Y), dtype=bool)
    keep[1::2] = ~held
    return Y[keep], doubled[keep]


def _doubling_cap(max_segments: int, tol: float) -> int:
    """The segments of the last level that may double: ``max_segments``, four times that below ``tol = 1e-6``.

    The level changes of a smooth curve shrink about four times per level
    (an error ~ n^-2), so a decade of ``tol`` takes about two more levels.
    At ``max_segments = 512`` a straight crossing at 37 degrees with uneven
    arms stopped at ``tol=1e-7`` with an estimate of 1.4e-7 (relative) and a
    warning, its level changes 1.3e-7, 3.2e-8, 8.0e-9 (ratios 4.0), its
    error 1.5e-12; one more level meets ``tol``.  Never more than four
    times: a curve that cannot meet ``tol`` (a kink, a crease) doubles to
    the cap, and the cost doubles with each level.
    """
    return max_segments if tol >= _TIGHT_TOL else 4 * max_segments


#: below this ``tol`` the levels may double to four times ``max_segments`` (see :func:`refine_many`)
_TIGHT_TOL = 1e-6


def _route_work(domain: Domain, jobs: list[GeodesicJob]) -> np.ndarray:
    """An estimate of each job's work, to balance the parts of a batch (:func:`direct.parallel.split`).

    The vertices of a refined curve are mostly its refraction vertices, one
    where it crosses a vertex line (hundreds on a finely sampled circle), and a
    few dozen free ones: the lines the route crosses plus 32.
    """
    work = np.full(len(jobs), 32.0)
    for k, job in enumerate(jobs):
        R = np.asarray(job.route, dtype=float)
        if len(R) < 2:
            continue
        for axis in range(2):
            u = R[:, axis]
            vp = _vertex_params(domain.comps[axis], float(u.min()), float(u.max()))
            work[k] += len(_breaks(vp, u[:-1], u[1:])[0])
    return work


def refine_many(
    domain: Domain,
    metric: Metric,
    jobs: list[GeodesicJob],
    tol: float = 1e-3,
    atol: float = 0.0,
    start: int = 8,
    max_segments: int = 512,
    max_rounds: int = 8,
    above: Sequence[float | None] | None = None,
) -> list[RefinedPath]:
    """Refine grid routes into geodesics: minimize their exact lengths, multilevel, all curves together.

    Parameters
    ----------
    domain : Domain
        The pair domain.
    metric : Metric
        The metric on M x M.
    jobs : list of GeodesicJob
        The routes and how their ends are held.
    tol : float, default 1e-3
        Relative tolerance of each length (a curve whose levels differ by
        less than the rounding of its length, :func:`length_rounding`, stops
        there too).
    atol : float, default 0
        Absolute tolerance: a curve much shorter than the others needs no
        relative accuracy of its own.
    start, max_segments : int
        First and largest number of segments: the levels double the segments
        from ``start`` to ``max_segments`` (four times that below ``tol =
        1e-6``, where a decade of ``tol`` takes two more levels of a smooth
        curve: :func:`_doubling_cap`), each curve from the vertices of
        its route (a coarse geodesic of 16 segments, most of the time, so
        its last level has about ``2 max_segments``, plus a vertex where it
        crosses a vertex line).  A curve whose route already has
        ``max_segments`` segments or more (a start made from a refined
        curve, kept where its coarse geodesic is longer) settles at its own
        vertices, then at every other one, twice (:func:`_levels_down`).
    max_rounds : int
        Rounds of normal moves per level (the normals recomputed each time);
        a level stops earlier when what further rounds could still gain,
        extrapolated from the ratio of successive gains, is below
        ``tol / 100`` of the length.
    above : sequence of float or None, optional
        One per job (``None``: none), a length the caller needs a result
        below of, no more: the further starts of :mod:`direct.starts`, which
        only count where they end within a ten-thousandth above the curve
        they check.  A curve whose extrapolated length lies above its bound
        by more than ten times its estimate and by more than 1 % of the
        bound at two levels in a row, from its third, is given up there (its
        result that level's, with that level's estimate, which need not
        cover where further levels would have gone: a rule of thumb, not a
        proof; see :func:`_given_up`): the interval loop of a nodal cubic,
        whose straight curve to the diagonal gets four bent starts, refined
        two of them 14 % above it to 6,104 and 5,758 vertices at
        ``tol=1e-5`` (31 of its 62 s, twice over).  Routes as fine as a last
        level (below) are never given up.

    Returns
    -------
    list of RefinedPath
        One per job, in order.  ``length`` is Richardson-extrapolated, kept
        between 0 and ``upper`` (the exact length of the last polyline, a curve
        of the class, so at least the least length);
        ``error_estimate`` is the whole last change between levels, at least
        a quarter of the change before it, at least the geometric tail
        ``c r / (1 - r)`` of the changes when the last one ``c`` is more
        than half the one before (ratio ``r``, capped at ``_MAX_RATIO``),
        plus what further rounds of the last level could still gain.

    Notes
    -----
    Each curve is refined independently of the others in the batch (its own
    damping, step, line search, rounds and levels), so within
    :func:`direct.parallel.using` (``direct.penalty(..., workers=N)``) a
    batch is cut into parts of about equal work (:func:`_route_work`), one
    refined here and the others on worker processes, with the same result
    (bit for bit where the metric's integrals have a closed form; see
    :mod:`direct.parallel`).
    """
    jobs = list(jobs)
    if parallel.current() > 1 and len(jobs) > 1:  # direct.penalty(..., workers=N): parts on other processes
        parts = parallel.split(_route_work(domain, jobs), parallel.current())
        results = parallel.run_parts(refine_many, [(domain, metric, [jobs[i] for i in part], tol, atol, start,
                                                    max_segments, max_rounds,
                                                    None if above is None else [above[i] for i in part])
                                                   for part in parts])
        if results is not None:  # else no worker could take a part (a warning said why): all of it here
            out: list = [None] * len(jobs)
            for part, refined in zip(parts, results):
                for i, rp in zip(part, refined):
                    out[i] = rp
            return out
    scale = float(max(domain.lengths))
    # the coarse geodesic, unless the grid route itself is shorter: where the metric vanishes along whole lines the
    # grid route may run along them for free in a staircase that 16 segments cannot follow (fig13 at 192 cells:
    # the coarse geodesic 2 % longer than its route, the refinement from it 1.2 % too high)
    todo = [k for k, job in enumerate(jobs) if not job.coarse]
    routes = [np.asarray(job.route, dtype=float) for job in jobs]
    if todo:
        coarse = coarse_geodesics(domain, metric, [jobs[k] for k in todo])
        direct_len = polyline_lengths(domain, metric, [routes[k] for k in todo])
        for k, (X, L), Lr in zip(todo, coarse, direct_len):
            if L <= Lr:
                routes[k] = X
    curves = []
    for k, (job, route) in enumerate(zip(jobs, routes)):
        X, modes = _initial_polyline(domain, route, start, job.start_ground, job.end_ground, job.closed)
        curves.append(_Curve(job, X, modes, fine=len(route) - 1 >= max_segments,
                             above=None if above is None else above[k]))
    fine = [c for c in curves if c.fine]
    if fine:
        _levels_down(domain, metric, fine, scale, tol, max_rounds)
        for c in fine:
            _finish(c, tol, atol)
    live = [c for c in curves if not c.fine]
    cap = _doubling_cap(max_segments, tol)
    rounding = partial(length_rounding, domain, metric)
    n = start
    while live:
        _grade_and_measure(domain, metric, live, scale)
        _settle(domain, metric, live, scale, tol, max_rounds)
        nxt = []
        for c in live:
            c.history.append(c.length)  # the length of the last round's polyline
            if len(c.history) >= 2 and _finish(c, tol, atol, last=n >= cap or _given_up(c), rounding=rounding):
                continue
            if len(c.history) == 1 and c.length == 0.0:
                c.result = RefinedPath(c.X, 0.0, 0.0, 0.0, len(c.X) - 1)
                continue
            c.X, c.modes = _doubled(c.X, c.modes)
            nxt.append(c)
        live = nxt
        n *= 2
    return [c.result for c in curves]


def refine(
    domain: Domain,
    metric: Metric,
    route: np.ndarray,
    start_ground: int | None = None,
    end_ground: int | None = None,
    closed: bool = False,
    tol: float = 1e-3,
    atol: float = 0.0,
    start: int = 8,
    max_segments: int = 512,
    max_rounds: int = 8,
) -> RefinedPath:
    """Refine one grid route into a geodesic (see :func:`refine_many`, which refines several at once).

    Parameters
    ----------
    domain : Domain
        The pair domain.
    metric : Metric
        The metric on M x M.
    route : (k, 2) ndarray
        Grid route in parameters (unwrapped across seams).
    start_ground, end_ground : int, optional
        Ground on which the first / last point slides (eq. (9)); ``None``:
        a fixed crossing point.
    closed : bool, default False
        A closed curve: ``route[-1] - route[0]`` is a period shift.
    tol, atol, start, max_segments, max_rounds
        As in :func:`refine_many`.

    Returns
    -------
    RefinedPath
    """
    job = GeodesicJob(np.asarray(route, dtype=float), start_ground, end_ground, closed)
    return refine_many(domain, metric, [job], tol, atol, start, max_segments, max_rounds)[0]
