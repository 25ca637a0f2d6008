"""Signed crossings of the deformed polylines: the points of ``r_phi^{-1}(0)`` off the diagonal.

A crossing is a pair of material points ``x1 != x2`` with ``phi(x1) = phi(x2)``
(section 2.2.2 of the paper).  When the two velocities form a basis of
``R^2`` the crossing is *transversal* and carries the sign of Proposition 9,
``s = sign det(phi'(x1), phi'(x2))``.  :func:`find_crossings` lists every
crossing of a scene once, between two components ``i < j`` or within one
component (then with ``x1 < x2``); the mirrored point ``(x2, x1)`` of
``M x M`` has the opposite sign and is left to the caller.

Generic crossings
-----------------
Candidate pairs of deformed segments come in bulk from a :class:`shapely.STRtree`
(bounding boxes: a guaranteed superset of the touching pairs, even for contacts
that floating point cannot see); the four orientation determinants of every
pair are evaluated at once with numpy together with a rigorous floating-point
error bound (Shewchuk's bound for ``orient2d``).  When the four signs are
certain, the pair is settled in floating point: two segments cross iff each
separates the endpoints of the other, and such a crossing is transversal
(``exact=True``).  Only the rare pairs with an uncertain sign go to an exact
evaluation (floats are dyadic rationals: scaled to Python integers), which either proves them
transversal or disjoint, or finds a *degenerate contact*: a vertex lying on
the other curve, two vertices at the same place, a collinear overlap, a
collapsed (zero deformed length) segment.

The rule for degenerate contacts
--------------------------------
Degenerate contacts are decided by one fixed, generic perturbation of the
deformation, in the spirit of Simulation of Simplicity::

    phi_eps(x) = phi(x) + eps * v_c + eps**2 * x * u        (x on component c)

where ``x`` is the reference arclength, ``u`` a fixed unit vector and ``v_c``
a fixed unit vector per component index (golden-angle spaced; never random).
Every orientation determinant of ``phi_eps`` is a polynomial in ``eps``, whose
sign for small ``eps > 0`` is the sign of its first nonzero coefficient; the
perturbed segments cross iff each separates the endpoints of the other.  The
perturbation is affine on every segment, so segments stay segments, and it
depends on ``(c, x)`` only, never on the vertex list: inserting a vertex on a
segment (with its deformed position on the segment) changes nothing.
On a closed component ``x * u`` jumps back by ``L u`` at parameter
``0 = L``; the perturbed curve closes the gap near ``phi(0)`` with two tiny
segments ``phi(0) + eps v_c + eps**2 L u -> phi(0) + eps v_c + eps**2 L (u/2 + w)
-> phi(0) + eps v_c`` (``w`` another fixed unit vector), which belong to
parameter 0.

Every crossing of ``phi_eps`` tends, as ``eps -> 0``, to a point of the contact
set ``Z = {(x1, x2) : phi(x1) = phi(x2)}``.  The crossings are then gathered by
*connected component* of ``Z`` (a component is an isolated contact point, or a
stretch where the two curves run together, or a collapsed segment lying on
the other curve):

* a component whose perturbed crossings have signs summing to ``+1`` or
  ``-1`` is **one** crossing with that sign; a sum of 0 means no crossing;
* it is reported at the lexicographically smallest point ``(x1, x2)`` of the
  component (for an isolated contact, the contact itself; for a stretch run
  together, its end with the smallest parameter on the first component), with
  ``exact=False``;
* a component that reaches the diagonal ``x1 = x2`` (a curve folding back on
  itself, a collapsed segment, the closing gap above) is dropped: such a
  contact is undone by an arbitrarily small deformation near the diagonal
  and costs nothing (the metrics of section 3.4 vanish on ``Z``).

Consequences a user can rely on: a curve crossing another at a vertex (of
either curve, or of both) gives one crossing with the sign of the actual
passage from one side to the other; a vertex that touches the other curve
without passing through gives none; two curves that run together for a while
give one crossing if they arrive and leave on opposite sides, none if on the
same side.  These answers are topological, so they do not depend on the
perturbation (and are invariant under rigid motions and vertex insertion).
The perturbation only matters when a contact component reaches an end of an
open component (e.g. a curve that *ends* on another one, or runs along it
past its end): there the answer is that of the perturbed curve ``phi_eps``,
still invariant under vertex insertion, but it may change under a rotation of
the whole scene, a reversal of a component, a renumbering of the components
or (closed components) a change of the starting vertex.  Signs, parameters
and points of exact crossings are computed in floating point; everything
about degenerate contacts is computed exactly.  The configurations the rule
cannot decide (a coefficient that vanishes identically, which needs e.g. a
segment exactly parallel to ``u``, or a contact component of net crossing
number beyond +-1) raise :class:`direct.DegenerateError`.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np
import shapely

from .errors import DegenerateError

__all__ = ["Crossing", "find_crossings", "crossings_as_arrays"]

# -- the fixed generic perturbation ----------------------------------------------------------
_GOLDEN_ANGLE = math.pi * (3.0 - math.sqrt(5.0))
#: direction of the second-order, parameter-proportional perturbation ``eps**2 * x * u``
_U = (math.cos(0.5772156649015329), math.sin(0.5772156649015329))
#: direction of the apex of the closing gap of a closed component
_W = (math.cos(1.7182818284590453), math.sin(1.7182818284590453))

#: relative bound on the floating-point error of an orientation determinant (> Shewchuk's 3.3e-16)
_ORIENT_ERR = 8.9e-16


def _component_vector(c: int) -> tuple[float, float]:
    """Return the first-order perturbation ``v_c`` of component ``c`` (unit, golden-angle spaced)."""
    a = 1.0 + c * _GOLDEN_ANGLE
    return (math.cos(a), math.sin(a))


@dataclass(frozen=True)
class Crossing:
    """One geometric crossing ``phi(x1) == phi(x2)`` of the deformed curves.

    Attributes
    ----------
    components : tuple of int
        Indices ``(i, j)`` into ``scene.components`` with ``i <= j``.
    params : tuple of float
        Reference arclength ``x1`` on component ``i`` and ``x2`` on component
        ``j``; when ``i == j``, ``x1 < x2``.  On a closed component the
        parameters lie in ``[0, length)``.
    segments : tuple of int
        The segment of each component carrying the crossing; a crossing at a
        vertex belongs to the segment starting there (the last segment for the
        last vertex of an open component).
    point : tuple of float
        The deformed position ``phi(x1) == phi(x2)``.
    sign : int
        ``+1`` or ``-1``: ``sign det(phi_i'(x1), phi_j'(x2))`` (Proposition 9);
        for a degenerate contact, the net sign under the generic perturbation.
    exact : bool
        True for a transversal crossing in the ordinary sense; False when the
        crossing was decided by the perturbation rule (see the module docstring).
    """

    components: tuple[int, int]
    params: tuple[float, float]
    segments: tuple[int, int]
    point: tuple[float, float]
    sign: int
    exact: bool = True

    def to_dict(self, scene: Any = None) -> dict[str, Any]:
        """JSON-ready form of the crossing.

        Parameters
        ----------
        scene : Scene, optional
            The scene of the crossing; when given, components are named,
            otherwise given by index.

        Returns
        -------
        dict
            ``{"components": [i, j], "params": [x1, x2], "point": [x, y],
            "sign": s, "exact": bool}``.
        """
        comps: list[Any] = list(self.components)
        if scene is not None:
            comps = [scene.components[k].name for k in self.components]
        return {
            "components": comps,
            "params": [float(p) for p in self.params],
            "point": [float(p) for p in self.point],
            "sign": int(self.sign),
            "exact": bool(self.exact),
        }


def crossings_as_arrays(crossings: list[Crossing]) -> dict[str, np.ndarray]:
    """Stack a list of crossings into arrays.

    Parameters
    ----------
    crossings : list of Crossing
        As returned by :func:`find_crossings`.

    Returns
    -------
    dict of ndarray
        ``"components"`` (m, 2) int, ``"params"`` (m, 2) float, ``"segments"``
        (m, 2) int, ``"point"`` (m, 2) float, ``"sign"`` (m,) int and
        ``"exact"`` (m,) bool.
    """
    m = len(crossings)
    return {
        "components": np.array([c.components for c in crossings], dtype=int).reshape(m, 2),
        "params": np.array([c.params for c in crossings], dtype=float).reshape(m, 2),
        "segments": np.array([c.segments for c in crossings], dtype=int).reshape(m, 2),
        "point": np.array([c.point for c in crossings], dtype=float).reshape(m, 2),
        "sign": np.array([c.sign for c in crossings], dtype=int).reshape(m),
        "exact": np.array([c.exact for c in crossings], dtype=bool).reshape(m),
    }


# -- the segment table -----------------------------------------------------------------------
@dataclass
class _Segments:
    """All deformed segments of a scene, plus the two closing segments of each closed component.

    A row is a segment ``X0 -> X1`` of the perturbed curve, in the direction of
    increasing parameter.  Endpoint ``X`` is perturbed to
    ``p + eps v_c + eps**2 (a u + b w)``.
    """

    p0: np.ndarray  # (m, 2) deformed start
    p1: np.ndarray  # (m, 2) deformed end
    comp: np.ndarray  # (m,) component index
    seg: np.ndarray  # (m,) reported segment index (closing segments: 0)
    s0: np.ndarray  # (m,) parameter of the start (closing segments: 0)
    s1: np.ndarray  # (m,) parameter of the end (last segment of a closed component: length)
    ab0: np.ndarray  # (m, 2) second-order coefficients (a, b) of the start
    ab1: np.ndarray  # (m, 2) of the end
    pos: np.ndarray  # (m,) position along the perturbed chain of the component
    chain: np.ndarray  # (n_comp,) number of rows of each component
    closed: np.ndarray  # (n_comp,) bool
    length: np.ndarray  # (n_comp,) reference length


def _build_segments(scene) -> _Segments:
    p0, p1, comp, seg, s0, s1, ab0, ab1, pos = ([] for _ in range(9))
    chain, closed, length = [], [], []
    for c, cp in enumerate(scene.components):
        ring, par, n = cp.deformed_ring, cp.params, cp.n_segments
        L = float(par[-1])
        p0.append(ring[:-1])
        p1.append(ring[1:])
        comp.append(np.full(n, c))
        seg.append(np.arange(n))
        s0.append(par[:-1])
        s1.append(par[1:])
        ab0.append(np.column_stack([par[:-1], np.zeros(n)]))
        ab1.append(np.column_stack([par[1:], np.zeros(n)]))
        pos.append(np.arange(n))
        m = n
        if cp.closed:
            o = ring[:1]
            p0.append(np.vstack([o, o]))
            p1.append(np.vstack([o, o]))
            comp.append(np.full(2, c))
            seg.append(np.zeros(2, dtype=int))
            s0.append(np.zeros(2))
            s1.append(np.zeros(2))
            ab0.append(np.array([[L, 0.0], [L / 2, L]]))
            ab1.append(np.array([[L / 2, L], [0.0, 0.0]]))
            pos.append(np.array([n, n + 1]))
            m = n + 2
        chain.append(m)
        closed.append(cp.closed)
        length.append(L)
    cat = np.concatenate
    return _Segments(
        p0=cat(p0).astype(float),
        p1=cat(p1).astype(float),
        comp=cat(comp).astype(int),
        seg=cat(seg).astype(int),
        s0=cat(s0).astype(float),
        s1=cat(s1).astype(float),
        ab0=cat(ab0).astype(float),
        ab1=cat(ab1).astype(float),
        pos=cat(pos).astype(int),
        chain=np.array(chain, dtype=int),
        closed=np.array(closed, dtype=bool),
        length=np.array(length, dtype=float),
    )


def _adjacent(S: _Segments, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """Tell where rows i and j are consecutive on the perturbed chain of one component."""
    same = S.comp[i] == S.comp[j]
    gap = np.abs(S.pos[j] - S.pos[i])
    ch = S.chain[S.comp[i]]
    return same & ((gap == 1) | (S.closed[S.comp[i]] & (gap == ch - 1)))


def _orient_float(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Orientation ``det(b - a, c - a)`` and whether its sign is certain (nonzero)."""
    ab, ac = b - a, c - a
    left = ab[:, 0] * ac[:, 1]
    right = ab[:, 1] * ac[:, 0]
    det = left - right
    bound = _ORIENT_ERR * (np.abs(left) + np.abs(right)) + 1e-300
    return det, np.abs(det) > bound


