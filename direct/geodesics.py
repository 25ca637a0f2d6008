r"""Geodesic distances in a pair domain: grid Dijkstra, then continuous refinement.

Two stages (section 5.1.1 computes the matrix ``A`` of eq. (34) from
geodesic distances):

1. **Grid Dijkstra** (:func:`grid_distances`) on the graph of
   :func:`direct.grid.build_graph`, with :func:`scipy.sparse.csgraph.dijkstra`
   or, as an independent cross-check, :mod:`networkx`.  It gives the
   distances between all *terminals* (the boundary parts, then the crossing
   points) and the route of each geodesic.  On the pieces of program (34)
   the searches are bounded: one from the boundary, then one from each point
   stopped where no curve can be worth it.  Grid distances are lengths of
   real curves, hence upper bounds, but they keep a metrication bias that
   refining the grid never removes (up to 2.75 % with 16 neighbours, see
   ``shared/NUMERICS.md``).  On a torus, :func:`torus_distances` works on a
   3 x 3 block of the universal cover, so that each distance comes with the
   homotopy class of its route (how many times it goes around each circle).
2. **Continuous refinement** (:func:`refine`): each route becomes a polyline
   whose exact metric length is minimized.  A coarse pass first (16 segments,
   each across many cells, where the kinks of the length are small ripples)
   settles the large-scale shape; then the polyline gets a vertex wherever it
   crosses a vertex parameter of either component (the metric's norm jumps
   there and the geodesic refracts), sliding along that line, so that every
   segment lies in one cell where its length is smooth.  Free vertices move
   across the curve only (along the polyline's normals: moves along it barely
   change the length and make the problem singular), ends slide on their
   boundary, with a geometric grading of vertices next to them and the
   freedom to change side at a corner.  A damped Newton method
   (Levenberg-Marquardt, Marquardt's scaling, steps limited to half a
   segment) uses the exact gradient (:func:`direct.metric.segment_lengths`)
   and a Hessian from central differences of it, tridiagonal in the unknowns
   of an open curve; an L-BFGS-B pass takes over where Newton stalls on a
   kink.  The number of segments doubles, three levels at least, until the
   length changes by less than the tolerance; the value is
   Richardson-extrapolated (error ``~ n^-2``) and the error estimate is the
   whole last change, at least a quarter of the change before it.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Literal

import numpy as np
import scipy.sparse as sp
from scipy.linalg import LinAlgError, solve_banded
from scipy.optimize import minimize
from scipy.sparse.csgraph import dijkstra
from scipy.sparse.linalg import spsolve

from .grid import Domain, GridGraph
from .metric import Metric, _breaks, _vertex_params, segment_lengths

__all__ = [
    "grid_distances", "torus_distances", "closed_curve_distances", "refine", "coarse_geodesic", "RefinedPath", "Backend"
]

Backend = Literal["scipy", "networkx"]


def _paths_from_predecessors(pred: np.ndarray, sources: np.ndarray):
    def route(a: int, target: int) -> list[int]:
        out = [int(target)]
        while out[-1] != sources[a]:
            nxt = int(pred[a, out[-1]])
            if nxt < 0:
                raise RuntimeError("no path")  # pragma: no cover - callers only ask for reachable targets
            out.append(nxt)
        return out[::-1]

    return route


def _shortest(matrix: sp.csr_matrix, sources: np.ndarray, backend: Backend):
    """Distances from ``sources`` to every node, and a route function ``route(a, target)``."""
    if backend == "scipy":
        dist, pred = dijkstra(matrix, directed=True, indices=sources, return_predecessors=True)
        return dist, _paths_from_predecessors(pred, sources)
    if backend == "networkx":
        import networkx as nx

        coo = matrix.tocoo()
        G = nx.DiGraph()
        G.add_nodes_from(range(matrix.shape[0]))
        G.add_weighted_edges_from(zip(coo.row.tolist(), coo.col.tolist(), coo.data.tolist()))
        dist = np.full((len(sources), matrix.shape[0]), np.inf)
        paths = []
        for k, s in enumerate(sources):
            d, p = nx.single_source_dijkstra(G, int(s), weight="weight")
            dist[k, list(d.keys())] = list(d.values())
            paths.append(p)
        return dist, (lambda a, target: paths[a][int(target)])
    raise ValueError(f"backend must be 'scipy' or 'networkx', got {backend!r}")


def _bounded_shortest(matrix: sp.csr_matrix, sources: np.ndarray, bound: float):
    """:func:`_shortest` from one ground (``sources[0]``) and points, each point's search bounded (see ``bound``)."""
    d0, p0 = dijkstra(matrix, directed=True, indices=sources[:1], return_predecessors=True)
    d_ground = d0[0, sources[1:]]
    reach = np.isfinite(d_ground)
    far = float(d_ground[reach].max()) if reach.any() else np.inf
    dist = np.full((len(sources), matrix.shape[0]), np.inf)
    pred = np.full(dist.shape, -9999, dtype=np.int32)
    dist[0], pred[0] = d0[0], p0[0]
    for a in range(1, len(sources)):
        limit = bound * (d_ground[a - 1] + far) if reach[a - 1] else np.inf
        dist[a], pred[a] = dijkstra(matrix, directed=True, indices=int(sources[a]), return_predecessors=True,
                                    limit=limit)
    return dist, _paths_from_predecessors(pred, sources)


