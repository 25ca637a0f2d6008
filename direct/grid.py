r"""Pair domains of M x M and their metric-weighted grid graphs (section 5.1.1).

``M x M`` minus the diagonal splits into one connected piece per ordered pair
of components.  The map ``(x1, x2) -> (x2, x1)`` exchanges ``M_i x M_j`` with
``M_j x M_i``, preserves every metric of :mod:`direct.metric` and flips the
sign of every crossing point, so an optimal family on one piece has a mirror
image of the same length on the other.  A :class:`Domain` is therefore taken
for ``i <= j`` only and counted twice, except ``S^1 x S^1 \ Delta`` (a circle
with itself), which the map sends to itself.  The five kinds:

=============  ===============================  ==================  ===============================
kind           piece                            counted             boundary (where gamma ends)
=============  ===============================  ==================  ===============================
``rect``       ``I_i x I_j``                    twice               the four sides: one ground
``triangle``   ``{x1 < x2}`` of ``I_i x I_i``   twice (two halves)  sides and diagonal: one ground
``cylinder``   ``S^1 x I`` (or ``I x S^1``)     twice               the two end circles: grounds 0, 1
``annulus``    ``S^1 x S^1 \ Delta``            once                the two sides of the diagonal: 0, 1
``torus``      ``S^1_i x S^1_j``                twice               none
=============  ===============================  ==================  ===============================

Each domain has *local* coordinates ``(s, v)``, ``s`` along the circle when
there is one (periodic), in which it is the rectangle ``[0, S] x [0, V]``;
parameters are ``(x1, x2) = s e_s + v e_v``.  For the annulus ``x1 = s``,
``x2 = s + v`` with ``0 < v < L``: ``v -> 0`` is the side ``x2 > x1`` of the
diagonal (``B_0^-`` of section 3.3.3), ``v -> L`` the other side.

The grid graph of a domain has

* a node per grid point strictly inside (uniform steps in the grid coordinate
  of ``(s, v)``), or with ``coarsen > 1`` (local refinement) only the
  points of a lattice ``coarsen`` times coarser, plus every grid point in a
  patch around each crossing point and on the coarse cells where ``rho``
  varies by more than a factor ``ratio``;
* a *ground* node per boundary part (indices ``0 .. n_grounds - 1``);
* a node per crossing point, joined to the grid nodes of its neighbourhood,
  to the crossing points nearby, and to the boundary by straight moves
  along the local axes and, in a rectangle or triangle, along the four
  diagonals in deformed arclength (one of them follows the valley of
  ``rho`` out of the point);
* an edge per stencil move (8, 16 or 32 neighbours, moves of the parameters
  ``(x1, x2)``: on the annulus the move ``(a, b)`` is ``(a, b - a)`` in
  ``(s, v)``, see :func:`_local_stencil`; scaled by ``coarsen``
  between the nodes of the coarse lattice) whose weight is the exact
  metric length of the straight segment (:func:`direct.metric.segment_lengths`).
  A move that leaves the domain is cut where it leaves and joined to that
  ground.  On periodic axes moves wrap around; each edge records how many
  times it crosses the seams ``s = 0`` and (torus) ``v = 0``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import scipy.sparse as sp
from scipy.ndimage import maximum_filter

from .errors import DirectError
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


def _local_stencil(domain: "Domain", neighbours: int) -> np.ndarray:
    """The stencil's moves in a domain's local grid indices: the moves of :func:`stencil` in the parameters.

    The grid of an annulus is uniform in its local coordinates ``(s, v)``,
    ``(x1, x2) = s (1, 1) + v (0, 1)``, with the same step on both axes: its
    nodes are the square lattice of the parameters, and the move ``(a, b)``
    of the parameters is ``(a, b - a)`` in ``(s, v)``.  Taken in ``(s, v)``
    as they stand, the 16 moves would leave gaps of 45 degrees in the
    parameters (on either side of ``(-1, 1)``) and a bias of up to
    8.2 % instead of 2.75 % (8 moves: 90 degrees, 41 %): a figure eight whose geodesics run in that
    gap had its grid pick a local geodesic 6.7 % longer than the shortest,
    whatever the resolution (``tests/test_circles.py``).
    """
    half = stencil(neighbours)
    if domain.kind == "annulus":
        return np.column_stack([half[:, 0], half[:, 1] - half[:, 0]])
    return half


def _apply(B: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``x @ B.T`` for a 2 x 2 change of coordinates, without a BLAS call (slow for tiny inner sizes)."""
    out = np.empty_like(x)
    out[:, 0] = B[0, 0] * x[:, 0] + B[0, 1] * x[:, 1]
    out[:, 1] = B[1, 0] * x[:, 0] + B[1, 1] * x[:, 1]
    return out