# -- exact arithmetic on perturbed points ------------------------------------------------------
# Every float is a dyadic rational, so one power of two S = 2**K turns all the
# coordinates, parameters and perturbation vectors of a scene into integers.
# A perturbed point is stored as S**2 * (p, v_c, a u + b w): the three orders in
# eps are scaled alike, so every sign and every limit ratio is unchanged and
# the predicates run on Python integers.
_F0 = Fraction(0)


def _exponent_bound(values: np.ndarray) -> int:
    """Return K such that ``2**K * f`` is an integer for every float f of ``values``."""
    v = np.abs(np.asarray(values, dtype=float).ravel())
    v = v[v != 0]
    if not v.size:
        return 0
    _, e = np.frexp(v)
    return int(max(0, int((53 - e).max())))


def _scaled(f: float, K: int) -> int:
    n, d = float(f).as_integer_ratio()
    return n << (K - (d.bit_length() - 1))


class _Exact:
    """Exact integer data of the rows, built lazily for the few degenerate pairs."""

    def __init__(self, S: _Segments, scene) -> None:
        self.S = S
        self.scene = scene
        vs = [_component_vector(c) for c in range(len(S.chain))]
        K = _exponent_bound(np.concatenate([S.p0.ravel(), S.p1.ravel(), S.ab0.ravel(), S.ab1.ravel(), _U, _W, *vs]))
        self.K = K
        self.scale = 1 << K
        self.u = (_scaled(_U[0], K), _scaled(_U[1], K))
        self.w = (_scaled(_W[0], K), _scaled(_W[1], K))
        self.v = [(_scaled(x, K) << K, _scaled(y, K) << K) for x, y in vs]
        self._rows: dict[int, tuple] = {}

    def point(self, p, c: int, a: float, b: float) -> tuple:
        """Return ``S**2`` times the perturbed point, as its coefficient vectors of orders 0, 1, 2 in ``eps``."""
        K = self.K
        sa, sb = _scaled(a, K), _scaled(b, K)
        second = (sa * self.u[0] + sb * self.w[0], sa * self.u[1] + sb * self.w[1])
        return ((_scaled(p[0], K) << K, _scaled(p[1], K) << K), self.v[c], second)

    def row(self, k: int) -> tuple:
        """Return (X0, X1, s0, s1, x0, x1) of row k.

        ``X0, X1`` are the perturbed endpoints (see :meth:`point`), ``s0, s1``
        the exact parameters and ``x0, x1`` the deformed endpoints times ``S``.
        """
        r = self._rows.get(k)
        if r is None:
            S, K = self.S, self.K
            c = int(S.comp[k])
            X0 = self.point(S.p0[k], c, S.ab0[k, 0], S.ab0[k, 1])
            X1 = self.point(S.p1[k], c, S.ab1[k, 0], S.ab1[k, 1])
            x0 = (_scaled(S.p0[k, 0], K), _scaled(S.p0[k, 1], K))
            x1 = (_scaled(S.p1[k, 0], K), _scaled(S.p1[k, 1], K))
            r = (X0, X1, Fraction(float(S.s0[k])), Fraction(float(S.s1[k])), x0, x1)
            self._rows[k] = r
        return r

    def to_float_point(self, pt) -> tuple[float, float]:
        """Convert a point in units of ``1/S`` to floats."""
        return (float(Fraction(pt[0]) / self.scale), float(Fraction(pt[1]) / self.scale))


