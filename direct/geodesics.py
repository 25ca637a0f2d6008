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
2. **Continuous refinement** (:mod:`direct.refinement`, re-exported here):
   each route becomes a polyline whose exact metric length is minimized,
   multilevel, with Richardson extrapolation and an error estimate; all the
   curves of a domain are refined together in one vectorized problem.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components, dijkstra

from .grid import GridGraph
from .refinement import GeodesicJob, RefinedPath, coarse_geodesic, coarse_geodesics, refine, refine_many

__all__ = [
    "grid_distances", "torus_distances", "closed_curve_distances", "closed_curve_bounds", "Backend",
    # the second stage, from direct.refinement
    "refine", "refine_many", "coarse_geodesic", "coarse_geodesics", "RefinedPath", "GeodesicJob",
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

    route.pred = pred
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


def _limited_searches(matrix: sp.csr_matrix, sources: np.ndarray, limits: dict, dist=None, pred=None):
    """Searches from some sources only, each stopped at its limit: ``{a: limit}`` for source ``sources[a]``.

    Rows not searched stay ``inf`` (``dist``, ``pred`` may come filled for some rows already).
    """
    if dist is None:
        dist = np.full((len(sources), matrix.shape[0]), np.inf)
        pred = np.full(dist.shape, -9999, dtype=np.int32)
    for a, limit in limits.items():
        dist[a], pred[a] = dijkstra(matrix, directed=True, indices=int(sources[a]), return_predecessors=True,
                                    limit=limit)
    return dist, _paths_from_predecessors(pred, sources)


def _bounded_shortest(matrix: sp.csr_matrix, sources: np.ndarray, bound: float):
    """:func:`_shortest` from one ground (``sources[0]``) and points, each point's search bounded (see ``bound``)."""
    d0, p0 = dijkstra(matrix, directed=True, indices=sources[:1], return_predecessors=True)
    d_ground = d0[0, sources[1:]]
    reach = np.isfinite(d_ground)
    far = float(d_ground[reach].max()) if reach.any() else np.inf
    dist = np.full((len(sources), matrix.shape[0]), np.inf)
    pred = np.full(dist.shape, -9999, dtype=np.int32)
    dist[0], pred[0] = d0[0], p0[0]
    limits = {a: bound * (d_ground[a - 1] + far) if reach[a - 1] else np.inf for a in range(1, len(sources))}
    return _limited_searches(matrix, sources, limits, dist, pred)


def _side_of(domain, st: np.ndarray) -> np.ndarray:
    """Which side of the domain's boundary each point ``st`` (local coordinates, on the boundary) lies on."""
    S, V = domain.local_lengths
    dist = [np.abs(st[:, 1]), np.abs(st[:, 1] - V)]
    if not domain.periodic[0]:
        dist += [np.abs(st[:, 0]), np.abs(st[:, 0] - S)]
    if domain.kind == "triangle":
        dist.append(np.abs(st[:, 1] - st[:, 0]) / np.sqrt(2))
    return np.argmin(np.column_stack(dist), axis=1)


def grid_distances(
    graph: GridGraph, backend: Backend = "scipy", bound: float | None = None, searches: dict | None = None
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
    searches : dict, optional
        ``{terminal: limit}`` (scipy): search only from these terminals, each
        stopped at its limit (a grid length); the other rows of ``T`` are
        ``inf`` and their routes unknown.  Overrides ``bound``.

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
        ``route.alternatives(a, b, margin, share, most)`` lists other routes
        between two terminals (scipy; none with networkx), those of *choice
        routing*: each runs along a plateau of the two trees of shortest
        paths from ``a`` and from ``b`` (edges that both trees use, one each
        way) that does not touch ``route(a, b)``, is at least ``share`` of
        ``T[a, b]`` long, and costs at most ``(1 + margin)`` times
        ``T[a, b]``; the ``most`` cheapest (the other side of a hill of the
        metric, see :func:`direct.starts._alternative_starts`).
    """
    src, dst = graph.sources, graph.targets
    if searches is not None and backend == "scipy":
        dist, node_route = _limited_searches(graph.matrix, src, searches)
    elif bound is not None and backend == "scipy" and graph.n_grounds == 1 and len(src) > 1:
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
            key = ends[:, 0]
        else:  # the boundary of a rectangle or triangle is star-shaped about its centroid
            centre = np.nanmean(ends, axis=0) if dom.kind == "torus" else np.array(dom.local_lengths) / 2
            if dom.kind == "triangle":
                centre = np.array([dom.local_lengths[0] / 3, 2 * dom.local_lengths[1] / 3])
            key = np.arctan2(ends[:, 1] - centre[1], ends[:, 0] - centre[0])
        order = np.argsort(key, kind="stable")
        c = cost[order]
        e = ends[order]
        side = _side_of(dom, e)
        n = len(c)
        is_min = np.ones(n, dtype=bool)
        # a local minimum beats its three neighbours on each side, and every exit on its side of the boundary
        # within two fine cells of it (a node has several exits: next to a refined patch three neighbours can be a
        # fraction of a cell); not across a corner, where a grazing crossing's geodesic has a basin on each side
        near = 2.0 * graph.cell
        c3, e3, side3 = (np.concatenate([x, x, x]) for x in (c, e, side))  # cyclic neighbours by slicing
        for shift in range(1, n):
            within = np.zeros(n, dtype=bool)
            for lo in (n - shift, n + shift):  # the exits ``shift`` places before, then after, each exit
                nb = c3[lo:lo + n]
                close = (np.abs(e3[lo:lo + n] - e) <= near).all(axis=1) & (side3[lo:lo + n] == side)
                within |= close
                is_min &= (c <= nb) | ~(close | (shift <= 3))
            if not within.any() and shift >= 3:
                break
        best = cost.min()
        picked = order[is_min & (c <= (1 + margin) * best)]
        picked = picked[np.argsort(cost[picked])][:most]
        return [graph.node_path(node_route(a, int(nodes[k])) + [g]) for k in picked]

    def alternatives(a: int, b: int, margin: float, share: float, most: int = 2) -> list[np.ndarray]:
        pred = getattr(node_route, "pred", None)  # the trees of shortest paths (scipy only)
        d = dist[a, dst[b]]
        if pred is None or not np.isfinite(d):
            return []
        da, db = dist[a], dist[b]
        n = np.flatnonzero(pred[a] >= 0)
        p = pred[a][n]
        both = pred[b][p] == n  # the edge p -> n in a's tree, n -> p in b's: a plateau of the two trees
        n, p = n[both], p[both]
        via = da[n] + db[n]
        keep = via <= (1.0 + margin) * d
        n, p, via = n[keep], p[keep], via[keep]
        if not len(n):
            return []
        size = len(da)  # the plateaus: components of the shared edges
        _, label = connected_components(sp.coo_matrix((np.ones(len(n)), (n, p)), shape=(size, size)), directed=False)
        main = np.unique(label[node_route(a, dst[b])])
        lab = label[n]
        seg = da[n] - da[p]
        other = ~np.isin(lab, main)
        if not other.any():
            return []
        lab, seg, via, n = lab[other], seg[other], via[other], n[other]
        labels, inv = np.unique(lab, return_inverse=True)
        length = np.bincount(inv, weights=seg)  # each plateau's grid length and the cost of its route
        cost = np.full(len(labels), np.inf)
        np.minimum.at(cost, inv, via)
        ok = np.flatnonzero(length >= share * d)
        out = []
        for k in ok[np.argsort(cost[ok])][:most]:
            m = int(n[np.flatnonzero(inv == k)[0]])  # a node of the plateau: the route a -> m -> b runs along it
            out.append(graph.node_path(node_route(a, m) + node_route(b, m)[::-1][1:]))
        return out

    route.candidates = candidates
    route.alternatives = alternatives
    return dist[:, dst], route


_COVER = [(a, b) for a in (-1, 0, 1) for b in (-1, 0, 1)]
#: the primitive classes searched from each seam (s = 0: a != 0; v = 0: (0, 1)); their opposites come reversed
_SEAM_CLASSES = ((0, ((1, 0), (1, 1), (1, -1))), (1, ((0, 1),)))
#: the closed-curve classes in the order closed_curve_distances returns them (the program's variables follow it)
_CLOSED_CLASSES = [k for _, classes in _SEAM_CLASSES for a, b in classes for k in ((a, b), (-a, -b))]


def _cover_index(k: np.ndarray) -> np.ndarray:
    """Index in ``_COVER`` of classes ``k`` (rows of two ints in ``{-1, 0, 1}``)."""
    return 3 * (k[..., 0] + 1) + (k[..., 1] + 1)


def _cover_matrix(graph: GridGraph) -> sp.csr_matrix:
    """The 3 x 3 block of the universal cover of a torus graph: copy ``c`` of node ``u`` is ``u + N c``.

    Block ``(c, c')`` holds the edges whose winds are ``c' - c``: one
    ``N x N`` matrix per wind, stacked block by block (CSR stacking copies
    index arrays; a single ``(row, col)`` conversion of all the cover's
    entries took 0.16 s of the 0.7 s of two overlapping 32-gons, and its
    Python assembly 0.18 s more).  The result is the same canonical matrix.
    """
    cached = getattr(graph, "_cover", None)
    if cached is not None:
        return cached
    N = graph.n_nodes
    rows = np.concatenate([graph.rows, graph.cols])
    cols = np.concatenate([graph.cols, graph.rows])
    weights = np.concatenate([graph.weights, graph.weights])
    by_wind = _cover_index(np.concatenate([graph.winds, -graph.winds]))  # a wind is in {-1, 0, 1}^2 too
    blocks = {}  # wind -> the N x N matrix of the edges with that wind
    for w in np.unique(by_wind):
        on = by_wind == w
        blocks[_COVER[w]] = sp.csr_matrix((weights[on], (rows[on], cols[on])), shape=(N, N))
    empty = sp.csr_matrix((N, N))
    M = sp.bmat([[blocks.get((c2[0] - c[0], c2[1] - c[1]), empty) for c2 in _COVER] for c in _COVER], format="csr")
    graph._cover = M
    return M


def torus_distances(graph: GridGraph, backend: Backend = "scipy") -> tuple[dict, callable]:
    """Grid distances between crossing points of a torus, by homotopy class.

    The grid graph is copied onto the 3 x 3 cover of the torus (section
    3.3.4: a curve between two points is ranked in each class of its
    period shift); one search from every crossing point of the centre copy.

    Parameters
    ----------
    graph : GridGraph
        The grid of a torus piece ``C_i x C_j`` (edge weights: exact metric
        lengths, in the metric's length units).
    backend : {"scipy", "networkx"}, default "scipy"
        The shortest-path implementation (networkx as a cross-check).

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


def _periodic_hausdorff(p: np.ndarray, q: np.ndarray, period: np.ndarray, h) -> float:
    """Hausdorff distance between point sets ``p`` and ``q`` of a torus of periods ``period``, in steps ``h``."""
    dd = p[:, None, :] - q[None, :, :]
    dd -= np.round(dd / period) * period
    r = np.hypot(dd[..., 0] / h[0], dd[..., 1] / h[1])
    return float(max(r.min(axis=1).max(), r.min(axis=0).max()))


def closed_curve_distances(graph: GridGraph, max_bases: int = 24, most: int = 1, margin: float = 0.01,
                           classes=None, separation: float = 2.0, lines: int = 1) -> dict:
    """Shortest closed grid curves of a torus in the primitive homotopy classes.

    Parameters
    ----------
    graph : GridGraph
        A torus graph.
    max_bases : int
        Base points tried per line (see ``lines``): a closed curve of class ``(a, b)`` with
        ``a != 0`` crosses the seam ``s = 0``, one with ``a = 0`` the seam ``v = 0``.
    most : int, default 1
        Closed curves returned per class: the shortest, then the shortest
        through other base points, within ``(1 + margin)`` of the shortest,
        whose routes lie more than ``separation`` grid steps from every route
        kept before (a periodic Hausdorff distance).  The grid ranks local
        geodesics only to within its bias: on two random nested 7-gons six
        closed geodesics of one class lie within 1 % of each other, and the
        grid's shortest route refines to the fourth of them (7.0e-3 above
        ``J``); the refinement keeps the best of several starts
        (:func:`direct.penalty.penalty`).  Where the metric is nearly
        invariant along a class (two nested regular polygons: a family of
        closed geodesics, shifted copies of each other), the starts reach
        several members of the family.
    margin : float, default 0.01
        See ``most``.
    classes : iterable of (int, int), optional
        The classes wanted (with ``|a|, |b| <= 1``, not both 0); default all
        eight.  A class comes with its opposite (the same curves run backwards).
    separation : float, default 2.0
        See ``most``: in grid steps (``graph.h``).  Routes through
        neighbouring base points of one basin differ by about a step near
        their base points.
    lines : int, default 1
        The base points lie on this many lines across the period (constant
        ``s`` for the classes with ``a != 0``, ``v`` for ``(0, 1)``), the
        seam and the lines at ``k / lines`` of the period, ``max_bases`` on
        each.  Two closed geodesics that meet near the seam and part
        elsewhere have one basin there: the grid's shortest curve through
        each point of the seam can all lead to the one the grid weighs less
        (``g`` on a 7-gon nested in a 17-gon, two geodesics 0.3 % apart whose
        grid weights differ by 2.8 %: :func:`direct.penalty.penalty` passes 4
        for such metrics).

    Returns
    -------
    dict
        ``{(a, b): [(length, polyline), ...]}`` for the classes wanted and
        their opposites, at most ``most`` curves each, the shortest first;
        each polyline (parameters) ends at its start shifted by ``(a S, b V)``
        in local coordinates.

    Notes
    -----
    One Dijkstra search on the 3 x 3 cover per base point (a closed curve
    through any node is a path from it to its copy shifted by the class), each stopped at
    ``(1 + margin)`` times the shortest closed curve of the wanted classes
    found so far (the first one not stopped): every curve that can be
    returned is within that limit, and the lengths and routes are those of
    full searches.  On two overlapping 12-gons a full search took 0.05 s
    and one stopped at a short class 0.004 s.
    """
    N = graph.n_nodes
    M = _cover_matrix(graph)
    centre = _COVER.index((0, 0))
    grid = graph.coords
    period = np.asarray(graph.domain.local_lengths, dtype=float)
    wanted = set(_CLOSED_CLASSES) if classes is None else {tuple(int(x) for x in c) for c in classes}
    out = {}
    for axis, seam_classes in _SEAM_CLASSES:
        todo = [c for c in seam_classes if c in wanted or (-c[0], -c[1]) in wanted]
        if not todo:
            continue
        finite = np.isfinite(grid[:, 0])
        columns = np.unique(grid[finite, axis])
        bases = []
        for f in np.arange(lines) / lines:  # the seam, then lines across the period at equal steps
            col = columns[np.argmin(np.abs(columns - f * period[axis]))]
            on = np.flatnonzero(finite & np.isclose(grid[:, axis], col))
            bases.append(on[np.unique(np.linspace(0, len(on) - 1, min(max_bases, len(on))).astype(int))])
        on_seam = np.unique(np.concatenate(bases))
        src = on_seam + N * centre
        tgt = {c: on_seam + N * _COVER.index(c) for c in todo}
        d = {c: np.full(len(src), np.inf) for c in todo}
        preds = []
        for k, s in enumerate(src):
            limit = (1 + margin) * max(float(d[c].min()) for c in todo)
            dist, pred = dijkstra(M, directed=True, indices=int(s), return_predecessors=True, limit=limit)
            preds.append(pred)
            for c in todo:
                d[c][k] = dist[tgt[c][k]]
        node_route = _paths_from_predecessors(np.asarray(preds), src)
        for a, b in todo:
            dc, tc = d[(a, b)], tgt[(a, b)]
            order = np.argsort(dc, kind="stable")
            order = order[np.isfinite(dc[order]) & (dc[order] <= (1 + margin) * dc[order[0]])]
            kept, routes = [], []
            for k in order:  # the shortest first, then the shortest routes apart from those kept
                nodes = np.asarray(node_route(k, tc[k]))
                at = graph.coords[nodes % N]
                if all(_periodic_hausdorff(at, other, period, graph.h) > separation for other in routes):
                    kept.append(k)
                    routes.append(at)
                    if len(kept) == most:
                        break
            found = [(float(dc[k]), _cover_polyline(graph, node_route(k, tc[k]))) for k in kept]
            out[(a, b)] = found
            out[(-a, -b)] = [(length, poly[::-1].copy()) for length, poly in found]
    return out


def closed_curve_bounds(graph: GridGraph) -> dict:
    """Lower bounds on the grid lengths of :func:`closed_curve_distances`, without a search.

    A closed curve of class ``(a, b)`` on the torus goes ``|a|`` times around
    the ``s`` circle, so its projection covers every column of the grid (the
    strip between two consecutive node abscissae) at least ``|a|`` times.
    An edge spanning ``|ds|`` along ``s`` weighs at least its length per unit
    of ``s``, ``w / |ds|``, times each column it spans, so every closed grid
    curve of the class is at least ``|a|`` times the sum over the columns of
    their width times the smallest ``w / |ds|`` of the edges spanning them;
    likewise along ``v`` with ``|b|``.  The bound is the larger of the two.
    It needs one pass over the edges (milliseconds), against the 2 x 24
    searches on the 3 x 3 cover of :func:`closed_curve_distances` (2.8 of
    the 3.5 s of two overlapping 32-gons at ``tol=1e-3``), so the program
    (34) on a torus can be solved with these bounds first and the searches
    run only when it picks a closed curve (:func:`direct.penalty.penalty`).

    Parameters
    ----------
    graph : GridGraph
        A torus graph.

    Returns
    -------
    dict
        ``{(a, b): bound}`` for the eight classes with ``|a|, |b| <= 1`` (not
        both 0), in the units of the metric's lengths; ``inf`` where no grid
        curve goes around (some column is spanned by no edge).
    """
    periods = np.asarray(graph.domain.local_lengths, dtype=float)
    on = np.isfinite(graph.coords[:, 0])
    per_axis = []
    for axis in (0, 1):
        lines = np.unique(graph.coords[on, axis])
        n = len(lines)
        iu = np.searchsorted(lines, graph.coords[graph.rows, axis])
        iv = np.searchsorted(lines, graph.coords[graph.cols, axis])
        steps = iv - iu + n * graph.winds[:, axis]  # columns crossed from rows to cols, signed
        extent = np.abs(graph.coords[graph.cols, axis] + periods[axis] * graph.winds[:, axis]
                        - graph.coords[graph.rows, axis])
        moving = steps != 0
        count = np.abs(steps[moving])
        first = np.minimum(iu, iu + steps)[moving]
        ratio = graph.weights[moving] / extent[moving]
        # every (edge, column) pair: the columns first, first + 1, ..., first + count - 1 (cyclic)
        edge = np.repeat(np.arange(len(count)), count)
        column = (np.repeat(first, count) + np.arange(edge.size) - np.repeat(np.cumsum(count) - count, count)) % n
        least = np.full(n, np.inf)
        np.minimum.at(least, column, ratio[edge])
        widths = np.diff(np.append(lines, lines[0] + periods[axis]))
        # a safety factor against the rounding of the widths and extents (relative 1e-16 each)
        per_axis.append(float(least @ widths) * (1.0 - 1e-9))
    # in the order of closed_curve_distances: the program's variables, and so how it breaks exact ties, stay the same
    return {(a, b): max(per_axis[axis] for axis, k in enumerate((a, b)) if k) for a, b in _CLOSED_CLASSES}