def grid_distances(
    graph: GridGraph, backend: Backend = "scipy", bound: float | None = None
) -> tuple[np.ndarray, callable]:
    """Grid distances between the terminals of a domain: its boundary parts, then its crossing points.

    Parameters
    ----------
    graph : GridGraph
        From :func:`direct.grid.build_graph`.
    backend : {"scipy", "networkx"}
        ``scipy.sparse.csgraph.dijkstra`` (default), or networkx's Dijkstra
        as an independent implementation.
    bound : float, optional
        Bounded searches (scipy, domains with one boundary part: the pieces
        ``I_i x I_j`` of program (34)).  One search from the boundary first
        gives every point's distance ``d_a`` to it; the search from point ``a``
        then stops at ``bound * (d_a + max_b d_b)``.  A curve between two
        points is only worth it when shorter than sending both to the boundary,
        so with ``bound`` at least the grid's overestimate factor no entry that
        program (34) could use is lost.  Entries beyond the limit are ``inf``.

    Returns
    -------
    T : (n_terminals, n_terminals) ndarray
        ``T[a, b]``: grid distance of a curve from terminal ``a`` to terminal
        ``b`` (terminals ``0 .. n_grounds - 1`` are the boundary parts, the
        others the crossing points in order).  No curve runs through the
        boundary.
    route : callable
        ``route(a, b)`` is the parameter-space polyline of that curve;
        ``route.candidates(a, g, margin)`` lists the routes from point ``a``
        to boundary part ``g`` that end in distinct stretches of the
        boundary and cost at most ``(1 + margin)`` times the best: the
        geodesic to a boundary can have several local minima whose grid
        lengths differ by less than the grid's bias.
    """
    src, dst = graph.sources, graph.targets
    if bound is not None and backend == "scipy" and graph.n_grounds == 1 and len(src) > 1:
        dist, node_route = _bounded_shortest(graph.matrix, src, bound)
    else:
        dist, node_route = _shortest(graph.matrix, src, backend)

    def route(a: int, b: int) -> np.ndarray:
        return graph.node_path(node_route(a, dst[b]))

    def candidates(a: int, g: int, margin: float, most: int = 6) -> list[np.ndarray]:
        on = graph.rows == g
        nodes, w = graph.cols[on], graph.weights[on]
        cost = dist[a, nodes] + w
        ends = graph.exit_points[g, nodes]
        # order the exits along the boundary, then keep the local minima of the cost: one per basin
        dom = graph.domain
        if dom.kind in ("cylinder", "annulus"):
            key, periodic = ends[:, 0], True
        else:  # the boundary of a rectangle or triangle is star-shaped about its centroid
            centre = np.nanmean(ends, axis=0) if dom.kind == "torus" else np.array(dom.local_lengths) / 2
            if dom.kind == "triangle":
                centre = np.array([dom.local_lengths[0] / 3, 2 * dom.local_lengths[1] / 3])
            key, periodic = np.arctan2(ends[:, 1] - centre[1], ends[:, 0] - centre[0]), True
        order = np.argsort(key, kind="stable")
        c = cost[order]
        n = len(c)
        is_min = np.ones(n, dtype=bool)
        for shift in (1, 2, 3):
            for sgn in (1, -1):
                nb = np.roll(c, sgn * shift) if periodic else np.concatenate([c, np.full(shift, np.inf)])
                if not periodic:
                    nb = np.roll(nb, sgn * shift)[:n]
                is_min &= c <= nb
        best = cost.min()
        picked = order[is_min & (c <= (1 + margin) * best)]
        picked = picked[np.argsort(cost[picked])][:most]
        return [graph.node_path(node_route(a, int(nodes[k])) + [g]) for k in picked]

    route.candidates = candidates
    return dist[:, dst], route


_COVER = [(a, b) for a in (-1, 0, 1) for b in (-1, 0, 1)]