def _vsub(A: tuple, B: tuple) -> tuple:
    return tuple((a[0] - b[0], a[1] - b[1]) for a, b in zip(A, B, strict=True))


def _det(a, b):
    return a[0] * b[1] - a[1] * b[0]


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1]


def _pdet(A: tuple, B: tuple) -> list:
    out = [0] * 5
    for i in range(3):
        for j in range(3):
            out[i + j] += _det(A[i], B[j])
    return out


def _pdot(A: tuple, B: tuple) -> list:
    out = [0] * 5
    for i in range(3):
        for j in range(3):
            out[i + j] += _dot(A[i], B[j])
    return out


def _orient(X: tuple, Y: tuple, Z: tuple) -> list:
    """Coefficients (orders 0..4 in eps) of ``det(Y - X, Z - X)`` for perturbed points."""
    return _pdet(_vsub(Y, X), _vsub(Z, X))


def _sgn(poly: list) -> int:
    for c in poly:
        if c:
            return 1 if c > 0 else -1
    return 0


def _order(poly: list) -> int:
    for k, c in enumerate(poly):
        if c:
            return k
    return len(poly)


def _limit_fraction(num: list, other: list) -> Fraction:
    """Limit of ``num / (num - other)`` as eps -> 0, for polynomials of opposite signs."""
    k = min(_order(num), _order(other))
    return Fraction(num[k], num[k] - other[k])