@dataclass(frozen=True, eq=False)
class Domain:
    r"""One piece of ``M x M \ Delta`` with its crossing points (see the module docstring).

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

    @cached_property
    def kind(self) -> str:
        """One of ``rect``, ``triangle``, ``cylinder``, ``annulus``, ``torus``."""
        c1, c2 = (c.closed for c in self.comps)
        if self.pair[0] == self.pair[1]:
            return "annulus" if c1 else "triangle"
        if c1 and c2:
            return "torus"
        return "cylinder" if (c1 or c2) else "rect"

    @property
    def is_triangle(self) -> bool:
        """True for the half ``x1 < x2`` of ``I_i x I_i``."""
        return self.kind == "triangle"

    @property
    def multiplicity(self) -> int:
        """How many pieces of ``M x M`` this domain stands for (2 with its mirror image, 1 for the annulus)."""
        return 1 if self.kind == "annulus" else 2

    @property
    def lengths(self) -> tuple[float, float]:
        """Parameter lengths ``(L_i, L_j)`` in reference arclength."""
        return (self.comps[0].length, self.comps[1].length)

    @cached_property
    def basis(self) -> np.ndarray:
        """2 x 2 matrix whose columns ``e_s, e_v`` give ``(x1, x2) = s e_s + v e_v``."""
        if self.kind == "annulus":
            return np.array([[1.0, 0.0], [1.0, 1.0]])
        if self.kind == "cylinder" and not self.comps[0].closed:
            return np.array([[0.0, 1.0], [1.0, 0.0]])  # s runs along the circle x2
        return np.eye(2)

    @cached_property
    def _identity(self) -> bool:
        """Local coordinates are the parameters themselves (rectangle, triangle, torus, cylinder along ``x1``)."""
        return bool((self.basis == np.eye(2)).all())

    @cached_property
    def _inverse_basis(self) -> np.ndarray:
        return np.linalg.inv(self.basis)

    @cached_property
    def local_lengths(self) -> tuple[float, float]:
        """``(S, V)``: the domain is ``[0, S] x [0, V]`` in local coordinates."""
        L1, L2 = self.lengths
        if self.kind == "cylinder" and not self.comps[0].closed:
            return (L2, L1)
        return (L1, L2)

    @cached_property
    def periodic(self) -> tuple[bool, bool]:
        """Whether ``s`` and ``v`` are periodic."""
        k = self.kind
        return (k in ("cylinder", "annulus", "torus"), k == "torus")

    @property
    def n_grounds(self) -> int:
        """Number of boundary parts (ground nodes)."""
        return {"rect": 1, "triangle": 1, "cylinder": 2, "annulus": 2, "torus": 0}[self.kind]

    def to_local(self, x: np.ndarray, wrap: bool = True) -> np.ndarray:
        """Local coordinates ``(s, v)`` of parameters ``(x1, x2)``; periodic ones wrapped into ``[0, S)``."""
        x = np.asarray(x, dtype=float).reshape(-1, 2)
        st = x.copy() if self._identity else _apply(self._inverse_basis, x)
        if wrap:
            S, V = self.local_lengths
            ps, pv = self.periodic
            if ps:
                st[:, 0] = np.mod(st[:, 0], S)
            if pv or self.kind == "annulus":
                st[:, 1] = np.mod(st[:, 1], V)
        return st

    def to_param(self, st: np.ndarray) -> np.ndarray:
        """Parameters ``(x1, x2)`` of local coordinates (not wrapped)."""
        st = np.asarray(st, dtype=float).reshape(-1, 2)
        return st.copy() if self._identity else _apply(self.basis, st)

    def exit_time(self, p: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """First ``t >= 0`` at which ``p + t d`` (local coordinates) reaches the boundary, and which ground.

        Returns ``inf`` where it never does (periodic directions).
        """
        S, V = self.local_lengths
        ps, pv = self.periodic
        n = len(p)
        t = np.full(n, np.inf)
        which = np.zeros(n, dtype=np.int64)
        with np.errstate(divide="ignore", invalid="ignore"):
            if not ps:
                t = np.minimum(t, np.where(d[:, 0] > 0, (S - p[:, 0]) / d[:, 0], np.inf))
                t = np.minimum(t, np.where(d[:, 0] < 0, -p[:, 0] / d[:, 0], np.inf))
            if not pv:
                up = np.where(d[:, 1] > 0, (V - p[:, 1]) / d[:, 1], np.inf)
                down = np.where(d[:, 1] < 0, -p[:, 1] / d[:, 1], np.inf)
                if self.n_grounds == 2:
                    which = np.where(up < np.minimum(down, t), 1, 0)
                t = np.minimum(t, np.minimum(up, down))
            if self.kind == "triangle":
                dd = d[:, 1] - d[:, 0]
                t = np.minimum(t, np.where(dd < 0, (p[:, 1] - p[:, 0]) / -dd, np.inf))
        return np.maximum(t, 0.0), which

    def boundary_distance(self, p: np.ndarray) -> np.ndarray:
        """Euclidean distance in local coordinates from points to the boundary (inf on the torus)."""
        S, V = self.local_lengths
        ps, pv = self.periodic
        dist = np.full(len(p), np.inf)
        if not ps:
            dist = np.minimum(dist, np.minimum(p[:, 0], S - p[:, 0]))
        if not pv:
            dist = np.minimum(dist, np.minimum(p[:, 1], V - p[:, 1]))
        if self.kind == "triangle":
            dist = np.minimum(dist, (p[:, 1] - p[:, 0]) / np.sqrt(2))
        return dist


@dataclass(eq=False)
class GridGraph:
    """The metric-weighted grid graph of a :class:`Domain`.

    Attributes
    ----------
    domain : Domain
    h : (2,) ndarray
        Mean grid steps along ``s`` and ``v`` (reference arclength; for ``G`` the steps are uniform in
        deformed arclength instead, see :func:`_grid_coordinate`).
    coords : (n_nodes, 2) ndarray
        Local coordinates of every node; ground rows are NaN.
    crossing_nodes : (n_points,) ndarray of int
        Node of each crossing point of the domain.
    exit_points : (n_nodes, 2) ndarray
        For a node joined to a ground, where its cheapest edge to that ground
        meets the boundary, in local coordinates, per ground (NaN otherwise):
        shape ``(n_grounds, n_nodes, 2)``.
    exit_bends : dict
        ``(ground, node) -> (k, 2) ndarray``: where the chosen edge from a
        crossing point to the boundary bends on its way (a valley of ``rho``
        followed across vertex lines, see :func:`_valley_rays`), from the
        node to the exit, in local coordinates.  Straight edges are absent.
    rows, cols, weights : ndarray
        The edges (``rows < cols``) and their exact metric lengths.
    winds : (n_edges, 2) ndarray of int
        Signed number of times each edge, taken from ``rows`` to ``cols``,
        crosses the seams ``s = 0`` and ``v = 0`` of periodic axes.
    shape : tuple of int
        Number of grid cells along ``s`` and ``v`` (of the fine lattice).
    coarsen : int
        Step of the coarse lattice in fine cells (1: a uniform grid; see :func:`build_graph`).
    ticks : tuple of two ndarrays
        Positions of the fine lattice lines along ``s`` and ``v`` (local coordinates, ``shape[k] + 1`` each):
        grid node ``(i, j)`` sits at ``(ticks[0][i], ticks[1][j])``.
    """

    domain: Domain
    h: np.ndarray
    coords: np.ndarray
    crossing_nodes: np.ndarray
    exit_points: np.ndarray
    rows: np.ndarray
    cols: np.ndarray
    weights: np.ndarray
    winds: np.ndarray
    neighbours: int
    metric: Metric
    shape: tuple[int, int] = field(default=(0, 0))
    coarsen: int = 1
    ticks: tuple = (np.zeros(0), np.zeros(0))
    exit_bends: dict = field(default_factory=dict)

    @property
    def cell(self) -> np.ndarray:
        """Largest fine cell sides along ``s`` and ``v`` (local coordinates)."""
        return np.array([np.diff(t).max() for t in self.ticks])

    @property
    def n_nodes(self) -> int:
        """Number of nodes, grounds included."""
        return len(self.coords)

    @property
    def n_grounds(self) -> int:
        """Number of ground nodes (they come first)."""
        return self.domain.n_grounds

    @cached_property
    def matrix(self) -> sp.csr_matrix:
        """Directed weighted adjacency matrix for :func:`scipy.sparse.csgraph.dijkstra`.

        Ground ``g`` is split in two so that no path runs *through* the
        boundary: node ``g`` only receives (a curve ending on that boundary)
        and node ``n_nodes + g`` only emits (a curve starting there).
        """
        ng = self.n_grounds
        r, c, w = self.rows, self.cols, self.weights
        to_ground = r < ng  # rows < cols, so a ground is always the row
        inner = ~to_ground
        rows = np.concatenate([r[inner], c[inner], c[to_ground], self.n_nodes + r[to_ground]])
        cols = np.concatenate([c[inner], r[inner], r[to_ground], c[to_ground]])
        data = np.concatenate([w[inner], w[inner], w[to_ground], w[to_ground]])
        n = self.n_nodes + ng
        return sp.csr_matrix((data, (rows, cols)), shape=(n, n))

    @property
    def sources(self) -> np.ndarray:
        """Start node of each terminal: the emitting copy of each ground, then the crossing points."""
        return np.concatenate([self.n_nodes + np.arange(self.n_grounds), self.crossing_nodes])

    @property
    def targets(self) -> np.ndarray:
        """End node of each terminal: the receiving copy of each ground, then the crossing points."""
        return np.concatenate([np.arange(self.n_grounds), self.crossing_nodes])

    def node_path(self, nodes) -> np.ndarray:
        """Parameter-space polyline of a node path, unwrapped across seams.

        A ground at either end is replaced by the point where the path meets
        that boundary.
        """
        ng = self.n_grounds
        nodes = [int(v) - self.n_nodes if int(v) >= self.n_nodes else int(v) for v in nodes]  # emitting grounds
        pts = []
        if nodes[0] < ng:
            pts.append(self.exit_points[nodes[0], nodes[1]])
            pts += list(self.exit_bends.get((nodes[0], nodes[1]), ())[::-1])
        pts += [self.coords[v] for v in nodes if v >= ng]
        if nodes[-1] < ng:
            pts += list(self.exit_bends.get((nodes[-1], nodes[-2]), ()))
            pts.append(self.exit_points[nodes[-1], nodes[-2]])
        st = np.array(pts)
        S, V = self.domain.local_lengths
        for axis, (per, period) in enumerate(zip(self.domain.periodic, (S, V))):
            if per and len(st) > 1:
                step = np.diff(st[:, axis])
                step -= period * np.round(step / period)
                st[1:, axis] = st[0, axis] + np.cumsum(step)
        return self.domain.to_param(st)


def _dedupe_min(r, c, w, k, n_grounds: int, first_point: int):
    """Keep the lightest of parallel edges (sparse matrices would add them up); orient rows < cols.

    Edges between grid nodes are unique (the grid has more than ``2 * radius``
    cells around each circle), so only those that touch a ground (index
    ``< n_grounds``) or a crossing point (index ``>= first_point``) are sorted.
    """
    swap = r > c
    a, b = np.where(swap, c, r), np.where(swap, r, c)
    k = np.negative(k, out=k.copy(), where=swap[:, None])
    special = (a < n_grounds) | (b >= first_point)
    sub = special.nonzero()[0]
    order = sub[np.lexsort((w[sub], b[sub], a[sub]))]
    ao, bo = a[order], b[order]
    first = np.ones(len(order), dtype=bool)
    first[1:] = (ao[1:] != ao[:-1]) | (bo[1:] != bo[:-1])
    kept = np.concatenate([(~special).nonzero()[0], order[first]])
    return a.take(kept), b.take(kept), w.take(kept), np.take(k, kept, axis=0), kept


def deformed_speeds(comp, floor: float = 0.05) -> np.ndarray:
    """``|phi'|`` on each segment of a component, at least ``floor`` times its mean.

    The deformed arclength ``sigma`` of the component grows at this rate
    along its reference arclength (unitless: deformed length per reference
    length).  The floor keeps ``sigma`` strictly increasing where a segment
    collapses to a point (the default keeps a few grid cells on it).
    """
    speed = np.linalg.norm(comp.velocities, axis=1)
    return np.maximum(speed, floor * max(float(speed.mean()), 1e-300))


def _grid_coordinate(domain: Domain, metric: Metric, axis: int) -> tuple[np.ndarray, np.ndarray] | None:
    """Knots ``(local, grid)`` of the coordinate in which the grid of one axis is uniform, or None (uniform).

    The metrics that ask for it (``Metric.deformed_grid``) get a grid uniform
    in the deformed arclength.  For ``G`` the length element is ``rho |(phi'(x1) dx1, phi'(x2) dx2)|``: in the
    deformed arclength ``sigma`` of each component it is isotropic,
    ``rho |(d sigma1, d sigma2)|``, so a grid uniform in ``sigma`` has the
    stencil's isotropic bias (2.75 % with 16 neighbours).  Uniform in the
    reference arclength instead, a component stretched 10 times more in one
    place than in another would see directions squeezed by that factor and a
    bias of tens of percent (measured: 17 % on a random scene, whatever the
    resolution).  ``euclid`` too: in ``sigma`` the axes of its degenerate
    norm are the grid's diagonals on every cell, directions of the stencil
    (seed 2 of ``tests/conftest.random_crossing_scene``: with 16 neighbours
    the uniform grid routes one curve to a local geodesic 17 % longer than
    the shortest, the value 5 % too high, at 64 to 144 cells; in ``sigma``
    only at 128, and with 32 neighbours at none of 64 to 256).  ``g``
    (Euclidean in reference arclength) keeps the uniform grid, and so does
    the annulus, whose local axes mix the two parameters: for ``G`` its
    component is computed in its deformed arclength instead, whenever its
    speeds differ (``direct.penalty._in_deformed_arclength``).
    """
    if not metric.deformed_grid or domain.kind == "annulus":
        return None
    B = domain.basis
    col = B[:, axis]
    if np.count_nonzero(col) != 1:
        return None
    comp = domain.comps[int(np.flatnonzero(col)[0])]
    sigma = np.concatenate([[0.0], np.cumsum(deformed_speeds(comp) * np.diff(comp.params))])
    return comp.params, sigma


def _ticks(knots, length: float, n_cells: int) -> np.ndarray:
    """``n_cells + 1`` node positions on ``[0, length]``, uniform in the grid coordinate of ``knots``."""
    if knots is None:
        return np.linspace(0.0, length, n_cells + 1)
    local, grid = knots
    t = np.interp(np.linspace(0.0, grid[-1], n_cells + 1), grid, local)
    t[0], t[-1] = 0.0, length
    return t


def _patches(ci: np.ndarray, cj: np.ndarray, reach: int, ns: int, nv: int, ps: bool, pv: bool) -> np.ndarray:
    """Lattice positions ``(i, j)`` (shape ``(ns + 1, nv + 1)``) within ``reach`` steps of a crossing point's cell.

    The cell ``(ci, cj)`` of a point has the corners ``ci, ci + 1``; the
    patch takes ``reach`` more on each side, wrapped on periodic axes and cut
    at the ends of the others.
    """
    out = np.zeros((ns + 1, nv + 1), dtype=bool)
    if len(ci) == 0:
        return out
    offs = np.arange(-reach, reach + 2)
    rows = ci[:, None] + offs  # the box of each point: its rows times its columns
    cols = cj[:, None] + offs
    rows = np.mod(rows, ns) if ps else np.clip(rows, 0, ns)
    cols = np.mod(cols, nv) if pv else np.clip(cols, 0, nv)
    r = np.broadcast_to(rows[:, :, None], (len(ci), len(offs), len(offs)))
    c = np.broadcast_to(cols[:, None, :], r.shape)
    out[r, c] = True
    if ps:
        out[ns, :] = out[0, :]
    if pv:
        out[:, nv] = out[:, 0]
    return out


def _rough_cells(domain: Domain, metric: Metric, at, coarsen: int, ns: int, nv: int, ps: bool, pv: bool,
                 ratio: float) -> np.ndarray:
    """Lattice positions (shape ``(ns + 1, nv + 1)``) in the coarse cells where ``rho`` varies by more than ``ratio``.

    ``rho`` (the metric's weight of ``|phi(x1) - phi(x2)|^2``) is sampled
    every second fine node; a coarse cell is rough when the largest sample on
    it exceeds ``ratio`` times the smallest.  Rough cells and their eight
    neighbours are refined: geodesics follow the valleys of ``rho``.
    """
    if not np.isfinite(ratio):  # patches only
        return np.zeros((ns + 1, nv + 1), dtype=bool)
    step = 2 if coarsen % 2 == 0 else 1
    si, sj = np.arange(0, ns + 1, step), np.arange(0, nv + 1, step)
    ii, jj = np.meshgrid(si, sj, indexing="ij")
    x = domain.to_param(at(ii.ravel(), jj.ravel()))
    c1, c2 = domain.comps
    r = c1.phi(x[:, 0]) - c2.phi(x[:, 1])
    w = metric.weight(np.einsum("ij,ij->i", r, r)).reshape(ii.shape)
    k = coarsen // step  # samples per coarse cell side
    nI, nJ = ns // coarsen, nv // coarsen
    hi = np.full((nI, nJ), -np.inf)
    lo = np.full((nI, nJ), np.inf)
    for a in range(k + 1):  # the (k + 1)^2 samples on each coarse cell, as strided views
        for b in range(k + 1):
            v = w[a:a + k * nI:k, b:b + k * nJ:k]
            hi, lo = np.maximum(hi, v), np.minimum(lo, v)
    # rough cells and their eight neighbours (wrapped on periodic axes)
    rough = maximum_filter(hi > ratio * lo, size=3, mode=["wrap" if per else "constant" for per in (ps, pv)])
    # lattice positions on a rough cell: any of the (up to four) cells around the position
    cells = np.repeat(np.repeat(rough, coarsen, axis=0), coarsen, axis=1)  # (ns, nv): fine cell -> its coarse cell
    out = np.zeros((ns + 1, nv + 1), dtype=bool)
    out[:-1, :-1] |= cells
    out[1:, :-1] |= cells
    out[:-1, 1:] |= cells
    out[1:, 1:] |= cells
    if ps:
        out[0, :] |= out[ns, :]
        out[ns, :] = out[0, :]
    if pv:
        out[:, 0] |= out[:, nv]
        out[:, nv] = out[:, 0]
    return out


def _extended(ticks: np.ndarray, periodic: bool, idx: np.ndarray) -> np.ndarray:
    """Position of node index ``idx`` (any integer): periodic copies, or linear extension past the ends."""
    n = len(ticks) - 1
    if len(idx) and idx.min() >= 0 and idx.max() <= (n - 1 if periodic else n):  # the nodes themselves
        return ticks.take(idx)
    if periodic:
        k = np.floor_divide(idx, n)
        return ticks[idx - k * n] + k * ticks[-1]
    i = np.clip(idx, 0, n)
    lo = ticks[0] + (idx - 0) * (ticks[1] - ticks[0])
    hi = ticks[-1] + (idx - n) * (ticks[-1] - ticks[-2])
    return np.where(idx < 0, lo, np.where(idx > n, hi, ticks[i]))


def _valley_rays(domain: Domain, metric: Metric, pts: np.ndarray):
    """The valleys of ``rho`` out of crossing points, followed in deformed arclength across vertex lines.

    In a rectangle or triangle (whose local coordinates are the parameters)
    ``rho`` is smallest near a crossing point along the diagonals of the
    deformed arclengths ``(sigma1, sigma2)``, where both arms move at once;
    :func:`build_graph` adds straight moves along them, with the speeds at
    the point.  Past a vertex line the speed changes and a straight move in
    the parameters leaves the valley: a crossing 0.024 from a side, on an arm
    40 times slower beyond a vertex 0.007 away, got a route to the far side
    of the corner, 137 % too long, at 128 cells.  Here each of the four
    diagonals is followed in ``sigma`` up to the boundary: in the parameters
    a polyline that bends on every vertex line it crosses, with the exact
    length of that polyline.  Only the rays that bend are returned (the
    others are the straight moves).

    Returns
    -------
    owner : (m,) ndarray of int
        Crossing point of each ray.
    exits : (m, 2) ndarray
        Where each ray meets the boundary.
    bends : list of (k, 2) ndarray
        The points where each ray bends, from the crossing point to the exit.
    weights : (m,) ndarray
        Exact metric length of each ray.
    """
    knots = []
    for comp in domain.comps:
        speed = deformed_speeds(comp, floor=1e-6)  # sigma strictly increasing, collapsed segments barely counted
        knots.append((comp.params, np.concatenate([[0.0], np.cumsum(speed * np.diff(comp.params))])))
    n = len(pts)
    owner = np.repeat(np.arange(n), 4)
    sg = np.tile(np.array([[1.0, 1.0], [1.0, -1.0], [-1.0, 1.0], [-1.0, -1.0]]), (n, 1))
    s0 = np.column_stack([np.interp(pts[owner, k], *knots[k]) for k in (0, 1)])
    total = np.array([knots[0][1][-1], knots[1][1][-1]])
    t_exit = np.where(sg > 0, total - s0, s0).min(axis=1)
    if domain.kind == "triangle":  # inside sigma2 > sigma1 (one component): out through the diagonal
        closing = sg[:, 1] < sg[:, 0]
        gap = np.where(closing, s0[:, 1] - s0[:, 0], 0.0) / np.where(closing, sg[:, 0] - sg[:, 1], 1.0)
        t_exit = np.where(closing, np.minimum(t_exit, gap), t_exit)
    t_exit = np.maximum(t_exit, 0.0)
    # times at which each ray meets an interior vertex line of either axis, strictly before its exit
    T = np.hstack([(knots[k][1][1:-1][None, :] - s0[:, k:k + 1]) * sg[:, k:k + 1] for k in (0, 1)])
    eps = 1e-12 * max(float(total.max()), 1e-300)
    inside = (T > eps) & (T < t_exit[:, None] - eps)
    count = inside.sum(axis=1)
    bent = count > 0
    if not bent.any():
        return np.zeros(0, dtype=np.int64), np.zeros((0, 2)), [], np.zeros(0)
    T = np.where(inside, T, np.inf)[bent]
    T.sort(axis=1)
    T = T[:, :count.max()]
    owner, sg, s0, t_exit, count = owner[bent], sg[bent], s0[bent], t_exit[bent], count[bent]
    m = len(owner)
    # every ray's times: 0, its bends, its exit (inf pads the shorter rows)
    times = np.hstack([np.zeros((m, 1)), T, np.full((m, 1), np.inf)])
    times[np.arange(m), count + 1] = t_exit
    ok = np.isfinite(times)
    row = np.nonzero(ok)[0]
    t = times[ok]
    sig = s0[row] + sg[row] * t[:, None]
    X = np.column_stack([np.interp(sig[:, k], knots[k][1], knots[k][0]) for k in (0, 1)])
    X[np.flatnonzero(np.r_[True, row[1:] != row[:-1]])] = pts[owner]  # the crossing points themselves
    seg = np.flatnonzero(row[1:] == row[:-1])  # consecutive points of one ray
    w = segment_lengths(metric, domain.comps, X[seg], X[seg + 1])
    weights = np.maximum(np.bincount(row[seg], weights=w, minlength=m), _TINY)
    last = np.flatnonzero(np.r_[row[1:] != row[:-1], True])
    first = np.flatnonzero(np.r_[True, row[1:] != row[:-1]])
    bends = [X[a + 1:b] for a, b in zip(first.tolist(), last.tolist())]
    return owner, X[last], bends, weights


#: the most moves (nodes times stencil moves) a grid may have: building one takes about ``_BYTES_PER_MOVE`` bytes a
#: move at its peak (measured on ``cross`` with ``refine=False``, 16 neighbours: 1.8 GB for the uniform grid of 1024
#: cells, 6.8 GB for 2048; the uniform 4096 ran this 23 GB machine out of memory), so about 12 GB
_MAX_MOVES = 120_000_000
_BYTES_PER_MOVE = 100


def build_graph(
    domain: Domain, metric: Metric, resolution: int = 128, neighbours: int = 16, window: int = 2,
    coarsen: int = 1, patch: int = 2, ratio: float = 4.0
) -> GridGraph:
    """Build the grid graph of a domain.

    Parameters
    ----------
    domain : Domain
        The pair domain with its crossing points.
    metric : Metric
        Gives the exact edge weights.
    resolution : int, default 128
        Number of grid cells along the longer side of the domain, measured in
        the grid coordinate (deformed arclength for ``G``, see
        :func:`_grid_coordinate`; reference arclength otherwise).
    neighbours : {8, 16, 32}, default 16
        Stencil of the grid moves.
    window : int, default 2
        A crossing point is joined to the grid nodes within ``window`` cells.
    coarsen : int, default 1
        Local refinement.  With ``coarsen > 1`` the grid has the step of
        ``resolution`` only in a patch around each crossing point; elsewhere
        only every ``coarsen``-th node of that fine lattice is kept, joined by
        the stencil's moves scaled by ``coarsen`` (the same directions, hence
        the same angular bias, on a grid ``coarsen`` times coarser).  The
        patches and the coarse lattice share their nodes, so a path leaves a
        patch through a coarse node.  1 gives the uniform grid.  Must be 1 or
        larger than the stencil's radius (2 for 16 neighbours).
    patch : int, default 2
        Half-width of each patch around a crossing point, in coarse cells
        (used when ``coarsen > 1``).
    ratio : float, default 4
        With ``coarsen > 1``, a coarse cell (and its neighbours) is refined
        too where the metric's weight ``rho`` varies by more than this
        factor across it (sampled every second fine node): geodesics follow
        the valleys of ``rho`` (along the diagonal of a triangle or annulus,
        where it vanishes, and where two pieces of the curve come close),
        some narrower than a coarse cell.  The coarse lattice is kept only
        where ``rho`` is smooth at its scale.

    Returns
    -------
    GridGraph

    Raises
    ------
    DirectError
        When the grid would have more than ``_MAX_MOVES`` (1.2e8) moves
        (nodes times stencil moves), about 12 GB to build: the uniform grid
        of 4096 cells a side (``coarsen=1``) ran a 23 GB machine out of
        memory.

    Notes
    -----
    On a torus, distinct edges may join the same two nodes across different
    seams; only the lightest is kept.  This is harmless as long as the grid
    has at least ``2 * radius + 1`` cells around each circle (ensured).
    """
    S, V = domain.local_lengths
    ps, pv = domain.periodic
    ng = domain.n_grounds
    half = _local_stencil(domain, neighbours)
    radius = int(np.abs(half).max())
    knots = [_grid_coordinate(domain, metric, 0), _grid_coordinate(domain, metric, 1)]
    glen = [(S, V)[k] if knots[k] is None else float(knots[k][1][-1]) for k in (0, 1)]  # lengths in grid coordinates
    if domain.kind in ("triangle", "annulus"):
        ns = nv = max(int(resolution), 3)
    else:
        h0 = max(glen) / max(int(resolution), 2)
        ns, nv = max(int(np.ceil(glen[0] / h0)), 2), max(int(np.ceil(glen[1] / h0)), 2)
    if ps:
        ns = max(ns, 2 * radius + 3)
    if pv:
        nv = max(nv, 2 * radius + 3)
    coarsen = int(coarsen)
    if coarsen != 1 and coarsen <= radius:
        raise ValueError(f"coarsen must be 1 or larger than the stencil radius {radius}, got {coarsen}")
    if coarsen > 1:  # whole coarse cells (the coarse lattice wraps onto itself), enough of them to hold a node
        least = [2 * radius + 3 if per else 2 for per in (ps, pv)]  # and to keep the seams' edges distinct
        ns, nv = (coarsen * max(-(-n // coarsen), m) for n, m in zip((ns, nv), least))
    ticks_s, ticks_v = _ticks(knots[0], S, ns), _ticks(knots[1], V, nv)
    h = np.array([S / ns, V / nv])
    cell = np.array([np.diff(ticks_s).max(), np.diff(ticks_v).max()])  # largest cell sides

    def at(ti, tj):
        """Local coordinates of node indices (unwrapped across seams, extended past the ends)."""
        return np.column_stack([_extended(ticks_s, ps, ti), _extended(ticks_v, pv, tj)])

    pts = domain.to_local(domain.points) if len(domain.points) else np.empty((0, 2))
    n_pts = len(pts)
    ci = np.clip(np.searchsorted(ticks_s, pts[:, 0], side="right") - 1, 0, ns - 1)  # cell of each crossing point
    cj = np.clip(np.searchsorted(ticks_v, pts[:, 1], side="right") - 1, 0, nv - 1)
    # grid nodes: a in [0, ns) if periodic else (0, ns); same for b
    a_range = np.arange(0, ns) if ps else np.arange(1, ns)
    b_range = np.arange(0, nv) if pv else np.arange(1, nv)
    A, B = np.meshgrid(a_range, b_range, indexing="ij")
    inside = (B > A) if domain.kind == "triangle" else np.ones_like(A, dtype=bool)
    if coarsen > 1:
        fine_at = _patches(ci, cj, max(patch * coarsen, window), ns, nv, ps, pv)  # in a patch (at least the window)
        fine_at |= _rough_cells(domain, metric, at, coarsen, ns, nv, ps, pv, ratio)
        on_coarse = (A % coarsen == 0) & (B % coarsen == 0)
        fine = fine_at[A, B]
        kept = inside & (on_coarse | fine)
    else:
        kept = inside
    ii, jj = A[kept], B[kept]
    moves_out = len(ii) * 2 * len(half)
    if moves_out > _MAX_MOVES:
        raise DirectError(
            f"the grid of the pair {domain.pair} would have {len(ii)} nodes with {2 * len(half)} moves each, about "
            f"{_BYTES_PER_MOVE * moves_out / 1e9:.0f} GB to build ({ns} x {nv} cells at this resolution, "
            f"coarsen={coarsen}). Lower resolution, or keep the default coarsen=4: the refinement, not the grid, "
            f"sets the accuracy")
    node_of = np.full((ns + 1, nv + 1), -1, dtype=np.int64)  # -1: outside the domain (or on its boundary)
    node_of[A[inside & ~kept], B[inside & ~kept]] = -2  # -2: inside, but not a node of this grid
    node_of[ii, jj] = np.arange(ng, ng + len(ii))
    if ps:
        node_of[ns, :] = node_of[0, :]
    if pv:
        node_of[:, nv] = node_of[:, 0]
    node_flat = node_of.ravel()
    grid_st = at(ii, jj)
    n_grid = len(ii)
    if coarsen > 1:
        fine_src, coarse_src = fine[kept], on_coarse[kept]
    else:
        fine_src, coarse_src = np.ones(n_grid, dtype=bool), np.zeros(n_grid, dtype=bool)
    cross_nodes = np.arange(ng + n_grid, ng + n_grid + n_pts)
    coords = np.vstack([np.full((ng, 2), np.nan), grid_st, pts])

    # edges between grid nodes (unique, see _dedupe_min), then the others (to a ground or a crossing point)
    edges: tuple[list, list] = ([], [])

    def add(p_idx, q_idx, P, Q, ground, winds, grid=False):
        edges[0 if grid else 1].append((p_idx, q_idx, P, Q, ground, winds))

    def target(ti, tj):
        """Node at grid index (ti, tj) after wrapping, with the seam count; -1 outside or on the boundary."""
        ki = np.floor_divide(ti, ns) if ps else np.zeros_like(ti)
        kj = np.floor_divide(tj, nv) if pv else np.zeros_like(tj)
        ti, tj = ti - ki * ns, tj - kj * nv
        ok = (ti >= 0) & (ti <= ns) & (tj >= 0) & (tj <= nv)
        q = np.where(ok, node_flat.take(np.where(ok, ti * (nv + 1) + tj, 0)), -1)
        return q, np.column_stack([ki, kj])

    full = np.vstack([half, -half])
    node_ids = np.arange(ng, ng + n_grid)
    is_fine_src = np.zeros(ng + n_grid, dtype=bool)
    is_fine_src[ng:] = fine_src
    # the fine moves from the fine nodes (patches, rough cells), then (coarsen > 1) the scaled moves from the coarse
    # lattice
    for scale, sel in ((1, fine_src), (coarsen, coarse_src)):
        if not sel.any():
            continue
        src, si, sj, sst = node_ids[sel], ii[sel], jj[sel], grid_st[sel]
        # every move from every source at once, move by move (the order of the edges, hence of Dijkstra's ties,
        # is that of a loop over the moves)
        moves = full * scale
        n_src = len(src)
        ti = (si[None, :] + moves[:, :1]).ravel()
        tj = (sj[None, :] + moves[:, 1:]).ravel()
        q, kk = target(ti, tj)
        interior = q >= ng
        # each interior edge once: the other half of the moves only towards nodes without these moves
        other_half = np.repeat(np.arange(len(moves)) >= len(half), n_src)
        interior &= ~(other_half & is_fine_src.take(np.maximum(q, 0))) if scale == 1 else ~other_half
        inn, out = interior.nonzero()[0], (q == -1).nonzero()[0]
        owner = np.tile(np.arange(n_src), len(moves))
        add(src.take(owner.take(inn)), q.take(inn), np.take(sst, owner.take(inn), axis=0),
            at(ti.take(inn), tj.take(inn)), False, np.take(kk, inn, axis=0), grid=True)
        if out.size:
            p = np.take(sst, owner.take(out), axis=0)
            d = at(ti.take(out), tj.take(out)) - p
            t, which = domain.exit_time(p, d)
            t = np.minimum(t, 1.0)
            add(src.take(owner.take(out)), which, p, p + t[:, None] * d, True,
                np.zeros((out.size, 2), dtype=np.int64))

    if n_pts:
        offs = np.arange(-window + 1, window + 1)
        oi, oj = np.meshgrid(offs, offs, indexing="ij")
        ti = (ci[:, None] + oi.ravel()[None, :]).ravel()
        tj = (cj[:, None] + oj.ravel()[None, :]).ravel()
        owner = np.repeat(np.arange(n_pts), oi.size)
        q, kk = target(ti, tj)
        interior, outside = q >= ng, q == -1
        tgt = at(ti, tj)
        add(cross_nodes[owner[interior]], q[interior], pts[owner[interior]], tgt[interior], False, kk[interior])
        # straight moves to a ground: towards each window node outside, along the local axes, to the diagonal
        starts, dirs, owners = [pts[owner[outside]]], [tgt[outside] - pts[owner[outside]]], [owner[outside]]
        axes = [[1, 0], [-1, 0], [0, 1], [0, -1]] + ([[1, -1]] if domain.kind == "triangle" else [])
        for ax in axes:
            starts.append(pts)
            dirs.append(np.broadcast_to(np.array(ax, dtype=float), pts.shape))
            owners.append(np.arange(n_pts))
        # and, in a rectangle or triangle, along the diagonals in deformed arclength, where both arms move at once:
        # one of them is the valley of rho that the geodesic of the point follows (the only way out within a cell
        # of two sides when the domain is a few cells wide: a crossing 0.02 from two sides, 4 cells across, gave
        # a route 35 % too long).  Not around a circle, which has no corners: there they changed which local
        # geodesics the star polygons settle in (11 vertices: 4.9e-4 higher, 8 times slower)
        if domain.kind in ("rect", "triangle"):
            speed = [np.maximum(np.linalg.norm(comp.velocities[comp.segment_index(domain.points[:, k])], axis=1),
                                1e-12) for k, comp in enumerate(domain.comps)]
            for s1, s2 in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
                starts.append(pts)
                dirs.append(np.column_stack([s1 / speed[0], s2 / speed[1]]))
                owners.append(np.arange(n_pts))
        p, d, own = np.vstack(starts), np.vstack(dirs), np.concatenate(owners)
        t, which = domain.exit_time(p, d)
        good = np.isfinite(t)
        add(cross_nodes[own[good]], which[good], p[good], p[good] + t[good, None] * d[good], True,
            np.zeros((good.sum(), 2), dtype=np.int64))
        if n_pts > 1:
            a, b = np.triu_indices(n_pts, 1)
            delta = pts[b] - pts[a]
            shift = np.zeros_like(delta)
            for axis, (per, period) in enumerate(zip((ps, pv), (S, V))):
                if per:
                    shift[:, axis] = -period * np.round(delta[:, axis] / period)
            delta = delta + shift
            near = (np.abs(delta) <= window * cell).all(axis=1)
            # the move lands on the copy of b shifted by `shift`: that many periods across the seams
            kk = np.column_stack([np.round(shift[:, 0] / S) if ps else 0 * shift[:, 0],
                                  np.round(shift[:, 1] / V) if pv else 0 * shift[:, 1]]).astype(np.int64)
            add(cross_nodes[a[near]], cross_nodes[b[near]], pts[a[near]], pts[a[near]] + delta[near], False, kk[near])

    n_bent = 0
    # last, so that a tie keeps the straight moves; not for a degenerate metric (euclid), whose weight is 1
    # everywhere and whose norm nearly ignores these diagonals: with them interval seed 9 of
    # validation/euclid.py settled in a local geodesic 1.8 % too long at tol=1e-3, beyond its estimate
    if n_pts and domain.kind in ("rect", "triangle") and not metric.degenerate:
        owner, exits, bends, bent_w = _valley_rays(domain, metric, pts)
        n_bent = len(owner)
        if n_bent:
            add(cross_nodes[owner], np.zeros(n_bent, dtype=np.int64), pts[owner], exits, True,
                np.zeros((n_bent, 2), dtype=np.int64))

    inner, other = edges
    n_inner = sum(len(e[0]) for e in inner)
    rows, cols = (np.concatenate([e[i] for e in inner + other]) for i in (0, 1))
    P, Q = (np.vstack([e[i] for e in inner + other]) for i in (2, 3))
    winds = np.vstack([e[5] for e in inner + other]).astype(np.int64, copy=False)
    ground = np.concatenate([np.full(len(e[0]), e[4]) for e in other] + [np.zeros(0, dtype=bool)])
    identity = np.array_equal(domain.basis, np.eye(2))  # then local coordinates are parameters (no copies)
    w = np.maximum(segment_lengths(metric, domain.comps, P if identity else domain.to_param(P),
                                   Q if identity else domain.to_param(Q)), _TINY)
    if n_bent:
        w[len(w) - n_bent:] = bent_w
    # grid edges are unique: only oriented rows < cols; the others are deduplicated
    r, c, kw = rows[:n_inner], cols[:n_inner], winds[:n_inner]
    swap = r > c
    if swap.any():
        r, c = np.where(swap, c, r), np.where(swap, r, c)
        kw = np.negative(kw, out=kw.copy(), where=swap[:, None])
    rs, cs, ws, ks, kept = _dedupe_min(rows[n_inner:], cols[n_inner:], w[n_inner:], winds[n_inner:], ng, ng + n_grid)
    exit_points = np.full((max(ng, 1), len(coords), 2), np.nan)
    g = ground[kept]
    exit_points[rs[g], cs[g]] = np.take(Q[n_inner:], kept[g], axis=0)  # grounds have the smallest indices: rows
    exit_bends = {}
    if n_bent:
        first_bent = len(rows) - n_inner - n_bent
        for k in np.flatnonzero(g & (kept >= first_bent)).tolist():  # the chosen exits that are bent rays
            exit_bends[(int(rs[k]), int(cs[k]))] = bends[int(kept[k]) - first_bent]
    r, c, w = np.concatenate([r, rs]), np.concatenate([c, cs]), np.concatenate([w[:n_inner], ws])
    winds = np.concatenate([kw, ks])
    return GridGraph(
        domain=domain,
        h=h,
        coords=coords,
        crossing_nodes=cross_nodes,
        exit_points=exit_points,
        exit_bends=exit_bends,
        rows=r,
        cols=c,
        weights=w,
        winds=winds,
        neighbours=neighbours,
        metric=metric,
        shape=(ns, nv),
        coarsen=coarsen,
        ticks=(ticks_s, ticks_v),
    )
