r"""The penalty ``J(phi)`` by the direct method (section 5.1.1): the pipeline.

scene -> crossings (:mod:`direct.crossings`) -> pair domains and grid graphs
(:mod:`direct.grid`) -> grid geodesics and refined geodesics
(:mod:`direct.geodesics`) -> assignment program (34) (:mod:`direct.matching`)
-> :class:`Penalty`.

Convention: ``value`` is ``J`` over the whole of ``M x M`` as in eq. (34):
each geometric crossing ``phi(x1) = phi(x2)`` gives the two signed points
``(x1, x2)`` and ``(x2, x1)``, so every curve ``gamma`` of one half of
``M x M`` has a mirror image in the other and both are listed in ``pairs``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .crossings import Crossing, find_crossings
from .errors import DirectError, NotSupportedError
from .geodesics import Backend, grid_distances, refine
from .grid import Domain, GridGraph, build_graph
from .matching import solve
from .metric import Metric, MetricName, get_metric
from .scene import Scene
from .scenes import resolve

__all__ = ["penalty", "Penalty", "Pair"]

#: worst relative overestimate of grid distances by stencil (shared/NUMERICS.md), plus a margin for coarse grids
_STENCIL_BIAS = {8: 0.0824, 16: 0.0275, 32: 0.0131}


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
        The curve as a polyline in parameters ``(x1, x2)``, from ``gamma(0)`` to ``gamma(1)``.
    """

    components: tuple[str, str]
    start: tuple[float, float] | None
    end: tuple[float, float] | None
    start_crossing: int | None
    end_crossing: int | None
    length: float
    error_estimate: float
    path: np.ndarray = field(repr=False)

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
            "path": self.path.tolist(),
        }


@dataclass(frozen=True)
class Penalty:
    """The result of :func:`penalty`.

    Attributes
    ----------
    value : float
        ``J(phi)`` over the whole of ``M x M`` (eq. (34); both points of each crossing).
    error_estimate : float
        Estimated absolute error of ``value`` (sum of the Richardson
        corrections of the refined geodesics; 0 when there is no crossing).
    grid_value : float
        The same program solved with the grid (Dijkstra) distances alone.
    crossings : list of Crossing
        The geometric crossings, each once (:func:`direct.find_crossings`).
    pairs : list of Pair
        The optimal matching, boundary included, on all of ``M x M``.
    settings : dict
        Metric and numerical settings used.
    seconds : float
        Wall time of the computation.
    """

    value: float
    error_estimate: float
    grid_value: float
    crossings: list[Crossing]
    pairs: list[Pair]
    settings: dict[str, Any]
    seconds: float

    @property
    def paths(self) -> list[np.ndarray]:
        """The optimal curves ``gamma`` in parameter space, one per pair."""
        return [p.path for p in self.pairs]

    def to_dict(self, scene: Scene | None = None) -> dict[str, Any]:
        """JSON-ready form; with ``scene``, crossings name their components."""
        if scene is not None:
            crossings = [c.to_dict(scene) for c in self.crossings]
        else:
            crossings = [
                {"components": list(c.components), "params": list(c.params), "point": list(c.point), "sign": c.sign}
                for c in self.crossings
            ]
        return {
            "value": self.value,
            "error_estimate": self.error_estimate,
            "grid_value": self.grid_value,
            "crossings": crossings,
            "pairs": [p.to_dict() for p in self.pairs],
            "settings": self.settings,
            "seconds": self.seconds,
        }

    def __repr__(self) -> str:
        return (
            f"Penalty(value={self.value:.10g}, error_estimate={self.error_estimate:.2g}, "
            f"crossings={len(self.crossings)}, pairs={len(self.pairs)}, metric={self.settings.get('metric')!r})"
        )