def _on_closed_segment(Y: tuple, X0: tuple, X1: tuple) -> bool:
    """Whether the perturbed point Y, known collinear with X0 X1, lies on the closed segment X0 X1."""
    return _sgn(_pdot(_vsub(Y, X0), _vsub(X1, X0))) >= 0 and _sgn(_pdot(_vsub(Y, X1), _vsub(X0, X1))) >= 0


# -- contact pieces ----------------------------------------------------------------------------
@dataclass
class _Piece:
    """The contact set ``Z`` restricted to one pair of rows: a point, a segment or a rectangle.

    Coordinates are exact parameters ``(x1, x2)`` on components ``(c1, c2)``
    (before reduction modulo the length of a closed component).
    """

    c1: int
    c2: int
    verts: list  # [(x1, x2, (X, Y))] exact parameters and exact deformed point
    rect: tuple  # (s0, s1, t0, t1) exact
    rows: tuple  # (row on c1, row on c2)


def _segment_pieces(ex: _Exact, i: int, j: int) -> list:
    """Vertices ``(lam, mu, point)`` of the contact set of rows i and j (which must touch).

    ``point`` is in units of ``1/S`` (see :class:`_Exact`).
    """
    p0, p1 = ex.row(i)[4:]
    q0, q1 = ex.row(j)[4:]
    dp = (p1[0] - p0[0], p1[1] - p0[1])
    dq = (q1[0] - q0[0], q1[1] - q0[1])
    zp = dp == (0, 0)
    zq = dq == (0, 0)
    one = Fraction(1)

    def on(lam, base, d):
        return (base[0] + lam * d[0], base[1] + lam * d[1])

    def proj(x, base, d):
        return Fraction(_dot((x[0] - base[0], x[1] - base[1]), d), _dot(d, d))

    if zp and zq:
        return [(a, b, p0) for a in (_F0, one) for b in (_F0, one)]
    if zp:
        mu = proj(p0, q0, dq)
        return [(_F0, mu, p0), (one, mu, p0)]
    if zq:
        lam = proj(q0, p0, dp)
        return [(lam, _F0, q0), (lam, one, q0)]
    den = _det(dp, dq)
    if den:
        r = (q0[0] - p0[0], q0[1] - p0[1])
        lam = Fraction(_det(r, dq), den)
        mu = Fraction(_det(r, dp), den)
        return [(lam, mu, on(lam, p0, dp))]
    # collinear and overlapping
    a, b = proj(q0, p0, dp), proj(q1, p0, dp)
    lo, hi = max(_F0, min(a, b)), min(one, max(a, b))
    out = []
    for lam in (lo, hi) if hi != lo else (lo,):
        x = on(lam, p0, dp)
        out.append((lam, proj(x, q0, dq), x))
    return out


