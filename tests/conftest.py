"""Shared fixtures and scene generators for the tests."""

from __future__ import annotations

import sys

import numpy as np
import pytest
import shapely
from references import crossing_reference, cylinder_reference

import direct

# relative agreement expected between two computations of the same J at the default tol 1e-3
RTOL = 5e-3


def pytest_collection_modifyitems(config, items):
    """Skip the tests marked ``slow`` unless ``-m`` names the marker (``python -m pytest -q -m slow``; CI runs them
    after the default run). Skipped, not deselected: a slow test asked for by its id says how to run it."""
    if "slow" in (config.getoption("markexpr") or ""):
        return
    skip = pytest.mark.skip(reason="a slow regression test (20 s and more): run it with -m slow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


@pytest.fixture
def refine_batches(monkeypatch) -> list[int]:
    """The number of curves in each batch ``direct.penalty`` (and ``direct.starts``) sends to ``refine_many``, in
    order (a spy: the refinement itself runs unchanged). Read ``len`` before a call to take that call's batches
    alone."""
    P = sys.modules["direct.penalty"]
    batches: list[int] = []
    inner = P.refine_many

    def counting(domain, metric, jobs, *args, **kwargs):
        batches.append(len(jobs))
        return inner(domain, metric, jobs, *args, **kwargs)

    monkeypatch.setattr(P, "refine_many", counting)
    monkeypatch.setattr(sys.modules["direct.starts"], "refine_many", counting)  # the other starts' batches
    return batches


def random_intervals(rng: np.random.Generator, n_comp: int = 2, n_vert: int = 5, spread: float = 1.0) -> direct.Scene:
    """Random open polylines: references are parallel horizontal lines, deformations random walks.

    The references are embedded by construction; the deformations usually cross.
    """
    comps = []
    for k in range(n_comp):
        steps = rng.uniform(0.3, 1.0, size=n_vert - 1)
        x = np.concatenate([[0.0], np.cumsum(steps)])
        ref = np.column_stack([x, np.full(n_vert, 2.0 * k)])
        dfm = rng.normal(scale=spread, size=(n_vert, 2))
        comps.append(direct.Component(ref, dfm, name=f"P{k}"))
    return direct.Scene(tuple(comps), name="random")


def random_crossing_scene(seed: int, n_comp: int = 2, n_vert: int = 5, min_crossings: int = 1, max_crossings: int = 6):
    """A random interval scene with a number of crossings in the given range (deterministic in seed)."""
    rng = np.random.default_rng(seed)
    for _ in range(200):
        sc = random_intervals(rng, n_comp, n_vert)
        n = len(direct.find_crossings(sc))
        if min_crossings <= n <= max_crossings:
            return sc
    raise RuntimeError("no random scene with the requested number of crossings")


def polygon_pair(n: int, shift: float, wobble: float = 0.0, seed: int = 0) -> direct.Scene:
    """Two ``n``-gons of radius 1 pushed together (a torus of M x M): centres ``shift`` apart, the second wobbling.

    The second polygon's radius is ``1 + wobble cos(k t + phase)`` with ``k`` in 2..4 and the phase drawn from
    ``seed``; ``shift`` below 2 makes them cross (used by ``tests/test_circles.py`` and
    ``validation/closed_searches.py``).
    """
    rng = np.random.default_rng(seed)
    t = 2 * np.pi * np.arange(n) / n
    unit = np.column_stack([np.cos(t), np.sin(t)])
    k, phase = rng.integers(2, 5), rng.uniform(0, 2 * np.pi)
    bumpy = unit * (1 + wobble * np.cos(k * t + phase))[:, None]
    a = direct.Component(unit, unit, closed=True, name="a")
    b = direct.Component(unit + [5, 0], bumpy + [shift, 0.1], closed=True, name="b")
    return direct.Scene((a, b), name=f"{n}-gons {shift} apart" + (f", wobble {wobble}" if wobble else ""))


def study_scenes(seeds):
    """``(seed, scene)`` for the random interval scenes of the validation studies (``validation/default_tol.py``).

    2 polylines of 7 vertices for an even seed, 3 for an odd one, 1 to 10 crossings; the seeds that yield no
    such scene are skipped.
    """
    for seed in seeds:
        try:
            yield seed, random_crossing_scene(seed, n_comp=2 + seed % 2, n_vert=7, min_crossings=1, max_crossings=10)
        except RuntimeError:
            continue


def insert_vertex(comp: direct.Component, seg: int, t: float) -> direct.Component:
    """The same component with a material point added at fraction t of segment seg."""
    ref, dfm = comp.reference_ring, comp.deformed_ring
    new_r = ref[seg] + t * (ref[seg + 1] - ref[seg])
    new_d = dfm[seg] + t * (dfm[seg + 1] - dfm[seg])
    r = np.insert(comp.reference, seg + 1, new_r, axis=0)
    d = np.insert(comp.deformed, seg + 1, new_d, axis=0)
    return direct.Component(r, d, comp.closed, comp.name)


def rigid(scene: direct.Scene, angle: float, shift, scale: float = 1.0) -> direct.Scene:
    """Apply a similarity x -> scale * R(angle) x + shift to every deformed vertex."""
    c, s = np.cos(angle), np.sin(angle)
    R = np.array([[c, -s], [s, c]])
    return scene.with_deformed([scale * c_.deformed @ R.T + np.asarray(shift) for c_ in scene.components])


@pytest.fixture
def rng():
    return np.random.default_rng(20261123)


def straight_crossings_scene(seed: int, kind: str, isometric: bool = False) -> direct.Scene:
    """Intervals whose crossings :func:`references.straight_crossings_reference` knows exactly (deterministic in seed).

    Parameters
    ----------
    seed : int
        Seed of the random choices.
    kind : {"comb", "hook", "loop"}
        ``"comb"``: a long spine crossed by 2 to 4 short sticks at random angles; ``"hook"``: a spine crossed
        twice (opposite signs, one piece of ``M x M``) by a polyline that rises, bends and comes back down
        (once where the way down misses the spine: seeds 21 and 25); ``"loop"``: one polyline crossing itself
        once.
    isometric : bool, default False
        References with the deformed segment lengths (as the reference of ``g`` needs), and no scaling.

    Returns
    -------
    direct.Scene
        The spine and the runs through the crossings carry extra collinear vertices; the references are
        horizontal lines whose segments have random lengths (unless ``isometric``); a random rotation, shift
        and scale (not with ``isometric``) move the whole scene, and components are reversed or reordered at
        random.
    """
    rng = np.random.default_rng(seed)

    def component(D, name, level, splits=()):
        D = np.asarray(D, dtype=float)
        for i, fractions in sorted(splits, key=lambda split: -split[0]):  # extra collinear vertices on segment i
            if len(fractions):
                D = np.insert(D, i + 1, [D[i] + f * (D[i + 1] - D[i]) for f in sorted(fractions)], axis=0)
        w = np.hypot(*np.diff(D, axis=0).T) * (1.0 if isometric else np.exp(rng.uniform(-1.0, 1.0, len(D) - 1)))
        ref = np.column_stack([np.concatenate([[0.0], np.cumsum(w)]), np.full(len(D), 3.0 * level)])
        comp = direct.Component(ref, D, name=name)
        return comp.reversed() if rng.random() < 0.5 else comp

    spine = [[-4.5, 0.0], [4.5, 0.0]]
    spine_splits = [(0, rng.uniform(0.0, 1.0, rng.integers(0, 4)))]
    if kind == "comb":
        xs = np.linspace(-3.5, 3.5, rng.integers(2, 5)) + rng.uniform(-0.2, 0.2)
        comps = [component(spine, "spine", 0, spine_splits)]
        for n, x in enumerate(xs):
            e = np.array([np.cos(angle := rng.uniform(0.2, np.pi - 0.2)), np.sin(angle)])
            a, b = 10.0 ** rng.uniform(-2.0, -0.6, 2)
            comps.append(component([[x, 0.0] - a * e, [x, 0.0] + b * e], f"stick{n}", n + 1))
        rng.shuffle(comps)
    elif kind == "hook":
        alpha, beta = rng.uniform(0.3, np.pi - 0.3, 2)
        x1, h = rng.uniform(-2.0, -1.0), rng.uniform(0.8, 1.5)
        e1, e2 = np.array([np.cos(alpha), np.sin(alpha)]), -np.array([np.cos(beta), np.sin(beta)])
        bend = np.array([x1, 0.0]) + h / np.sin(alpha) * e1
        x2 = bend + h / np.sin(beta) * e2  # where the way down meets the spine's line
        c1, c2 = 10.0 ** rng.uniform(-2.0, -0.8, 2)
        hook = [np.array([x1, 0.0]) - c1 * e1, bend, x2 + c2 * e2]
        comps = [component(spine, "spine", 0, spine_splits),
                 component(hook, "hook", 1, [(0, rng.uniform(0.0, 1.0, 2)), (1, rng.uniform(0.0, 1.0, 1))])]
        rng.shuffle(comps)
    elif kind == "loop":
        alpha = rng.uniform(0.4, np.pi - 0.4)
        e = np.array([np.cos(alpha), np.sin(alpha)])
        a, d = 10.0 ** rng.uniform(-1.5, -0.5), 10.0 ** rng.uniform(-2.0, -0.8)
        b, top = rng.uniform(1.0, 2.0, 2)
        corner = np.array([max(b, top * e[0]) + 0.5, top * e[1] + 0.5])
        comps = [component([[-a, 0.0], [b, 0.0], corner, top * e, -d * e], "loop", 0,
                           [(0, rng.uniform(0.0, 1.0, 1)), (3, rng.uniform(0.0, 1.0, 1))])]
    else:
        raise ValueError(f"unknown kind {kind!r}")
    scene = direct.Scene(tuple(comps), name=f"{kind} {seed}")
    return rigid(scene, rng.uniform(0.0, 2.0 * np.pi), rng.normal(scale=3.0, size=2),
                 1.0 if isometric else 10.0 ** rng.uniform(-0.5, 0.5))


def slowed_cross(arms, alpha, cuts, lengths=None):
    """``cross(*arms, angle=alpha)`` with each arm cut at the fractions ``cuts[k]`` of its deformed length, the
    reference vertices equally spaced over ``lengths[k]`` (default: the arm's length): the speed jumps at the
    cut, and differs between the arms (``G`` sees neither, Example 14)."""
    a, b, c, d = arms
    lengths = (a + b, c + d) if lengths is None else lengths
    e = np.array([np.cos(alpha), np.sin(alpha)])
    comps = []
    for k, (start, end) in enumerate(((np.array([-a, 0.0]), np.array([b, 0.0])), (-c * e, d * e))):
        t = np.concatenate([[0.0], np.atleast_1d(cuts[k]), [1.0]])  # one cut or several
        reference = np.column_stack([np.linspace(0.0, lengths[k], len(t)), np.full(len(t), 10.0 * k)])
        comps.append(direct.Component(reference, start + t[:, None] * (end - start), name="AB"[k]))
    return direct.Scene(tuple(comps))


def crease_by_a_sliding_end() -> tuple[direct.Scene, float]:
    """A crossing near a corner whose geodesic meets the side next to a vertex line, and its ``J``: local geodesics
    2.7e-4 to 8.6e-4 (relative) longer end on the same side, in the same strip between vertex lines, closer than
    the route check's coarse pass (2 %) can tell apart; which one the grid's route leads to depends on the grid
    and on the scene's position (``validation/crease_motions.py``)."""
    arms, alpha = (0.0953, 0.0776, 0.0495, 0.0713), 2.390
    return slowed_cross(arms, alpha, ((0.695, 0.779), 0.0856), (0.1729, 0.1207)), crossing_reference(alpha, *arms)


def cylinder_scene(seed: int, isometric: bool = False, flip: bool = False) -> direct.Scene:
    """An interval that crosses a square once near the middle of its left side, moved, for ``cylinder_reference``.

    Even seeds put the reference interval outside the reference square, odd
    seeds inside: the curve of the crossing must end at the interval's inside
    end, or its outside end (``tests/references.py``). The arm towards the
    end it must reach is the longer (0.3 to 0.8 times the other is the
    shorter), so the nearer end is the wrong one. The square has 0 to 3
    collinear vertices on each side, is listed from a random vertex and
    maybe backwards; the interval maybe backwards, the two in either order;
    the whole turned, shifted and (unless ``isometric``, for ``g``) scaled by
    up to 10 either way, its reference lengths then stretched by up to e.
    ``flip`` puts the reference interval on the other side of the square, the
    deformed scene unchanged: the curve must then reach the nearer end.
    """
    rng = np.random.default_rng(9000 + seed)
    outside = seed % 2 == 0
    angle = rng.uniform(1.25, np.pi - 1.25) - np.pi / 2  # the interval's direction, near the side's normal
    y0 = rng.uniform(-1.0, 1.0)
    far = rng.uniform(0.3, 1.0)
    near = far * rng.uniform(0.3, 0.8)
    a, b = (near, far) if outside else (far, near)  # a: the outside arm, b: the inside arm
    e = np.array([np.cos(angle), np.sin(angle)])
    X = np.array([-2.0, y0])
    deformed = np.array([X - a * e, X + b * e])
    L = a + b
    stretch = L if isometric else L * np.exp(rng.uniform(-1.0, 1.0))
    reference = (np.array([[-8.0, 5.0], [-8.0 + stretch, 5.0]]) if outside != flip
                 else np.array([[-1.6, -0.3], [-1.6 + min(3.2, stretch), -0.3]]))
    corners = np.array([[-2.0, -2.0], [2.0, -2.0], [2.0, 2.0], [-2.0, 2.0]])
    pts = []
    for i in range(4):
        p, q = corners[i], corners[(i + 1) % 4]
        pts.append(p)
        pts.extend(p + f * (q - p) for f in np.sort(rng.uniform(0.05, 0.95, rng.integers(0, 4))))
    square = np.roll(np.array(pts), rng.integers(0, len(pts)), axis=0)
    if rng.random() < 0.5:
        square = square[::-1]
    polygon = direct.Component(square, square, closed=True, name="square")
    interval = direct.Component(reference, deformed, name="interval")
    if rng.random() < 0.5:
        interval = interval.reversed()
    comps = (polygon, interval) if rng.random() < 0.5 else (interval, polygon)
    scene = direct.Scene(comps, name=f"cylinder {seed}")
    return rigid(scene, rng.uniform(0.0, 2.0 * np.pi), rng.normal(scale=10.0, size=2),
                 1.0 if isometric else 10.0 ** rng.uniform(-1.0, 1.0))


def polygon_cylinder_scene(seed: int, isometric: bool = False, k: int = 2) -> direct.Scene:
    """An interval that crosses a random polygon once, drawn until ``cylinder_reference`` (with ``k``) applies.

    The polygon is star-shaped about the origin (3 to 8 vertices at radii
    0.6 to 2, either orientation, convex or not), the deformed interval a
    segment between two points drawn in ``[-2.5, 2.5]^2``; the reference
    interval lies inside the polygon (near its representative point) or far
    outside it, at random.  The polygon is not deformed; the interval's
    reference has its deformed length when ``isometric`` (for ``g``), else
    0.05 inside or 3 outside.  Draws again from the same generator where the
    reference refuses (about 1 draw in 25 is kept).
    """
    rng = np.random.default_rng(11000 + seed)
    while True:
        m = int(rng.integers(3, 9))
        angles = np.sort(rng.uniform(0.0, 2.0 * np.pi, m))
        radii = rng.uniform(0.6, 2.0, m)
        polygon = np.column_stack([radii * np.cos(angles), radii * np.sin(angles)])
        if rng.random() < 0.5:
            polygon = polygon[::-1]
        shape = shapely.Polygon(polygon)
        A, B = rng.uniform(-2.5, 2.5, 2), rng.uniform(-2.5, 2.5, 2)
        L = float(np.hypot(*(B - A)))
        if not shape.is_valid or not L > 0:
            continue
        if rng.random() < 0.5:  # the reference interval inside
            c = np.array(shape.representative_point().coords[0])
            reference = np.array([c, c + [L if isometric else 0.05, 0.0]])
            if not shape.contains(shapely.linestrings(reference)):
                continue
        else:
            reference = np.array([[-20.0, 7.0], [-20.0 + (L if isometric else 3.0), 7.0]])
        scene = direct.Scene((direct.Component(polygon, polygon, closed=True, name="polygon"),
                              direct.Component(reference, np.array([A, B]), name="interval")),
                             name=f"polygon cylinder {seed}")
        try:
            cylinder_reference(scene, k=k)
        except ValueError:
            continue
        return scene
