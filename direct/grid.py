r"""Pair domains of M x M and their metric-weighted grid graphs (section 5.1.1).

For intervals, ``M x M`` minus the diagonal splits into the rectangles
``I_i x I_j`` (``i != j``) and, for each ``i``, the two triangles of
``I_i x I_i`` on either side of the diagonal.  The map
``(x1, x2) -> (x2, x1)`` exchanges ``I_i x I_j`` with ``I_j x I_i`` (and the two
triangles), preserves every metric of :mod:`direct.metric` and flips the sign
of every crossing point, so each optimal family of curves on one half has a
mirror image of the same length on the other: a :class:`Domain` is one half,
``I_i x I_j`` with ``i < j`` or the triangle ``x1 < x2`` of ``I_i x I_i``, and
the penalty is twice the sum over the halves.

The grid graph of a domain has

* a node per grid point strictly inside the domain (uniform steps ``h1, h2``);
* one *ground* node (index 0) for the boundary: the sides of the rectangle
  and, for a triangle, the diagonal, where the curves ``gamma`` may end freely
  (eq. (9));
* a node per crossing point, joined to the grid nodes of its neighbourhood
  and to the other crossing points nearby;
* an edge per stencil move (8 or 16 neighbours) whose weight is the exact
  metric length of the straight segment (:func:`direct.metric.segment_lengths`).
  A move that leaves the domain is cut where it leaves and joined to ground.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from .metric import Metric, segment_lengths

__all__ = ["Domain", "GridGraph", "build_graph", "stencil"]

_TINY = np.finfo(float).tiny


def stencil(neighbours: int) -> np.ndarray:
    """Half of a symmetric stencil: one move of each opposite pair.

    Parameters
    ----------
    neighbours : {4, 8, 16, 32}
        Size of the full stencil.

    Returns
    -------
    (neighbours // 2, 2) ndarray of int
    """
    base = {4: [(1, 0), (0, 1)], 8: [(1, 0), (0, 1), (1, 1), (1, -1)]}
    if neighbours in base:
        return np.array(base[neighbours])
    radius = {16: 2, 32: 3}.get(neighbours)
    if radius is None:
        raise ValueError(f"neighbours must be 4, 8, 16 or 32, got {neighbours!r}")
    moves = [
        (a, b)
        for a in range(0, radius + 1)
        for b in range(-radius, radius + 1)
        if (a > 0 or b > 0) and np.gcd(a, b) == 1
    ]
    return np.array(moves)


@dataclass(frozen=True, eq=False)
class Domain:
    """One half of a connected component of ``M x M \\ Delta`` (see the module docstring).

    Parameters
    ----------
    pair : tuple of int
        Component indices ``(i, j)`` with ``i <= j``.
    comps : tuple of Component
        The two components.
    points : (n, 2) ndarray
        Crossing points ``(x1, x2)`` in this domain (reference arclength).
    signs : (n,) ndarray of int
        Their signs ``s = sign det(phi'(x1), phi'(x2))``.
    crossing_ids : (n,) ndarray of int
        Index of each point's crossing in the scene's crossing list.
    """

    pair: tuple[int, int]
    comps: tuple
    points: np.ndarray
    signs: np.ndarray
    crossing_ids: np.ndarray

    @property
    def is_triangle(self) -> bool:
        """True for the half ``x1 < x2`` of ``I_i x I_i``."""
        return self.pair[0] == self.pair[1]

    @property
    def lengths(self) -> tuple[float, float]:
        """Side lengths ``(L_i, L_j)`` in reference arclength."""
        return (self.comps[0].length, self.comps[1].length)

    def exit_time(self, p: np.ndarray, d: np.ndarray) -> np.ndarray:
        """First ``t >= 0`` at which ``p + t d`` reaches the boundary (inf if never).

        Parameters
        ----------
        p, d : (m, 2) ndarray
            Start points inside the domain and directions.
        """
        L = np.array(self.lengths)
        with np.errstate(divide="ignore", invalid="ignore"):
            up = np.where(d > 0, (L - p) / d, np.inf)
            down = np.where(d < 0, -p / d, np.inf)
            t = np.minimum(up, down).min(axis=1)
            if self.is_triangle:
                dd = d[:, 1] - d[:, 0]
                t = np.minimum(t, np.where(dd < 0, (p[:, 1] - p[:, 0]) / -dd, np.inf))
        return np.maximum(t, 0.0)

    def boundary_distance(self, p: np.ndarray) -> np.ndarray:
        """Euclidean distance in parameter space from points to the boundary."""
        L = np.array(self.lengths)
        dist = np.minimum(p, L - p).min(axis=1)
        if self.is_triangle:
            dist = np.minimum(dist, (p[:, 1] - p[:, 0]) / np.sqrt(2))
        return dist


@dataclass(eq=False)
class GridGraph:
    """The metric-weighted grid graph of a :class:`Domain`.

    Attributes
    ----------
    domain : Domain
    h : (2,) ndarray
        Grid steps along ``x1`` and ``x2`` (reference arclength).
    coords : (n_nodes, 2) ndarray
        Parameter coordinates of every node; row 0 (ground) is NaN.
    crossing_nodes : (n_points,) ndarray of int
        Node of each crossing point of the domain.
    exit_points : (n_nodes, 2) ndarray
        For a node joined to ground, where its cheapest ground edge meets the
        boundary (NaN otherwise).
    matrix : scipy.sparse.csr_matrix
        Symmetric weighted adjacency matrix (upper triangle stored).
    """

    domain: Domain
    h: np.ndarray
    coords: np.ndarray
    crossing_nodes: np.ndarray
    exit_points: np.ndarray
    rows: np.ndarray
    cols: np.ndarray
    weights: np.ndarray
    neighbours: int
    metric: Metric
    shape: tuple[int, int] = field(default=(0, 0))

    @property
    def n_nodes(self) -> int:
        """Number of nodes, ground included."""
        return len(self.coords)

    @cached_property
    def matrix(self) -> sp.csr_matrix:
        """Weighted adjacency matrix for :func:`scipy.sparse.csgraph.dijkstra` (``directed=False``)."""
        return sp.csr_matrix((self.weights, (self.rows, self.cols)), shape=(self.n_nodes, self.n_nodes))

    def node_path(self, nodes: list[int] | np.ndarray, end_on_ground: bool) -> np.ndarray:
        """Parameter-space polyline of a node path (ground replaced by its exit point)."""
        nodes = [int(v) for v in nodes]
        pts = [self.coords[v] for v in nodes if v != 0]
        if end_on_ground:
            pts.append(self.exit_points[nodes[-2] if nodes[-1] == 0 else nodes[0]])
        return np.array(pts)


def _dedupe_min(r: np.ndarray, c: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Keep the lightest of parallel edges (sparse matrices would add them up)."""
    a, b = np.minimum(r, c), np.maximum(r, c)
    order = np.lexsort((w, b, a))
    a, b, w = a[order], b[order], w[order]
    first = np.ones(len(a), dtype=bool)
    first[1:] = (a[1:] != a[:-1]) | (b[1:] != b[:-1])
    return a[first], b[first], w[first], order[first]


def build_graph(domain: Domain, metric: Metric, resolution: int = 96, neighbours: int = 16, window: int = 2) -> GridGraph:
    """Build the grid graph of a domain.

    Parameters
    ----------
    domain : Domain
        The pair domain with its crossing points.
    metric : Metric
        Gives the exact edge weights.
    resolution : int, default 96
        Number of grid cells along the longer side of the domain.
    neighbours : {8, 16, 32}, default 16
        Stencil of the grid moves.
    window : int, default 2
        A crossing point is joined to the grid nodes within ``window`` cells.

    Returns
    -------
    GridGraph
    """
    L1, L2 = domain.lengths
    if domain.is_triangle:
        n1 = n2 = max(int(resolution), 3)
    else:
        h0 = max(L1, L2) / max(int(resolution), 2)
        n1, n2 = max(int(np.ceil(L1 / h0)), 2), max(int(np.ceil(L2 / h0)), 2)
    h = np.array([L1 / n1, L2 / n2])
    # interior grid nodes, numbered from 1 (0 is ground)
    I, J = np.meshgrid(np.arange(1, n1), np.arange(1, n2), indexing="ij")
    inside = np.ones_like(I, dtype=bool)
    if domain.is_triangle:
        inside = J > I
    ii, jj = I[inside], J[inside]
    node_of = np.full((n1 + 1, n2 + 1), -1, dtype=np.int64)
    node_of[ii, jj] = np.arange(1, len(ii) + 1)
    grid_xy = np.column_stack([ii * h[0], jj * h[1]])
    n_grid = len(ii)
    pts = np.asarray(domain.points, dtype=float).reshape(-1, 2)
    n_pts = len(pts)
    cross_nodes = np.arange(n_grid + 1, n_grid + 1 + n_pts)
    coords = np.vstack([np.full((1, 2), np.nan), grid_xy, pts])

    P_list, Q_list, A_list, B_list, ground_list = [], [], [], [], []

    def add(p_idx, q_idx, P, Q, ground):
        A_list.append(p_idx)
        B_list.append(q_idx)
        P_list.append(P)
        Q_list.append(Q)
        ground_list.append(ground)

    half = stencil(neighbours)
    full = np.vstack([half, -half])
    src = np.arange(1, n_grid + 1)
    for k, (di, dj) in enumerate(full):
        ti, tj = ii + di, jj + dj
        ok = (ti >= 0) & (ti <= n1) & (tj >= 0) & (tj <= n2)
        q = np.full(n_grid, -1, dtype=np.int64)
        q[ok] = node_of[ti[ok], tj[ok]]
        interior = q > 0
        if k < len(half):  # each interior edge once
            add(src[interior], q[interior], grid_xy[interior], coords[q[interior]], False)
        out = ~interior
        if out.any():
            p = grid_xy[out]
            d = np.broadcast_to(np.array([di, dj]) * h, p.shape)
            t = np.minimum(domain.exit_time(p, d), 1.0)
            add(src[out], np.zeros(out.sum(), dtype=np.int64), p, p + t[:, None] * d, True)

    if n_pts:
        # crossing points: to grid nodes within the window, or to ground where the move leaves
        ci = np.floor(pts[:, 0] / h[0]).astype(int)
        cj = np.floor(pts[:, 1] / h[1]).astype(int)
        offs = np.arange(-window + 1, window + 1)
        oi, oj = np.meshgrid(offs, offs, indexing="ij")
        ti = (ci[:, None] + oi.ravel()[None, :]).ravel()
        tj = (cj[:, None] + oj.ravel()[None, :]).ravel()
        owner = np.repeat(np.arange(n_pts), oi.size)
        ok = (ti >= 0) & (ti <= n1) & (tj >= 0) & (tj <= n2)
        q = np.full(len(ti), -1, dtype=np.int64)
        q[ok] = node_of[ti[ok], tj[ok]]
        interior = q > 0
        add(cross_nodes[owner[interior]], q[interior], pts[owner[interior]], coords[q[interior]], False)
        # straight moves to ground: towards each window node outside, and along the axes / to the diagonal
        target = np.column_stack([ti * h[0], tj * h[1]])[~interior]
        p = pts[owner[~interior]]
        dirs = [target - p]
        starts = [p]
        axes = np.array([[1, 0], [-1, 0], [0, 1], [0, -1], [1, -1]], dtype=float)
        for ax in axes:
            if ax[0] == 1 and ax[1] == -1 and not domain.is_triangle:
                continue
            starts.append(pts)
            dirs.append(np.broadcast_to(ax, pts.shape))
        p = np.vstack(starts)
        d = np.vstack(dirs)
        own = np.concatenate([owner[~interior]] + [np.arange(n_pts)] * (len(starts) - 1))
        t = domain.exit_time(p, d)
        good = np.isfinite(t)
        add(cross_nodes[own[good]], np.zeros(good.sum(), dtype=np.int64), p[good], p[good] + t[good, None] * d[good], True)
        # crossing point to crossing point when close
        if n_pts > 1:
            a, b = np.triu_indices(n_pts, 1)
            near = (np.abs(pts[a] - pts[b]) <= window * h).all(axis=1)
            add(cross_nodes[a[near]], cross_nodes[b[near]], pts[a[near]], pts[b[near]], False)

    A = np.concatenate(A_list)
    B = np.concatenate(B_list)
    P = np.vstack(P_list)
    Q = np.vstack(Q_list)
    ground = np.concatenate([np.full(len(x), gflag) for x, gflag in zip(A_list, ground_list)])
    w = np.maximum(segment_lengths(metric, domain.comps, P, Q), _TINY)
    r, c, w, kept = _dedupe_min(A, B, w)
    exit_points = np.full((len(coords), 2), np.nan)
    g = ground[kept]
    exit_points[c[g]] = Q[kept][g]  # ground is node 0, so it is the row of a ground edge
    return GridGraph(
        domain=domain,
        h=h,
        coords=coords,
        crossing_nodes=cross_nodes,
        exit_points=exit_points,
        rows=r,
        cols=c,
        weights=w,
        neighbours=neighbours,
        metric=metric,
        shape=(n1, n2),
    )