def _make_piece(ex: _Exact, i: int, j: int) -> _Piece:
    s0, s1 = ex.row(i)[2:4]
    t0, t1 = ex.row(j)[2:4]
    verts = []
    for lam, mu, pt in _segment_pieces(ex, i, j):
        v = (s0 + lam * (s1 - s0), t0 + mu * (t1 - t0), pt)
        if all(v[:2] != w[:2] for w in verts):
            verts.append(v)
    return _Piece(int(ex.S.comp[i]), int(ex.S.comp[j]), verts, (s0, s1, t0, t1), (i, j))


def _mirror(p: _Piece) -> _Piece:
    s0, s1, t0, t1 = p.rect
    return _Piece(p.c2, p.c1, [(b, a, pt) for a, b, pt in p.verts], (t0, t1, s0, s1), (p.rows[1], p.rows[0]))


def _touch_unperturbed(c: list, ex: _Exact, i: int, j: int) -> bool:
    """Whether the closed unperturbed segments of rows i and j meet (c = the four orientations)."""
    c1, c2, c3, c4 = c
    if c1 * c2 > 0 or c3 * c4 > 0:
        return False
    if c1 or c2 or c3 or c4:
        return True
    p0, p1 = ex.row(i)[4:]
    q0, q1 = ex.row(j)[4:]
    dp = (p1[0] - p0[0], p1[1] - p0[1])
    dq = (q1[0] - q0[0], q1[1] - q0[1])
    if dp == (0, 0) and dq == (0, 0):
        return p0 == q0
    if dp == (0, 0):
        p0, p1, q0, q1, dp, dq = q0, q1, p0, p1, dq, dp
    n = _dot(dp, dp)
    a = _dot((q0[0] - p0[0], q0[1] - p0[1]), dp)
    b = _dot((q1[0] - p0[0], q1[1] - p0[1]), dp)
    return max(a, b) >= 0 and min(a, b) <= n


def _vertex_label(ex: _Exact, k: int) -> str:
    S = ex.S
    c = int(S.comp[k])
    cp = ex.scene.components[c]
    if S.s0[k] == S.s1[k]:
        return f"vertex 0 of component {cp.name!r}"
    a = int(S.seg[k])
    b = (a + 1) % cp.n_vertices if cp.closed else a + 1
    return f"segment {a} (vertices {a}-{b}) of component {cp.name!r}"


def _degenerate_error(ex: _Exact, i: int, j: int, why: str) -> DegenerateError:
    S = ex.S
    pts = np.vstack([S.p0[i], S.p1[i], S.p0[j], S.p1[j]])
    scale = float(np.max(np.abs(pts))) or 1.0
    where = [float(v) for v in np.mean(pts, axis=0)]
    return DegenerateError(
        f"{_vertex_label(ex, i)} and {_vertex_label(ex, j)} touch near {where} in a configuration that the "
        f"generic-perturbation rule cannot decide ({why}); move one of these deformed vertices by a tiny "
        f"amount (e.g. {1e-9 * scale:.3g}) so that the contact becomes transversal or disappears"
    )