def domains(scene: Scene, crossings: list[Crossing]) -> list[Domain]:
    """Group the crossing points into the pair domains that carry them (see :mod:`direct.grid`)."""
    groups: dict[tuple[int, int], list[int]] = {}
    for k, c in enumerate(crossings):
        groups.setdefault(tuple(c.components), []).append(k)
    out = []
    for (i, j), ids in sorted(groups.items()):
        pts = np.array([crossings[k].params for k in ids], dtype=float)
        signs = np.array([crossings[k].sign for k in ids], dtype=int)
        out.append(Domain((i, j), (scene.components[i], scene.components[j]), pts, signs, np.array(ids)))
    return out


def _route(graph: GridGraph, routes, a: int, b: int | None) -> np.ndarray:
    """Parameter-space polyline of the grid route from point ``a`` to point ``b`` (None: boundary)."""
    if b is None:
        return graph.node_path(routes[a](0), end_on_ground=True)
    return graph.node_path(routes[a](graph.crossing_nodes[b]), end_on_ground=False)


def _solve_domain(domain: Domain, metric: Metric, settings: dict, backend: Backend, do_refine: bool):
    graph = build_graph(domain, metric, settings["resolution"], settings["neighbours"])
    D, D0, routes = grid_distances(graph, backend)
    pos = np.flatnonzero(domain.signs > 0)
    neg = np.flatnonzero(domain.signs < 0)
    grid_value, grid_pairs = solve(D[np.ix_(pos, neg)], D0[pos], D0[neg])
    if not do_refine:
        chosen = {}
        for i, j in grid_pairs:
            a, b = (neg[j] if j is not None else pos[i]), (pos[i] if (i is not None and j is not None) else None)
            route = _route(graph, routes, a, b)
            length = D[a, b] if b is not None else D0[a]
            chosen[(i, j)] = (route, float(length), 0.0)
        return grid_value, grid_value, 0.0, grid_pairs, chosen
    bias = 1.0 + _STENCIL_BIAS.get(settings["neighbours"], 0.1) + 0.05
    cache: dict[tuple, Any] = {}
    pairs = grid_pairs
    for _ in range(len(pos) * len(neg) + len(pos) + len(neg) + 1):
        for i, j in pairs:
            if (i, j) in cache:
                continue
            if i is not None and j is not None:
                a, b = neg[j], pos[i]  # gamma runs from the negative point to the positive one
            else:
                a, b = (pos[i] if i is not None else neg[j]), None
            route = _route(graph, routes, a, b)
            cache[(i, j)] = refine(domain, metric, route, free_end=b is None, tol=settings["tol"])
        # refined lengths where known, optimistic lower estimates of the grid distances elsewhere
        A_pm = D[np.ix_(pos, neg)] / bias
        A_p0 = D0[pos] / bias
        A_0m = D0[neg] / bias
        for (i, j), rp in cache.items():
            if i is not None and j is not None:
                A_pm[i, j] = rp.length
            elif i is not None:
                A_p0[i] = rp.length
            else:
                A_0m[j] = rp.length
        value, new_pairs = solve(A_pm, A_p0, A_0m)
        if all(p in cache for p in new_pairs):
            pairs = new_pairs
            break
        pairs = new_pairs
    else:  # pragma: no cover - the loop refines a new entry each round, so it ends
        raise DirectError("the matching of refined geodesics did not settle")
    err = sum(cache[p].error_estimate for p in pairs)
    chosen = {p: (cache[p].points, cache[p].length, cache[p].error_estimate) for p in pairs}
    return value, grid_value, err, pairs, chosen


