"""Built-in scenes, by name: ``direct.scenes.get("fig2")``.

Every scene argument of the command line also accepts these names.

========  =====================================================================
name      what it is
========  =====================================================================
cross     two straight unit-speed segments of length 1 crossing at a right
          angle at their midpoints (a = b = c = d = 1/2): ``J^G = 2 m^3 / 3``,
          ``J^g = 2 m^5 / 5`` with ``m = 1/2``.
cross60   two straight unit-speed segments of length 2 crossing at 60 degrees
          at their midpoints; the geodesics do not follow grid axes.
fig2      the paper's Figure 2: two intervals, the second dips below the first
          and crosses it twice, with opposite signs.
waves     a curved interval (a sine wave sampled at 121 vertices) across a
          straight one: five crossings of alternating signs.
loop      one interval that makes a loop and crosses itself once: the curve
          gamma lives in the triangle ``x1 < x2`` of ``I x I`` and may end
          on the diagonal.
reversed  the unit circle (256 vertices) deformed into itself run backwards,
          ``(cos(-t), sin(-t))`` (paper, Fig. 12): no crossing, but turning
          number -1 instead of 1; ``J^G = 4 sqrt(2) pi`` for the smooth circle.
fig10     the unit circle deformed into the figure eight ``(cos t, sin 2t)``
          (Fig. 10): one self-crossing, turning number 0.
fig11     the double cover ``(cos 2t, sin 2t)`` (Fig. 11), its two passes on
          exactly the same vertices: no transversal crossing anywhere; the
          generic perturbation finds none, and the turning number (2 instead
          of 1) asks for one curve across the annulus.
fig13     the triple cover ``(cos 3t, sin 3t)`` (Fig. 13), likewise.
nested    the paper's example of section 3.3.4: two unit circles side by
          side; the deformation shrinks the first by 1/2 and moves the second
          onto the unit circle around it.  No crossing, yet not admissible:
          only a closed curve ``(-M1) x {a}`` meets the conditions.
ring      the example at the end of section 3.4.3: a unit circle kept in
          place and a segment collapsed to its centre; ``J^G = 0`` but
          ``J^g > 0`` (Prop. 17).
hairpin   a regular octagon folded into a thin loop: two segments of the
          deformation meet at a hairpin of 0.4 degrees and one crossing
          closes the loop; ``J^G`` is tiny (3.3e-5) and the grid's value at
          128 cells is 6.2 times it (a valley narrower than a cell).
========  =====================================================================

Circles are sampled as polylines with the vertices at equal angles; their
parameter is the reference arclength of the polygon.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from .errors import SceneError
from .scene import Component, Scene

__all__ = ["get", "names", "cross", "resolve", "circle_scene"]


def cross(a: float = 0.5, b: float = 0.5, c: float = 0.5, d: float = 0.5, angle: float = np.pi / 2) -> Scene:
    """Two straight unit-speed segments that cross once.

    The first runs along the x axis from ``-a`` to ``b``, the second along
    direction ``angle`` from ``-c`` to ``d``; they cross at the origin.  The
    references are the same segments, apart and parallel, so the deformation
    is an isometry on each component.

    Parameters
    ----------
    a, b, c, d : float, default 0.5
        Arclength from the crossing to the ends (length units, > 0).
    angle : float, default pi / 2
        Angle between the two segments (radians, in ``(0, pi)``).

    Returns
    -------
    Scene
    """
    e = np.array([np.cos(angle), np.sin(angle)])
    first = Component([[0, 0], [a + b, 0]], [[-a, 0], [b, 0]], name="A")
    second = Component([[0, 1 + a + b], [c + d, 1 + a + b]], [-c * e, d * e], name="B")
    return Scene((first, second), name=f"cross(a={a}, b={b}, c={c}, d={d}, angle={angle:.6g})")


def _fig2() -> Scene:
    first = Component([[0, 0], [3, 0]], [[0, 0], [3, 0]], name="I1")
    second = Component(
        [[0, 1], [1, 1], [2, 1], [3, 1]],
        [[0, 1], [1, -1], [2, -1], [3, 1]],
        name="I2",
    )
    return Scene((first, second), name="fig2")


def _waves() -> Scene:
    x = np.linspace(0.0, 3.0, 121)
    ref_wave = np.column_stack([x, np.full_like(x, 2.0)])
    wave = np.column_stack([x, 0.6 * np.sin(2 * np.pi * (x - 0.113) / 1.2)])
    line = Component([[-0.5, 0], [3.5, 0]], [[-0.5, 0], [3.5, 0]], name="line")
    return Scene((line, Component(ref_wave, wave, name="wave")), name="waves")


def _loop() -> Scene:
    t = np.linspace(0.0, 1.0, 41)
    ref = np.column_stack([3 * t, np.zeros_like(t)])
    # a prolate trochoid arch: x goes forward, back, forward and the image crosses itself once
    dfm = np.column_stack([3 * t + 1.2 * np.sin(2 * np.pi * t), 0.8 * (1 - np.cos(2 * np.pi * t))])
    return Scene((Component(ref, dfm, name="loop"),), name="loop")


def circle_scene(deformation, n: int = 256, radius: float = 1.0, name: str = "circle") -> Scene:
    """The circle of radius ``radius`` (``n`` vertices) with a deformation given as a function of the angle.

    Parameters
    ----------
    deformation : callable
        ``t -> (n, 2)`` array of deformed positions for angles ``t`` (radians).
    n : int, default 256
        Number of vertices.  A multiple cover ``(cos kt, sin kt)`` with ``k``
        dividing ``n`` puts the vertices of its passes on top of each other
        (the exact covers of section 5.2); otherwise the passes are different
        polygons that cross: ``k = 2`` with an odd ``n`` gives a star polygon
        with ``n`` crossings.
    radius : float, default 1
        Radius of the reference circle ``j(t) = radius (cos t, sin t)``.
    name : str
        Name of the component and the scene.

    Returns
    -------
    Scene
    """
    t = 2 * np.pi * np.arange(n) / n
    ref = radius * np.column_stack([np.cos(t), np.sin(t)])
    return Scene((Component(ref, np.asarray(deformation(t), dtype=float), closed=True, name=name),), name=name)


def _cover(k: int, per_turn: int = 96) -> Scene:
    """The unit circle deformed into ``(cos kt, sin kt)``; every pass on exactly the same vertices."""
    turn = 2 * np.pi * np.arange(per_turn) / per_turn
    deformed = np.tile(np.column_stack([np.cos(turn), np.sin(turn)]), (k, 1))
    return circle_scene(lambda t: deformed, n=k * per_turn, name=f"fig1{1 if k == 2 else 3}")


def _nested() -> Scene:
    t = 2 * np.pi * np.arange(128) / 128
    unit = np.column_stack([np.cos(t), np.sin(t)])
    m1 = Component(unit, 0.5 * unit, closed=True, name="M1")
    m2 = Component(unit + [0, 2.5], unit, closed=True, name="M2")
    return Scene((m1, m2), name="nested")


def _ring() -> Scene:
    t = 2 * np.pi * np.arange(128) / 128
    unit = np.column_stack([np.cos(t), np.sin(t)])
    ring = Component(unit, unit, closed=True, name="ring")
    seg = Component([[2, 0], [3, 0]], [[0, 0], [0, 0]], name="segment")
    return Scene((ring, seg), name="ring")


def _hairpin() -> Scene:
    t = 2 * np.pi * np.arange(8) / 8
    deformed = [[0.554, 0.615], [0.329, 0.559], [-0.798, 0.884], [-1.242, 0.635], [-1.086, 0.371],
                [-0.167, -1.035], [-0.653, -0.303], [1.138, -1.473]]
    octagon = np.column_stack([np.cos(t), np.sin(t)])
    return Scene((Component(octagon, deformed, closed=True, name="hairpin"),), name="hairpin")


_BUILTIN: dict[str, Callable[[], Scene]] = {
    "cross": lambda: Scene(cross().components, name="cross"),
    "cross60": lambda: Scene(cross(1, 1, 1, 1, np.pi / 3).components, name="cross60"),
    "fig2": _fig2,
    "waves": _waves,
    "loop": _loop,
    "reversed": lambda: circle_scene(lambda t: np.column_stack([np.cos(-t), np.sin(-t)]), name="reversed"),
    "fig10": lambda: circle_scene(lambda t: np.column_stack([np.cos(t), np.sin(2 * t)]), name="fig10"),
    "fig11": lambda: _cover(2),
    "fig13": lambda: _cover(3),
    "nested": _nested,
    "ring": _ring,
    "hairpin": _hairpin,
}


def names() -> list[str]:
    """Names of the built-in scenes."""
    return sorted(_BUILTIN)


def get(name: str) -> Scene:
    """A built-in scene by name.

    Parameters
    ----------
    name : str
        One of :func:`names`.

    Returns
    -------
    Scene

    Raises
    ------
    SceneError
        If there is no built-in scene of that name.
    """
    try:
        make = _BUILTIN[name]
    except KeyError:
        raise SceneError(f"no built-in scene named {name!r}; choose one of {names()}") from None
    return make()


def resolve(scene: "Scene | str") -> Scene:
    """A scene given as a :class:`Scene`, a JSON file path, or a built-in name.

    Parameters
    ----------
    scene : Scene or str or path-like
        A file that exists is read with :func:`direct.load_scene` (a file
        named like a built-in scene, in the working directory, comes first);
        otherwise the string must be a built-in name (:func:`names`).  A
        folder is not a file: a folder named like a built-in scene is passed
        over.

    Returns
    -------
    Scene

    Raises
    ------
    SceneError
        For a string that is neither an existing file nor a built-in name,
        or an object of another type; :class:`SceneFileError` for a file
        that cannot be read as a scene.
    """
    import os

    from .scene import load_scene

    if isinstance(scene, Scene):
        return scene
    if isinstance(scene, (str, os.PathLike)):
        if os.path.isfile(scene) or (os.path.exists(scene) and str(scene) not in _BUILTIN):
            return load_scene(scene)
        if str(scene) in _BUILTIN:
            return get(str(scene))
        text = os.fspath(scene)
        if str(text).lower().endswith(".json") or os.sep in str(text):
            raise SceneError(f"scene file {text!r} not found (from {os.getcwd()!r}); give the path of an existing "
                             f"JSON scene file, or a built-in scene name {names()}")
        raise SceneError(f"{text!r} is neither a scene file nor a built-in scene name {names()}")
    raise SceneError(f"expected a Scene, a JSON file path or a built-in name, got {type(scene).__name__}")