def _exact_pair(ex: _Exact, i: int, j: int):
    """Decide rows i (P) and j (Q) exactly.

    Returns ``None`` (no contact), ``("t", lam, mu, sign)`` for a transversal
    crossing, or ``("d", piece, crossing)`` for a degenerate contact, where
    ``crossing`` is ``None`` or ``(lam, mu, sign)`` for the perturbed curves.
    """
    P0, P1, _, _, p0, p1 = ex.row(i)
    Q0, Q1, _, _, q0, q1 = ex.row(j)

    def o0(a, b, c):
        return _det((b[0] - a[0], b[1] - a[1]), (c[0] - a[0], c[1] - a[1]))

    c = [o0(p0, p1, q0), o0(p0, p1, q1), o0(q0, q1, p0), o0(q0, q1, p1)]
    if not _touch_unperturbed(c, ex, i, j):
        return None
    if all(c):
        lam = Fraction(c[2], c[2] - c[3])
        mu = Fraction(c[0], c[0] - c[1])
        return ("t", lam, mu, 1 if c[1] > 0 else -1)
    piece = _make_piece(ex, i, j)
    polys = [_orient(P0, P1, Q0), _orient(P0, P1, Q1), _orient(Q0, Q1, P0), _orient(Q0, Q1, P1)]
    sg = [_sgn(o) for o in polys]
    if 0 in sg:
        # a perturbed endpoint stays on the other line for every eps: it must lie outside the other segment
        tests = [(Q0, P0, P1), (Q1, P0, P1), (P0, Q0, Q1), (P1, Q0, Q1)]
        for s, (Y, X0, X1) in zip(sg, tests, strict=True):
            if s == 0 and _on_closed_segment(Y, X0, X1):
                raise _degenerate_error(ex, i, j, "a perturbed vertex stays on the other perturbed segment")
        return ("d", piece, None)
    if sg[0] != sg[1] and sg[2] != sg[3]:
        lam = _limit_fraction(polys[2], polys[3])
        mu = _limit_fraction(polys[0], polys[1])
        return ("d", piece, (lam, mu, sg[1]))
    return ("d", piece, None)


# -- union of contact pieces into components of Z ----------------------------------------------
class _UnionFind:
    def __init__(self, n: int) -> None:
        self.parent = list(range(n))

    def find(self, a: int) -> int:
        p = self.parent
        while p[a] != a:
            p[a] = p[p[a]]
            a = p[a]
        return a

    def union(self, a: int, b: int) -> None:
        ra, rb = self.find(a), self.find(b)
        if ra != rb:
            self.parent[max(ra, rb)] = min(ra, rb)


def _touches_diagonal(p: _Piece, L: Fraction, closed: bool) -> bool:
    if p.c1 != p.c2:
        return False
    diffs = [a - b for a, b, _ in p.verts]
    lo, hi = min(diffs), max(diffs)
    shifts = (-L, _F0, L) if closed else (_F0,)
    return any(lo <= k <= hi for k in shifts)


def _components_of_contacts(ex: _Exact, pieces: list, signs: list, mirror: list) -> list:
    """Gather the pieces into connected components of Z and return the crossings they carry.

    ``signs[k]`` is the sum of the perturbed crossing signs attached to piece k
    (oriented as the piece); ``mirror[k]`` is the index of the mirrored piece
    ``(x2, x1)`` of a piece within one component (-1 between two components).
    Returns ``[(c1, c2, x1, x2, point, sign)]`` in exact reduced parameters.
    """
    S = ex.S
    Ls = [Fraction(float(x)) for x in S.length]
    closed = [bool(x) for x in S.closed]

    def red(c: int, x: Fraction) -> Fraction:
        return _F0 if closed[c] and x == Ls[c] else x

    uf = _UnionFind(len(pieces))
    lines: dict[tuple, list] = {}

    def register(key, lo, hi, c_other, pid):
        lst = lines.setdefault(key, [])
        lst.append((lo, hi, pid))
        if closed[c_other]:
            if hi == Ls[c_other]:
                lst.append((_F0, _F0, pid))
            if lo == 0:
                lst.append((Ls[c_other], Ls[c_other], pid))

    for pid, p in enumerate(pieces):
        s0, s1, t0, t1 = p.rect
        for val in {s0, s1}:
            vs = [b for a, b, _ in p.verts if a == val]
            if vs:
                register((p.c1, p.c2, 0, red(p.c1, val)), min(vs), max(vs), p.c2, pid)
        for val in {t0, t1}:
            vs = [a for a, b, _ in p.verts if b == val]
            if vs:
                register((p.c1, p.c2, 1, red(p.c2, val)), min(vs), max(vs), p.c1, pid)
    for lst in lines.values():
        lst.sort(key=lambda e: (e[0], e[1]))
        hi, first = None, None
        for lo_, hi_, pid in lst:
            if hi is not None and lo_ <= hi:
                uf.union(first, pid)
                hi = max(hi, hi_)
            else:
                hi, first = hi_, pid
    groups: dict[int, list] = {}
    for pid in range(len(pieces)):
        groups.setdefault(uf.find(pid), []).append(pid)

    info = {}
    for root, ids in groups.items():
        total = sum(signs[k] for k in ids)
        if total == 0:
            continue  # (the mirror of a component has the opposite total)
        diag = any(_touches_diagonal(pieces[k], Ls[pieces[k].c1], closed[pieces[k].c1]) for k in ids)
        best = None
        for k in ids:
            p = pieces[k]
            for a, b, pt in p.verts:
                key = (red(p.c1, a), red(p.c2, b))
                if best is None or key < best[0]:
                    best = (key, pt, k)
        info[root] = (diag, total, best)

    out = []
    for root, (diag, total, best) in info.items():
        if diag or total == 0:
            continue
        k = best[2]
        p = pieces[k]
        if p.c1 == p.c2:
            # the mirrored component carries the same crossing: keep the one with the smaller corner
            mroot = uf.find(mirror[k])
            if mroot == root or info[mroot][2][0] < best[0]:
                continue
        if abs(total) > 1:
            raise _degenerate_error(
                ex, p.rows[0], p.rows[1], f"a contact component carries a net crossing number {total}"
            )
        (x1, x2), pt = best[0], best[1]
        out.append((p.c1, p.c2, x1, x2, pt, 1 if total > 0 else -1))
    return out


