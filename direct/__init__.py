"""direct: the direct method for the topological self-contact penalty of plane curves.

The penalty ``J(phi)`` of a deformation ``phi`` of a body M made of intervals
and circles is the least length, in a metric on ``M x M`` that depends on
``phi``, of a family of curves whose boundary is the set of signed
self-crossings (eq. (9)).  The direct method (section 5.1.1) computes
geodesic distances between the crossing points and to the boundary, then
solves the assignment program (34).

Quick start
-----------
>>> import direct
>>> scene = direct.scenes.get("cross")
>>> round(direct.penalty(scene).value, 4)   # 2 m^3 / 3 with m = 0.5
0.0833
"""

from . import scenes
from .crossings import Crossing, find_crossings
from .errors import (
    ConvergenceError,
    DegenerateError,
    DegenerateMetricWarning,
    DirectError,
    NotSupportedError,
    SceneError,
    SceneFileError,
    ToleranceWarning,
)
from .penalty import Pair, Penalty, penalty
from .scene import Component, Scene, load_scene

__all__ = [
    "Component",
    "Scene",
    "load_scene",
    "scenes",
    "penalty",
    "Penalty",
    "Pair",
    "find_crossings",
    "Crossing",
    "DirectError",
    "SceneError",
    "SceneFileError",
    "DegenerateError",
    "NotSupportedError",
    "ConvergenceError",
    "ToleranceWarning",
    "DegenerateMetricWarning",
]

__version__ = "0.1.0"

