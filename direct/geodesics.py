r"""Geodesic distances in a pair domain: grid Dijkstra, then continuous refinement.

Two stages (section 5.1.1 computes the matrix ``A`` of eq. (34) from
geodesic distances):

1. **Grid Dijkstra** (:func:`grid_distances`) on the graph of
   :func:`direct.grid.build_graph`, with :func:`scipy.sparse.csgraph.dijkstra`
   or, as an independent cross-check, :mod:`networkx`.  It gives every
   distance between crossing points and from each crossing point to the
   boundary, and the route of each geodesic.  Grid distances are lengths of
   real curves, so they are upper bounds, but they keep a metrication bias
   that refinement of the grid never removes (up to 2.75 % with 16
   neighbours, see ``shared/NUMERICS.md``).
2. **Continuous refinement** (:func:`refine`): each route is resampled as a
   polyline with ``n`` segments whose interior vertices (and free end on the
   boundary) minimize the exact metric length, by L-BFGS-B with a gradient by
   central differences (each vertex moves only its two segments, so all
   partial derivatives come from one vectorized length evaluation).  ``n``
   doubles until Richardson extrapolation (error ``~ n^-2``) changes the
   length by less than the tolerance.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.optimize import minimize
from scipy.sparse.csgraph import dijkstra

from .grid import Domain, GridGraph
from .metric import Metric, segment_lengths

__all__ = ["grid_distances", "refine", "RefinedPath", "Backend"]

Backend = Literal["scipy", "networkx"]


def _networkx_paths(graph: GridGraph, sources: np.ndarray) -> tuple[np.ndarray, list[dict]]:
    import networkx as nx

    G = nx.Graph()
    G.add_weighted_edges_from(zip(graph.rows.tolist(), graph.cols.tolist(), graph.weights.tolist()))
    dist = np.full((len(sources), graph.n_nodes), np.inf)
    paths = []
    for k, s in enumerate(sources):
        d, p = nx.single_source_dijkstra(G, int(s), weight="weight")
        dist[k, list(d.keys())] = list(d.values())
        paths.append(p)
    return dist, paths


def grid_distances(graph: GridGraph, backend: Backend = "scipy") -> tuple[np.ndarray, np.ndarray, list]:
    """Grid distances between the crossing points of a domain, and to its boundary.

    Parameters
    ----------
    graph : GridGraph
        From :func:`direct.grid.build_graph`.
    backend : {"scipy", "networkx"}
        ``scipy.sparse.csgraph.dijkstra`` (default), or networkx's Dijkstra
        as an independent implementation.

    Returns
    -------
    D : (n, n) ndarray
        ``D[a, b]`` grid distance between crossing points ``a`` and ``b``.
    D0 : (n,) ndarray
        Grid distance from each crossing point to the boundary (ground).
    routes : list of callables
        ``routes[a](target)`` gives the node path from point ``a`` to node ``target``.
    """
    src = graph.crossing_nodes
    if backend == "scipy":
        dist, pred = dijkstra(graph.matrix, directed=False, indices=src, return_predecessors=True)

        def route(k):
            def path(target):
                out = [int(target)]
                while out[-1] != src[k]:
                    out.append(int(pred[k, out[-1]]))
                return out[::-1]

            return path

        routes = [route(k) for k in range(len(src))]
    elif backend == "networkx":
        dist, paths = _networkx_paths(graph, src)
        routes = [(lambda p: (lambda target: p[int(target)]))(p) for p in paths]
    else:
        raise ValueError(f"backend must be 'scipy' or 'networkx', got {backend!r}")
    return dist[:, src], dist[:, 0], routes


@dataclass(frozen=True)
class RefinedPath:
    """A refined geodesic: its polyline, length, and convergence record.

    Attributes
    ----------
    points : (n + 1, 2) ndarray
        Vertices in parameter space ``(x1, x2)`` (reference arclength).
    length : float
        Richardson-extrapolated length.
    upper : float
        Exact length of ``points`` (a real curve: an upper bound of the distance).
    error_estimate : float
        ``|L_n - L_{n/2}| / 3``, the Richardson correction applied.
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


def _end_side(domain: Domain, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, tuple[float, float]]:
    """The boundary side that holds ``q``: base point, unit direction and the range of the slide."""
    L1, L2 = domain.lengths
    cands = [
        (abs(q[0]), np.array([0.0, 0.0]), np.array([0.0, 1.0]), (0.0, L2)),
        (abs(q[0] - L1), np.array([L1, 0.0]), np.array([0.0, 1.0]), (0.0, L2)),
        (abs(q[1]), np.array([0.0, 0.0]), np.array([1.0, 0.0]), (0.0, L1)),
        (abs(q[1] - L2), np.array([0.0, L2]), np.array([1.0, 0.0]), (0.0, L1)),
    ]
    if domain.is_triangle:
        cands.append((abs(q[1] - q[0]) / np.sqrt(2), np.array([0.0, 0.0]), np.array([1.0, 1.0]) / np.sqrt(2),
                      (0.0, L1 * np.sqrt(2))))
    _, base, direction, rng = min(cands, key=lambda c: c[0])
    return base, direction, rng


