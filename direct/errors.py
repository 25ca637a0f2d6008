"""The exception family of `direct`.

Every error that `direct` raises on purpose is a :class:`DirectError`; the
subclasses say what kind of problem it is.  Messages name the component and
the vertex at fault and say what to do about it.
"""

from __future__ import annotations

__all__ = [
    "DirectError",
    "SceneError",
    "SceneFileError",
    "DegenerateError",
    "NotSupportedError",
    "ConvergenceError",
    "ToleranceWarning",
    "DegenerateMetricWarning",
]


class DirectError(Exception):
    """Base class of every error raised on purpose by `direct`."""


class SceneError(DirectError, ValueError):
    """A scene is invalid: bad coordinates, counts, or a reference that is not an embedding."""


class SceneFileError(SceneError):
    """A scene file cannot be read: malformed JSON, missing or mistyped keys."""


class DegenerateError(DirectError, ValueError):
    """The deformation is too degenerate for the generic-perturbation rule to decide."""


class NotSupportedError(DirectError, NotImplementedError):
    """The configuration is valid but not handled by this version of `direct`."""


class ConvergenceError(DirectError, RuntimeError):
    """A numerical stage did not reach the requested tolerance."""


class ToleranceWarning(UserWarning):
    """A result whose ``error_estimate`` exceeds the requested relative tolerance.

    The value is returned with its estimate; the warning says that the
    tolerance asked for was not reached (turn it into an error with
    ``warnings.simplefilter("error", direct.ToleranceWarning)`` in a property
    test that must not accept such a number).
    """


class DegenerateMetricWarning(ToleranceWarning):
    """A value computed in a degenerate metric, whose ``error_estimate`` cannot cover the choice of routes.

    The heuristic metric of section 3.1 (``metric="euclid"``) vanishes on a
    direction of every cell, and a grid overestimates lengths along its thin
    unit ball by tens of percent: the grid may send a curve towards another
    local geodesic than the shortest, and no refinement brings it back.
    ``Penalty.upper_bound``, the exact length of the curves returned, bounds
    ``J`` from above; the estimate covers their refinement and the spread
    between two grids, not routes that neither grid found
    (``validation/euclid.py``).
    A subclass of :class:`ToleranceWarning`: a property test that turns
    those into errors refuses these values too.
    """