def _cover_index(k: np.ndarray) -> np.ndarray:
    """Index in ``_COVER`` of classes ``k`` (rows of two ints in ``{-1, 0, 1}``)."""
    return 3 * (k[..., 0] + 1) + (k[..., 1] + 1)


def _cover_matrix(graph: GridGraph) -> sp.csr_matrix:
    """The 3 x 3 block of the universal cover of a torus graph: copy ``c`` of node ``u`` is ``u + N c``."""
    cached = getattr(graph, "_cover", None)
    if cached is not None:
        return cached
    N = graph.n_nodes
    rows, cols, data = [], [], []
    for c in _COVER:
        k = np.array(c)
        for r, q, w, dk in ((graph.rows, graph.cols, graph.weights, graph.winds),
                            (graph.cols, graph.rows, graph.weights, -graph.winds)):
            to = k[None, :] + dk
            ok = (np.abs(to) <= 1).all(axis=1)
            rows.append(r[ok] + N * _COVER.index(c))
            cols.append(q[ok] + N * _cover_index(to[ok]))
            data.append(w[ok])
    n = N * len(_COVER)
    M = sp.csr_matrix((np.concatenate(data), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
    graph._cover = M
    return M


def torus_distances(graph: GridGraph, backend: Backend = "scipy") -> tuple[dict, callable]:
    """Grid distances between crossing points of a torus, by homotopy class.

    Returns
    -------
    T : dict
        ``T[(k1, k2)][a, b]``: grid distance from point ``a`` to point ``b``
        along a route that crosses the seams ``s = 0`` and ``v = 0`` (signed)
        ``k1`` and ``k2`` times, for ``k1, k2`` in ``{-1, 0, 1}``.
    route : callable
        ``route(a, b, k)``: the unwrapped parameter polyline of that route.
    """
    N = graph.n_nodes
    M = _cover_matrix(graph)
    centre = _COVER.index((0, 0))
    src = graph.crossing_nodes + N * centre
    dist, node_route = _shortest(M, src, backend)
    T = {c: dist[:, graph.crossing_nodes + N * k] for k, c in enumerate(_COVER)}

    def route(a: int, b: int, c: tuple[int, int]) -> np.ndarray:
        nodes = node_route(a, graph.crossing_nodes[b] + N * _COVER.index(tuple(c)))
        return _cover_polyline(graph, nodes)

    return T, route


def _cover_polyline(graph: GridGraph, nodes) -> np.ndarray:
    N = graph.n_nodes
    S, V = graph.domain.local_lengths
    st = []
    for v in nodes:
        u, k = int(v) % N, _COVER[int(v) // N]
        st.append(graph.coords[u] + np.array([k[0] * S, k[1] * V]))
    return graph.domain.to_param(np.array(st))


def closed_curve_distances(graph: GridGraph, max_bases: int = 24) -> dict:
    """Shortest closed grid curves of a torus in the primitive homotopy classes.

    Parameters
    ----------
    graph : GridGraph
        A torus graph.
    max_bases : int
        Base points tried per seam: a closed curve of class ``(a, b)`` with
        ``a != 0`` crosses the seam ``s = 0``, one with ``a = 0`` the seam ``v = 0``.

    Returns
    -------
    dict
        ``{(a, b): (length, polyline)}`` for the eight classes with ``|a|, |b| <= 1``;
        the polyline (parameters) ends at its start shifted by ``(a S, b V)`` in
        local coordinates.  Opposite classes are the same curves run backwards.
    """
    N = graph.n_nodes
    M = _cover_matrix(graph)
    centre = _COVER.index((0, 0))
    grid = graph.coords
    out = {}
    for axis, classes in ((0, [(1, 0), (1, 1), (1, -1)]), (1, [(0, 1)])):
        on_seam = np.flatnonzero(np.isfinite(grid[:, 0]) & np.isclose(grid[:, axis], 0.0))
        on_seam = on_seam[np.unique(np.linspace(0, len(on_seam) - 1, min(max_bases, len(on_seam))).astype(int))]
        src = on_seam + N * centre
        dist, node_route = _shortest(M, src, "scipy")
        for a, b in classes:
            tgt = on_seam + N * _COVER.index((a, b))
            d = dist[np.arange(len(src)), tgt]
            k = int(np.argmin(d))
            poly = _cover_polyline(graph, node_route(k, tgt[k]))
            out[(a, b)] = (float(d[k]), poly)
            out[(-a, -b)] = (float(d[k]), poly[::-1].copy())
    return out


# ---------------------------------------------------------------------------------------------------------------
# continuous refinement
# ---------------------------------------------------------------------------------------------------------------


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


def _segment_derivatives(metric: Metric, comps, P: np.ndarray, Q: np.ndarray, step: float,
                         hessian: bool = True):
    """Length, gradient (m, 4) and Hessian (m, 4, 4) of each segment in its end coordinates ``(P1, P2, Q1, Q2)``.

    The gradient is exact (:func:`direct.metric.segment_lengths`); the Hessian
    is its central difference with step ``step``, symmetrized.
    """
    m = len(P)
    U = np.hstack([P, Q])
    if not hessian:
        f, g = segment_lengths(metric, comps, P, Q, gradient=True)
        return f, g, None
    st = np.broadcast_to(np.asarray(step, dtype=float), (m,))[:, None]  # one step per segment
    E = np.eye(4)
    Us = np.vstack([U] + [U + st * e for e in E] + [U - st * e for e in E])
    f, g = segment_lengths(metric, comps, Us[:, :2], Us[:, 2:], gradient=True)
    g = g.reshape(9, m, 4)
    H = np.stack([(g[1 + k] - g[5 + k]) / (2 * st) for k in range(4)], axis=1)  # H[:, k, :] = d grad / d u_k
    H = 0.5 * (H + H.transpose(0, 2, 1))
    return f[:m], g[0], H


def _project(domain: Domain, X: np.ndarray) -> np.ndarray:
    """Put polyline vertices (parameters, unwrapped) back into the closed domain."""
    if domain.kind == "torus":
        return X
    st = domain.to_local(X, wrap=False)
    S, V = domain.local_lengths
    ps, _ = domain.periodic
    if not ps:
        st[:, 0] = np.clip(st[:, 0], 0.0, S)
    st[:, 1] = np.clip(st[:, 1], 0.0, V)
    X = domain.to_param(st)
    if domain.kind == "triangle":
        low = X[:, 1] < X[:, 0]
        X[low] = 0.5 * (X[low, 0] + X[low, 1])[:, None]
    return X


class _Parametrization:
    """Vertices of a polyline as an affine function ``X = X0 + M z`` of the unknowns ``z``.

    ``modes[k]`` is ``"fixed"`` (a crossing point), ``"free"`` (two unknowns),
    or ``(base, e, lo, hi)``: the vertex slides on the line ``base + tau e``
    with ``lo <= tau <= hi`` (one unknown): a free end on the boundary, or a
    refraction point on a line where the metric's norm jumps.  For a closed
    curve (``shift`` given) the last vertex is the first plus ``shift``.
    """

    def __init__(self, X: np.ndarray, modes: list, shift=None):
        n = len(X) - 1
        self.n = n
        self.X0 = X.copy()
        rows, cols, vals = [], [], []
        nz = 0
        self.slides = []
        last = n - 1 if shift is not None else n
        first_cols = None
        for k in range(last + 1):
            mode = modes[k]
            if isinstance(mode, str) and mode == "fixed":
                continue
            self.X0[k] = 0.0
            if isinstance(mode, str):  # free
                rows.extend([2 * k, 2 * k + 1])
                cols.extend([nz, nz + 1])
                vals.extend([1.0, 1.0])
                entries = [(0, nz, 1.0), (1, nz + 1, 1.0)]
                nz += 2
            else:
                base, e, lo, hi = mode
                self.X0[k] = base
                rows.extend([2 * k, 2 * k + 1])
                cols.extend([nz, nz])
                vals.extend([e[0], e[1]])
                entries = [(0, nz, e[0]), (1, nz, e[1])]
                self.slides.append((nz, lo, hi))
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
        arr = np.array(self.slides, dtype=float).reshape(-1, 3)
        self._slide_idx, self._lo, self._hi = arr[:, 0].astype(int), arr[:, 1], arr[:, 2]

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
        z[self._slide_idx] = np.clip(z[self._slide_idx], self._lo, self._hi)
        return z

    def unpack(self, z: np.ndarray) -> np.ndarray:
        if self.banded:
            X = self.X0.copy()
            X[self.vertex] += z[:, None] * self.E
            return X
        return self.X0 + (self.M @ z).reshape(-1, 2)


def _normal_modes(X: np.ndarray, modes: list, closed: bool) -> list:
    """Let each free vertex move only across the polyline, along its normal.

    Moving vertices along a geodesic barely changes its length (not at all
    where it is straight), so with both coordinates free the Hessian is
    nearly singular and Newton creeps; the normal offsets alone are well
    conditioned.  The spacing of the vertices stays that of the resampled
    route and its midpoint refinements, the family Richardson extrapolation
    assumes.
    """
    if closed:
        prev = np.roll(X[:-1], 1, axis=0)
        nxt = np.roll(X[:-1], -1, axis=0)
        prev[0] = X[-2] - (X[-1] - X[0])
        tangent = np.vstack([nxt - prev, [[0.0, 0.0]]])
    else:
        tangent = np.zeros_like(X)
        tangent[1:-1] = X[2:] - X[:-2]
    out = list(modes)
    for k, mode in enumerate(modes):
        if isinstance(mode, str) and mode == "free":
            t = tangent[k]
            norm = np.hypot(t[0], t[1])
            e = np.array([-t[1], t[0]]) / norm if norm > 0 else np.array([1.0, 0.0])
            out[k] = (X[k].copy(), e, -np.inf, np.inf)
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


def _grade_ends(domain: Domain, X: np.ndarray, modes: list, start_ground, end_ground, scale: float):
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
            modes = [modes[0]] + ["free"] * depth + list(modes[1:])
        else:
            X = np.vstack([X[:-1], pts, X[-1:]])
            modes = list(modes[:-1]) + ["free"] * depth + [modes[-1]]
    return X, modes


def _corner_switch(domain: Domain, metric: Metric, X: np.ndarray, modes: list, k: int) -> list:
    """Let an end held at a corner of the boundary slide on the other side if that is cheaper.

    An end slides on one side of a rectangle or triangle; the optimizer
    stops it at the corner where that side ends, even when the geodesic
    wants to go on along the other side (a grazing crossing, whose narrow
    valley runs into the corner).  Try a small step along every side through
    that corner and keep the side of the cheapest.
    """
    mode = modes[k]
    if isinstance(mode, str) or domain.kind in ("cylinder", "annulus", "torus"):
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

    best, best_mode = cost(q), mode
    for _, base, e, (lo, hi) in through:
        tau = float((q - base) @ e)
        for sgn in (1.0, -1.0):
            t = tau + sgn * step
            if lo <= t <= hi:
                c = cost(base + t * e)
                if c < best:
                    best, best_mode = c, (base, e, lo, hi)
    if best_mode is mode:
        return modes
    out = list(modes)
    out[k] = best_mode
    return out


def _truncate_at_boundary(domain: Domain, ground: int, X: np.ndarray, modes: list) -> tuple[np.ndarray, list]:
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
    modes = list(modes[:k]) + [(base, e, lo, hi)]
    return X, modes


def _resampled_with_ends(domain: Domain, route: np.ndarray, n: int, start_ground, end_ground, closed: bool):
    """``n`` segments evenly along the route; ends fixed (crossing points) or sliding on their boundary."""
    X = _resample(route, n)
    modes: list = ["free"] * (n + 1)
    if not closed:
        for k, ground in ((0, start_ground), (n, end_ground)):
            if ground is None:
                modes[k] = "fixed"
            else:
                base, e, (lo, hi) = _side(domain, ground, X[k])
                modes[k] = (base, e, lo, hi)
    return X, modes


def coarse_geodesic(
    domain: Domain, metric: Metric, route: np.ndarray, end_ground: int | None = None
) -> tuple[np.ndarray, float]:
    """The coarse geodesic near a route (the first stage of :func:`refine`) and its exact length.

    Cheap, and enough to rank routes that lead to different local geodesics;
    the polyline is a good start for :func:`refine`, whose first stage then
    has nothing left to do.
    """
    scale = float(max(domain.lengths))
    X = _coarse_geodesic(domain, metric, np.asarray(route, dtype=float), None, end_ground, None, scale, False)
    return X, float(segment_lengths(metric, domain.comps, X[:-1], X[1:]).sum())


def _coarse_geodesic(
    domain, metric, route, start_ground, end_ground, shift, scale, closed, n: int = 16, rounds: int = 3
) -> np.ndarray:
    """Straighten a grid route at a coarse scale first: ``n`` segments, each across many cells.

    At that scale the kinks of the length (where segments cross vertex
    lines) are small ripples, so the large-scale shape of the geodesic
    settles quickly; the fine levels then only adjust it locally.
    """
    X, modes = _resampled_with_ends(domain, route, n, start_ground, end_ground, closed)
    for _ in range(rounds):
        X = _optimize_level(domain, metric, X, _normal_modes(X, modes, closed), shift, scale, polish=False)
        if end_ground is not None:
            X, modes = _truncate_at_boundary(domain, end_ground, X, modes)
    return X


def _initial_polyline(domain: Domain, route: np.ndarray, start: int, start_ground, end_ground, closed: bool):
    """First polyline of the refinement: the route's ends and its crossings with the cell lines.

    Each segment then lies in one cell, where the length is a smooth function
    of its ends.  Where the route crosses fewer than ``start`` lines, its
    evenly resampled points fill in (free vertices).
    """
    X, modes = _resampled_with_ends(domain, route, start, start_ground, end_ground, closed)
    smooth = _resample(route, 4 * start)  # the grid route zigzags at the scale of the grid: smooth it first
    Y, ymodes = _insert_breaks(domain, smooth, ["free"] * len(smooth))
    lines = [k for k, m in enumerate(ymodes) if not isinstance(m, str)]
    if len(lines) + 1 < start:
        return _insert_breaks(domain, X, modes)
    keep = [0] + lines + [len(Y) - 1]
    X = Y[keep]
    modes = [modes[0]] + [ymodes[k] for k in lines] + [modes[-1]]
    if closed:
        modes[0] = modes[-1] = "free"
    return X, modes


def _prune_breaks(X: np.ndarray, modes: list) -> tuple[np.ndarray, list]:
    """Drop refraction vertices whose neighbours are on the same side of their line.

    Such a vertex only touches the line: the curve no longer crosses it there,
    and holding a vertex on it would keep the curve in a sequence of cells it
    has left.  :func:`_insert_breaks` adds back the crossings that remain.
    """
    keep = np.ones(len(X), dtype=bool)
    for k in range(1, len(X) - 1):
        mode = modes[k]
        if isinstance(mode, str) or mode[1][0] * mode[1][1] != 0:
            continue
        axis = 0 if mode[1][0] == 0.0 else 1  # the coordinate that is constant on the line
        c = X[k, axis]
        if (X[k - 1, axis] - c) * (X[k + 1, axis] - c) >= 0:
            keep[k] = False
    if keep.all():
        return X, modes
    return X[keep], [m for m, kk in zip(modes, keep) if kk]


def _insert_breaks(domain: Domain, X: np.ndarray, modes: list) -> tuple[np.ndarray, list]:
    """Add a sliding vertex where the polyline crosses a vertex parameter of either component.

    There the metric's norm jumps and the geodesic refracts; with a vertex on
    the line, every segment stays in one cell, where the length is smooth.
    """
    P, Q = X[:-1], X[1:]
    new_t, new_seg, new_axis = [], [], []
    for axis, comp in enumerate(domain.comps):
        u0, u1 = P[:, axis], Q[:, axis]
        vp = _vertex_params(comp, float(min(u0.min(), u1.min())), float(max(u0.max(), u1.max())))
        seg, t = _breaks(vp, u0, u1)
        keep = (t > 1e-9) & (t < 1 - 1e-9)
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
    out_X, out_modes = [], []
    j = 0
    for k in range(len(X)):
        out_X.append(X[k])
        out_modes.append(modes[k])
        while j < len(seg) and seg[j] == k:
            e = np.array([0.0, 1.0]) if axis[j] == 0 else np.array([1.0, 0.0])
            base = pts[j] * (1 - e)
            out_X.append(pts[j])
            out_modes.append((base, e, -np.inf, np.inf))
            j += 1
    return np.array(out_X), out_modes


def _newton(par, unpack, length, assemble, z, scale, max_iter, rtol=1e-11):
    """Damped Newton (Levenberg-Marquardt) with backtracking: ``(X, converged)``.

    Converged when the Newton decrement (the model's decrease, about twice the
    length still to gain) is at most ``rtol`` times the length.

    ``assemble(X)`` returns the length, its gradient and its Hessian in the
    unknowns: a sparse matrix, or ``(diag, off)`` for a tridiagonal one.
    """
    X = unpack(z)
    f, grad, H = assemble(X)
    lam = 1e-8
    eye = None if isinstance(H, tuple) else sp.identity(par.nv, format="csc")
    for _ in range(max_iter):
        if isinstance(H, tuple):
            diag, off = H
            damp = np.maximum(np.abs(diag), 1e-12 * max(float(np.abs(diag).max()), 1e-300))  # Marquardt scaling
            ab = np.zeros((3, len(diag)))
            ab[0, 1:], ab[1], ab[2, :-1] = off, diag + lam * damp, off
            try:
                dz = solve_banded((1, 1), ab, -grad, check_finite=False)
            except (LinAlgError, ValueError):
                dz = np.full_like(grad, np.nan)
        else:
            hscale = max(float(np.abs(H.diagonal()).max()), 1e-300)
            dz = spsolve(H + lam * hscale * eye, -grad)
        decrease = -float(dz @ grad)
        if not np.all(np.isfinite(dz)) or decrease <= 0:
            lam = max(lam * 100, 1e-6)
            if lam > 1e8:
                return X, False
            continue
        if decrease <= rtol * f:
            return X, True
        t, accepted = 1.0, False
        if par.banded:  # no vertex moves more than half its shorter segment in one step: the curve keeps its shape
            seg = np.linalg.norm(np.diff(X, axis=0), axis=1)
            room = np.minimum(seg[np.maximum(par.vertex - 1, 0)], seg[np.minimum(par.vertex, len(seg) - 1)])
            room = np.maximum(room, 0.25 * float(np.mean(seg)))  # a vertex beside a tiny segment may still move
            move = np.abs(dz) * np.sqrt(par._diag)
            worst = float(np.max(move / np.maximum(room, 1e-300)))
            t = min(1.0, 0.5 / worst) if worst > 0 else 1.0
        for _ls in range(12):
            X_new = unpack(par.clip(z + t * dz))
            f_new = length(X_new)
            if f_new <= f:
                accepted = True
                break
            t *= 0.5
        if not accepted:
            lam *= 100
            if lam > 1e8:
                return X, False
            continue
        z = par.pack(X_new)
        stalled = f - f_new <= 1e-13 * f and decrease <= 1e-8 * f  # converged to rounding
        X, f = X_new, f_new
        if stalled:
            return X, True
        lam = max(lam / 10, 1e-12)
        f, grad, H = assemble(X)
    return X, False


def _optimize_level(domain: Domain, metric: Metric, X0: np.ndarray, modes: list, shift, scale: float,
                    max_iter: int = 20, polish: bool = True) -> np.ndarray:
    """Minimize the exact length of a polyline over its free coordinates.

    Damped Newton (Levenberg-Marquardt with Marquardt's diagonal scaling) with
    a backtracking line search; where it stalls (lengths that are not smooth,
    such as the degenerate norm of the euclid metric) an L-BFGS-B polish takes
    over, unless ``polish`` is False (the coarse pass, which only needs the
    shape of the curve).
    """
    comps = domain.comps
    par = _Parametrization(X0, modes, shift)
    if par.nv == 0:
        return X0
    n = par.n
    step = 1e-6 * scale
    # global coordinate indices of the local coordinates (P1, P2, Q1, Q2) of each segment
    k = np.arange(n)
    loc = np.column_stack([2 * k, 2 * k + 1, 2 * k + 2, 2 * k + 3])

    def unpack(z):
        return _project(domain, par.unpack(z))

    def length(X):
        return float(segment_lengths(metric, comps, X[:-1], X[1:]).sum())

    def assemble(X):
        seg = np.linalg.norm(X[1:] - X[:-1], axis=1)
        steps = np.minimum(step, np.maximum(1e-3 * seg, 1e-9 * scale))  # short segments get short steps
        f, gl, Hl = _segment_derivatives(metric, comps, X[:-1], X[1:], steps)
        if par.banded:  # tridiagonal in the unknowns: project the 4 x 4 blocks on each vertex's direction
            gV = np.zeros((n + 1, 2))
            gV[:-1] += gl[:, :2]
            gV[1:] += gl[:, 2:]
            dV = np.zeros(n + 1)
            E = np.zeros((n + 1, 2))
            E[par.vertex] = par.E
            dV[:-1] += np.einsum("ki,kij,kj->k", E[:-1], Hl[:, :2, :2], E[:-1])
            dV[1:] += np.einsum("ki,kij,kj->k", E[1:], Hl[:, 2:, 2:], E[1:])
            oV = np.einsum("ki,kij,kj->k", E[:-1], Hl[:, :2, 2:], E[1:])  # vertex k with vertex k + 1
            vt = par.vertex
            adjacent = np.diff(vt) == 1
            off = np.where(adjacent, oV[np.minimum(vt[:-1], n - 1)], 0.0)
            return float(f.sum()), (gV[vt] * par.E).sum(axis=1), (dV[vt], off)
        gX = np.bincount(loc.ravel(), weights=gl.ravel(), minlength=2 * (n + 1))
        r = np.repeat(loc, 4, axis=1).ravel()
        c = np.tile(loc, (1, 4)).ravel()
        HX = sp.csr_matrix((Hl.ravel(), (r, c)), shape=(2 * (n + 1), 2 * (n + 1)))
        M, Mt = par.M, par.M.T.tocsr()
        return float(f.sum()), Mt @ gX, (Mt @ HX @ M).tocsc()

    z = par.pack(X0)
    # the coarse pass only needs the shape of the curve: its lengths are not part of any estimate
    X, converged = _newton(par, unpack, length, assemble, z, scale, max_iter, rtol=1e-11 if polish else 1e-7)
    if converged or not polish:
        return X
    z = par.pack(X)

    # quasi-Newton on the exact gradient: robust where the length has kinks
    f0 = max(length(unpack(z)), 1e-300)

    def fun(zz):
        XX = unpack(par.clip(zz.copy()))
        fl, gl, _ = _segment_derivatives(metric, comps, XX[:-1], XX[1:], step, hessian=False)
        gX = np.bincount(loc.ravel(), weights=gl.ravel(), minlength=2 * (n + 1))
        return float(fl.sum()) / f0, (par.M.T @ gX) / f0

    wide = 10.0 * scale
    bounds = [(float(zk) - wide, float(zk) + wide) for zk in z]
    for kk, lo, hi in par.slides:
        bounds[kk] = (max(lo, bounds[kk][0]), min(hi, bounds[kk][1]))
    res = minimize(fun, z, jac=True, method="L-BFGS-B", bounds=bounds,
                   options={"maxiter": 100, "ftol": 1e-12, "gtol": 1e-14, "maxcor": 30})
    return unpack(par.clip(res.x))


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
    max_rounds: int = 3,
) -> RefinedPath:
    """Refine a grid route into a geodesic: minimize its exact length, multilevel.

    Parameters
    ----------
    domain : Domain
        The pair domain.
    metric : Metric
        The metric on M x M.
    route : (k, 2) ndarray
        Grid route in parameters (unwrapped across seams).
    start_ground, end_ground : int, optional
        Ground (boundary part) on which the first / last point may slide: a
        curve ``gamma`` ending freely on the boundary or the diagonal (eq. (9)).
        ``None``: the end is a fixed crossing point.
    closed : bool, default False
        A closed curve: ``route[-1] - route[0]`` is a period shift and every
        vertex is free.
    tol : float, default 1e-3
        Relative tolerance of the length.
    atol : float, default 0
        Absolute tolerance: a curve much shorter than the others needs no
        relative accuracy of its own.
    start, max_segments : int
        First and largest number of segments.
    max_rounds : int
        Rounds of normal moves per level.

    Returns
    -------
    RefinedPath
    """
    scale = float(max(domain.lengths))
    route = np.asarray(route, dtype=float)
    shift = route[-1] - route[0] if closed else None
    route = _coarse_geodesic(domain, metric, route, start_ground, end_ground, shift, scale, closed)
    X, modes = _initial_polyline(domain, route, start, start_ground, end_ground, closed)
    history = []
    n = start
    def length(X):
        return float(segment_lengths(metric, domain.comps, X[:-1], X[1:]).sum())

    while True:
        # rounds of normal moves, the normals recomputed each time, until the length settles:
        # one round cannot carry a vertex past the centre of curvature of the polyline
        if not closed:
            X, modes = _grade_ends(domain, X, modes, start_ground, end_ground, scale)
        L_prev = length(X)
        for _round in range(max_rounds):
            X = _optimize_level(domain, metric, X, _normal_modes(X, modes, closed), shift, scale)
            X, modes = _insert_breaks(domain, *_prune_breaks(X, modes))
            if end_ground is not None:
                X, modes = _truncate_at_boundary(domain, end_ground, X, modes)
                modes = _corner_switch(domain, metric, X, modes, len(X) - 1)
            if start_ground is not None:
                modes = _corner_switch(domain, metric, X, modes, 0)
            L_new = length(X)
            if L_prev - L_new <= 1e-2 * tol * L_new:
                break
            L_prev = L_new
        Ln = L_new  # the length of the last round's polyline
        history.append(Ln)
        if len(history) >= 2:
            # Richardson: with an error ~ n^-2, L_n - L_inf ~ (L_{n/2} - L_n) / 3.  The estimate is the whole
            # last difference, three times that correction: the first levels are not always asymptotic.
            diff = history[-2] - history[-1]
            estimate = abs(diff)
            if len(history) >= 3:
                # a level that barely moves after one that moved a lot has stalled (a kink it cannot cross),
                # not converged: with an error ~ n^-2 each change is about a quarter of the one before
                estimate = max(estimate, abs(history[-3] - history[-2]) / 4.0)
            # three levels at least: the change between the first two is often not yet in the asymptotic
            # range (measured: 3.8e-3 off at tol 1e-3 after two), and the third checks it through the ratio
            if (estimate <= max(tol * abs(history[-1]), atol) and len(history) >= 3) or n >= max_segments:
                return RefinedPath(X, history[-1] - diff / 3.0, Ln, estimate, len(X) - 1)
        elif Ln == 0.0:
            return RefinedPath(X, 0.0, 0.0, 0.0, len(X) - 1)
        # double: a free midpoint in every segment
        mid = 0.5 * (X[:-1] + X[1:])
        Y = np.empty((2 * len(X) - 1, 2))
        Y[0::2], Y[1::2] = X, mid
        new_modes: list = []
        for k in range(len(X)):
            new_modes.append(modes[k])
            if k < len(X) - 1:
                new_modes.append("free")
        X, modes, n = Y, new_modes, 2 * n