_E4 = np.eye(4)
# second-difference stencils of a function of the 4 end coordinates (P1, P2, Q1, Q2) of a segment
_PAIRS = [(a, b) for a in range(4) for b in range(a + 1, 4)]
_OFFSETS = np.vstack(
    [_E4, -_E4]
    + [np.array([s * _E4[a] + t * _E4[b] for s, t in ((1, 1), (1, -1), (-1, 1), (-1, -1))]) for a, b in _PAIRS]
)


def _segment_derivatives(metric: Metric, comps, P: np.ndarray, Q: np.ndarray, step: float, hessian: bool = True):
    """Length, gradient (m, 4) and Hessian (m, 4, 4) of each segment in its end coordinates.

    Central differences with step ``step`` (the lengths themselves are exact).
    """
    m = len(P)
    U = np.hstack([P, Q])
    offsets = _OFFSETS if hessian else _OFFSETS[:8]
    Us = np.vstack([U] + [U + step * o for o in offsets])
    f = segment_lengths(metric, comps, Us[:, :2], Us[:, 2:]).reshape(len(offsets) + 1, m)
    f0, fp, fm = f[0], f[1:5], f[5:9]
    grad = ((fp - fm) / (2 * step)).T
    if not hessian:
        return f0, grad, None
    H = np.empty((m, 4, 4))
    diag = (fp - 2 * f0 + fm) / step**2
    H[:, np.arange(4), np.arange(4)] = diag.T
    for k, (a, b) in enumerate(_PAIRS):
        q = f[9 + 4 * k : 13 + 4 * k]
        hab = (q[0] - q[1] - q[2] + q[3]) / (4 * step**2)
        H[:, a, b] = H[:, b, a] = hab
    return f0, grad, H


def _project(domain: Domain, X: np.ndarray) -> np.ndarray:
    """Put polyline vertices back into the closed domain."""
    L = np.array(domain.lengths)
    X = np.clip(X, 0.0, L)
    if domain.is_triangle:
        low = X[:, 1] < X[:, 0]
        X[low] = 0.5 * (X[low, 0] + X[low, 1])[:, None]
    return X