def _inside(x: Fraction) -> float:
    """Round a parameter strictly inside a segment to a float that stays below the segment's end."""
    f = float(x)
    return math.nextafter(f, -math.inf) if f > x else f


def _segment_of(comp, x: Fraction) -> int:
    """Return the segment carrying exact parameter x (the one starting at a vertex; last for the last vertex)."""
    k = bisect.bisect_right(comp.params.tolist(), x) - 1
    return int(min(max(k, 0), comp.n_segments - 1))


# -- main entry point --------------------------------------------------------------------------
def find_crossings(scene) -> list[Crossing]:
    """Every transversal crossing of the deformed polylines, between components and within one.

    Parameters
    ----------
    scene : Scene or str
        The scene; only the deformed vertices and the reference parameters are used.
        A JSON file path or a built-in scene name is accepted too (:func:`direct.scenes.resolve`).

    Returns
    -------
    list of Crossing
        Each geometric crossing once, sorted by ``(components, params)``.
        Degenerate contacts (at vertices, collinear overlaps, collapsed
        segments) are resolved by the rule of the module docstring and
        marked ``exact=False``.

    Raises
    ------
    DegenerateError
        If a contact is too degenerate for the generic-perturbation rule.

    Examples
    --------
    >>> import direct
    >>> [(c.params, c.sign) for c in find_crossings(direct.scenes.get("cross"))]
    [((0.5, 0.5), 1)]
    """
    from .scenes import resolve

    scene = resolve(scene)
    S = _build_segments(scene)
    comps = scene.components
    results: list[Crossing] = []

    geoms = shapely.linestrings(np.stack([S.p0, S.p1], axis=1))
    tree = shapely.STRtree(geoms)
    # bounding-box candidates: a superset of the touching pairs that is exact in floating point
    ii, jj = tree.query(geoms)
    keep = ii < jj
    ii, jj = ii[keep], jj[keep]
    keep = ~_adjacent(S, ii, jj)
    ii, jj = ii[keep], jj[keep]

    # -- generic pairs, settled in floating point -------------------------------------------------
    p0, p1, q0, q1 = S.p0[ii], S.p1[ii], S.p0[jj], S.p1[jj]
    o1, k1 = _orient_float(p0, p1, q0)
    o2, k2 = _orient_float(p0, p1, q1)
    o3, k3 = _orient_float(q0, q1, p0)
    o4, k4 = _orient_float(q0, q1, p1)
    sep12 = k1 & k2 & (np.sign(o1) == np.sign(o2))
    sep34 = k3 & k4 & (np.sign(o3) == np.sign(o4))
    certain = k1 & k2 & k3 & k4
    hit = certain & ~sep12 & ~sep34
    fallback = np.flatnonzero(~certain & ~sep12 & ~sep34)

    if hit.any():
        a, b = ii[hit], jj[hit]
        t = o3[hit] / (o3[hit] - o4[hit])
        s = o1[hit] / (o1[hit] - o2[hit])
        # t, s lie strictly inside (0, 1): keep the parameters inside their segments after rounding
        xa = np.clip(S.s0[a] + t * (S.s1[a] - S.s0[a]), S.s0[a], np.nextafter(S.s1[a], -np.inf))
        xb = np.clip(S.s0[b] + s * (S.s1[b] - S.s0[b]), S.s0[b], np.nextafter(S.s1[b], -np.inf))
        pt = S.p0[a] + t[:, None] * (S.p1[a] - S.p0[a])
        sign = np.where(o2[hit] > 0, 1, -1)
        swap = (S.comp[a] > S.comp[b]) | ((S.comp[a] == S.comp[b]) & (xa > xb))
        ca, cb = np.where(swap, S.comp[b], S.comp[a]), np.where(swap, S.comp[a], S.comp[b])
        x1, x2 = np.where(swap, xb, xa), np.where(swap, xa, xb)
        g1, g2 = np.where(swap, S.seg[b], S.seg[a]), np.where(swap, S.seg[a], S.seg[b])
        sign = np.where(swap, -sign, sign)
        for r in range(len(a)):
            results.append(
                Crossing(
                    (int(ca[r]), int(cb[r])),
                    (float(x1[r]), float(x2[r])),
                    (int(g1[r]), int(g2[r])),
                    (float(pt[r, 0]), float(pt[r, 1])),
                    int(sign[r]),
                    True,
                )
            )

    # -- uncertain pairs, settled exactly ----------------------------------------------------------
    ex = _Exact(S, scene)
    pieces: list[_Piece] = []
    signs: list[int] = []
    mirror: list[int] = []

    def add_piece(piece: _Piece, sign: int) -> None:
        if piece.c1 == piece.c2:
            Lc = Fraction(float(S.length[piece.c1]))
            if len(piece.verts) == 1 and _touches_diagonal(piece, Lc, bool(S.closed[piece.c1])) and sign == 0:
                return  # just the shared point of two consecutive segments
            n = len(pieces)
            pieces.extend([piece, _mirror(piece)])
            signs.extend([sign, -sign])
            mirror.extend([n + 1, n])
        else:
            pieces.append(piece if piece.c1 < piece.c2 else _mirror(piece))
            signs.append(sign if piece.c1 < piece.c2 else -sign)
            mirror.append(-1)

    def report(i: int, j: int, lam: Fraction, mu: Fraction) -> tuple:
        s0, s1 = ex.row(i)[2:4]
        t0, t1 = ex.row(j)[2:4]
        return s0 + lam * (s1 - s0), t0 + mu * (t1 - t0)

    for k in fallback:
        i, j = int(ii[k]), int(jj[k])
        res = _exact_pair(ex, i, j)
        if res is None:
            continue
        if res[0] == "t":
            _, lam, mu, sgn = res
            xa, xb = report(i, j, lam, mu)
            P0, P1 = ex.row(i)[4:]
            pt = ex.to_float_point((P0[0] + lam * (P1[0] - P0[0]), P0[1] + lam * (P1[1] - P0[1])))
            ci, cj, gi, gj = int(S.comp[i]), int(S.comp[j]), int(S.seg[i]), int(S.seg[j])
            if ci > cj or (ci == cj and xa > xb):
                ci, cj, gi, gj, xa, xb, sgn = cj, ci, gj, gi, xb, xa, -sgn
            results.append(
                Crossing((ci, cj), (_inside(xa), _inside(xb)), (gi, gj), (float(pt[0]), float(pt[1])), sgn, True)
            )
            continue
        _, piece, cross = res
        add_piece(piece, 0 if cross is None else cross[2])

    # -- folds and collapsed segments between consecutive rows (they only shape Z) ------------------
    m = len(S.comp)
    a = np.arange(m)
    nxt = a + 1
    ok = nxt < m
    a, nxt = a[ok], nxt[ok]
    ok = _adjacent(S, a, nxt)
    a, nxt = a[ok], nxt[ok]
    # closing adjacency of a closed component: its last row (second closing segment) and its segment 0
    last = np.flatnonzero(S.closed[S.comp] & (S.pos == S.chain[S.comp] - 1))
    first = np.searchsorted(S.comp, S.comp[last])  # rows are grouped by component, segment 0 first
    a, nxt = np.concatenate([a, first]), np.concatenate([nxt, last])
    zero = np.all(S.p0 == S.p1, axis=1)
    dp, dq = S.p1[a] - S.p0[a], S.p1[nxt] - S.p0[nxt]
    left, right = dp[:, 0] * dq[:, 1], dp[:, 1] * dq[:, 0]
    flat = np.abs(left - right) <= _ORIENT_ERR * (np.abs(left) + np.abs(right)) + 1e-300
    backward = (dp * dq).sum(axis=1) <= 0
    ok = zero[a] | zero[nxt] | (flat & backward)
    for i, j in zip(a[ok], nxt[ok], strict=True):
        piece = _make_piece(ex, int(i), int(j))
        if len(piece.verts) > 1:
            add_piece(piece, 0)
    for i in np.flatnonzero(zero & (S.s0 != S.s1)):
        add_piece(_make_piece(ex, int(i), int(i)), 0)

    for c1, c2, x1, x2, pt, sgn in _components_of_contacts(ex, pieces, signs, mirror):
        results.append(
            Crossing(
                (c1, c2),
                (float(x1), float(x2)),
                (_segment_of(comps[c1], x1), _segment_of(comps[c2], x2)),
                ex.to_float_point(pt),
                sgn,
                False,
            )
        )
    results.sort(key=lambda c: (c.components, c.params))
    return results