def penalty(
    scene: Scene | str,
    metric: MetricName | Metric = "G",
    *,
    power: float | None = None,
    tol: float = 1e-3,
    resolution: int = 96,
    neighbours: int = 16,
    backend: Backend = "scipy",
    refine: bool = True,
) -> Penalty:
    r"""The penalty ``J(phi)`` of a deformation, by the direct method (section 5.1.1).

    Parameters
    ----------
    scene : Scene or str
        The body M with its reference embedding and deformation; a JSON file
        path or a built-in scene name is accepted too.
    metric : {"G", "g", "euclid"} or Metric, default "G"
        ``"G"``: ``G(y1, y2) = |y1 - y2|^4 Id`` (Example 14); ``"g"``: the
        non-degenerate family ``g(s) = s^p`` of section 3.4.2; ``"euclid"``:
        the heuristic metric of section 3.1.  See :mod:`direct.metric`.
    power : float, optional
        ``q`` of ``G = |y1 - y2|^(2q) Id`` or ``p`` of ``g(s) = s^p`` (both default 2).
    tol : float, default 1e-3
        Relative tolerance of each refined geodesic length.
    resolution : int, default 96
        Grid cells along the longer side of each pair domain.
    neighbours : {8, 16, 32}, default 16
        Grid stencil.
    backend : {"scipy", "networkx"}, default "scipy"
        Shortest-path implementation of the grid stage.
    refine : bool, default True
        Refine the grid geodesics continuously (without it, ``value`` is the
        biased grid value).

    Returns
    -------
    Penalty
        ``value`` is ``J`` over all of ``M x M`` (eq. (34)): each geometric
        crossing contributes its two points ``(x1, x2)`` and ``(x2, x1)``.

    Raises
    ------
    SceneError
        For an invalid scene.
    NotSupportedError
        For closed components (circles of M), not handled yet.

    Examples
    --------
    >>> import direct
    >>> res = direct.penalty(direct.scenes.cross(0.3, 0.5, 0.4, 0.6))
    >>> abs(res.value - 2 * 0.3**3 / 3) < 1e-3 * res.value
    True
    """
    t0 = time.perf_counter()
    scene = resolve(scene)
    for c in scene.components:
        if c.closed:
            raise NotSupportedError(
                f"component {c.name!r} is closed (a circle of M); this version of the direct method handles "
                "intervals only (section 5.1.1): give it as an open polyline if its ends are free"
            )
    met = get_metric(metric, power)
    if not (0 < tol < 1):
        raise DirectError(f"tol must be in (0, 1), got {tol!r}")
    if int(resolution) < 4:
        raise DirectError(f"resolution must be at least 4 grid cells, got {resolution!r}")
    settings: dict[str, Any] = dict(met.describe())
    settings.update(tol=float(tol), resolution=int(resolution), neighbours=int(neighbours), backend=backend,
                    refine=bool(refine))
    crossings = find_crossings(scene)
    names = [c.name for c in scene.components]
    total = grid_total = err_total = 0.0
    pairs: list[Pair] = []
    for dom in domains(scene, crossings):
        value, grid_value, err, dom_pairs, chosen = _solve_domain(dom, met, settings, backend, refine)
        total += 2.0 * value
        grid_total += 2.0 * grid_value
        err_total += 2.0 * err
        pos = np.flatnonzero(dom.signs > 0)
        neg = np.flatnonzero(dom.signs < 0)
        ni, nj = names[dom.pair[0]], names[dom.pair[1]]
        for (i, j), (path, length, perr) in chosen.items():
            path = np.asarray(path, dtype=float)
            if i is not None and j is None:
                path = path[::-1]  # from the boundary to the positive point
            a = None if j is None else int(neg[j])
            b = None if i is None else int(pos[i])
            start = None if a is None else tuple(map(float, dom.points[a]))
            end = None if b is None else tuple(map(float, dom.points[b]))
            sc = None if a is None else int(dom.crossing_ids[a])
            ec = None if b is None else int(dom.crossing_ids[b])
            pairs.append(Pair((ni, nj), start, end, sc, ec, float(length), float(perr), path))
            # mirror image in M_j x M_i: coordinates swapped, signs (hence orientation) reversed
            mstart = None if end is None else end[::-1]
            mend = None if start is None else start[::-1]
            pairs.append(Pair((nj, ni), mstart, mend, ec, sc, float(length), float(perr), path[::-1, ::-1].copy()))
    return Penalty(
        value=float(total),
        error_estimate=float(err_total),
        grid_value=float(grid_total),
        crossings=crossings,
        pairs=pairs,
        settings=settings,
        seconds=time.perf_counter() - t0,
    )