def _optimize_level(domain: Domain, metric: Metric, X0: np.ndarray, free_end: bool, side, scale: float,
                    max_iter: int = 60, polish: bool = True) -> np.ndarray:
    """Minimize the exact length over the interior vertices (and the slide of a free end).

    Damped Newton: the Hessian of the length is block tridiagonal (vertex
    ``k`` moves segments ``k - 1`` and ``k`` only), assembled from the
    finite-difference Hessians of the segments and solved as a banded system.
    """
    from scipy.linalg import solveh_banded

    comps = domain.comps
    n = len(X0) - 1
    nv = 2 * (n - 1) + (1 if free_end else 0)
    if nv == 0:
        return X0
    direction = side[1] if free_end else None
    base = side[0] if free_end else None
    lo, hi = side[2] if free_end else (0.0, 0.0)
    step = 1e-5 * scale
    # map from the local coordinates (P1, P2, Q1, Q2) of each segment to the unknowns
    idx = np.full((n, 4), -1)
    k = np.arange(1, n)
    idx[k - 1, 2], idx[k - 1, 3] = 2 * (k - 1), 2 * (k - 1) + 1  # vertex k ends segment k - 1
    idx[k, 0], idx[k, 1] = 2 * (k - 1), 2 * (k - 1) + 1  # and starts segment k

    def assemble(X):
        f, gl, Hl = _segment_derivatives(metric, comps, X[:-1], X[1:], step)
        Jl = np.zeros((n, 4))  # weights when a local coordinate is the slide of the free end
        if free_end:
            # Q of the last segment = base + tau * direction
            gl[-1, 2] = gl[-1, 2] * direction[0] + gl[-1, 3] * direction[1]
            Hq = Hl[-1]
            J = np.array([[1, 0, 0], [0, 1, 0], [0, 0, direction[0]], [0, 0, direction[1]]], dtype=float)
            H3 = J.T @ Hq @ J
            Hl[-1] = 0.0
            Hl[-1, :3, :3] = H3
            gl[-1, 3] = 0.0
            Jl[-1, 2] = 1.0
        loc = idx.copy()
        if free_end:
            loc[-1, 2], loc[-1, 3] = nv - 1, -1
        grad = np.zeros(nv)
        valid = loc >= 0
        np.add.at(grad, loc[valid], gl[valid])
        # banded Hessian (upper form for solveh_banded): ab[u + i - j, j] = H[i, j]
        u = 3
        ab = np.zeros((u + 1, nv))
        a_idx, b_idx = np.meshgrid(np.arange(4), np.arange(4), indexing="ij")
        rows = loc[:, a_idx]
        cols = loc[:, b_idx]
        ok = (rows >= 0) & (cols >= 0) & (rows <= cols)
        np.add.at(ab, (u + rows[ok] - cols[ok], cols[ok]), Hl[:, a_idx, b_idx][ok])
        return float(f.sum()), grad, ab

    def unpack(z):
        X = X0.copy()
        X[1:n] = z[: 2 * (n - 1)].reshape(-1, 2)
        if free_end:
            X[n] = base + z[-1] * direction
        X[1:n] = _project(domain, X[1:n])
        return X

    def pack(X):
        z = X[1:n].ravel()
        if free_end:
            z = np.append(z, np.clip(float(np.dot(X[n] - base, direction)), lo, hi))
        return z

    def _polish(X):
        # quasi-Newton from the Newton point: robust where the length is not smooth (degenerate norms)
        def fun(zz):
            XX = unpack(zz)
            f0, gl, _ = _segment_derivatives(metric, comps, XX[:-1], XX[1:], step * 1e-2, hessian=False)
            if free_end:
                gl[-1, 2] = gl[-1, 2] * direction[0] + gl[-1, 3] * direction[1]
                gl[-1, 3] = 0.0
            loc = idx.copy()
            if free_end:
                loc[-1, 2], loc[-1, 3] = nv - 1, -1
            g = np.zeros(nv)
            valid = loc >= 0
            np.add.at(g, loc[valid], gl[valid])
            return float(f0.sum()), g

        L = np.array(domain.lengths)
        bounds = [(0.0, L[0]), (0.0, L[1])] * (n - 1) + ([(lo, hi)] if free_end else [])
        res = minimize(fun, pack(X), jac=True, method="L-BFGS-B", bounds=bounds,
                       options={"maxiter": 500, "ftol": 1e-15, "gtol": 0.0})
        Xp = unpack(res.x)
        return Xp if res.fun < float(segment_lengths(metric, comps, X[:-1], X[1:]).sum()) else X

    z = pack(X0)
    X = unpack(z)
    f, grad, ab = assemble(X)
    lam = 1e-8
    for _ in range(max_iter):
        scale_h = max(np.abs(ab[-1]).max(), 1e-300)
        while True:
            abd = ab.copy()
            abd[-1] += lam * scale_h
            try:
                dz = -solveh_banded(abd, grad)
                break
            except np.linalg.LinAlgError:
                lam = max(lam * 100, 1e-6)
        t = 1.0
        accepted = False
        for _ls in range(30):
            z_new = z + t * dz
            if free_end:
                z_new[-1] = np.clip(z_new[-1], lo, hi)
            X_new = unpack(z_new)
            f_new = float(segment_lengths(metric, comps, X_new[:-1], X_new[1:]).sum())
            if f_new <= f:
                accepted = True
                break
            t *= 0.5
        if not accepted:
            lam *= 100
            if lam > 1e8:
                break
            continue
        z = pack(X_new)
        done = f - f_new <= 1e-15 * max(f, 1e-300) or np.abs(t * dz).max() <= 1e-13 * scale
        X, f = X_new, f_new
        lam = max(lam / 10, 1e-12)
        if done:
            break
        _, grad, ab = assemble(X)
    if polish:
        X = _polish(X)
    return X


def refine(
    domain: Domain,
    metric: Metric,
    route: np.ndarray,
    free_end: bool,
    tol: float = 1e-3,
    start: int = 8,
    max_segments: int = 512,
) -> RefinedPath:
    """Refine a grid route into a geodesic: minimize its exact length, multilevel.

    Parameters
    ----------
    domain : Domain
        The pair domain.
    metric : Metric
        The metric on M x M.
    route : (k, 2) ndarray
        Grid route in parameter space; its first point is a crossing point,
        its last a crossing point or, with ``free_end``, a boundary point.
    free_end : bool
        True when the last point may slide along its boundary side (a curve
        ``gamma`` ending freely on the boundary or the diagonal, eq. (9)).
    tol : float, default 1e-3
        Relative tolerance of the length.
    start, max_segments : int
        First and largest number of segments.

    Returns
    -------
    RefinedPath
    """
    scale = float(max(domain.lengths))
    side = _end_side(domain, route[-1]) if free_end else None
    X = _resample(route, start)
    history = []
    n = start
    while True:
        X = _optimize_level(domain, metric, X, free_end, side, scale)
        Ln = float(segment_lengths(metric, domain.comps, X[:-1], X[1:]).sum())
        history.append(Ln)
        if len(history) >= 2:
            corr = (history[-2] - history[-1]) / 3.0
            if abs(corr) <= tol * abs(history[-1]) or n >= max_segments:
                return RefinedPath(X, history[-1] - corr, Ln, abs(corr), n)
        elif Ln == 0.0:
            return RefinedPath(X, 0.0, 0.0, 0.0, n)
        # double: insert midpoints
        mid = 0.5 * (X[:-1] + X[1:])
        Y = np.empty((2 * n + 1, 2))
        Y[0::2], Y[1::2] = X, mid
        X, n = Y, 2 * n
