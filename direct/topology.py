r"""Turning numbers and winding numbers of closed polylines (sections 3.3.3 and 3.3.4).

These integers fix the topological constraints on the curves ``gamma`` when M
has circles:

* the turning number ``#phi`` of a closed component (Remark 10): the number of
  turns of its tangent, ``sum of the signed exterior angles / 2 pi``;
* the winding number of a closed component around a point: the number of
  turns of ``phi(x) - p`` as ``x`` runs once around the circle.

Both are exact for polylines.  Degenerate cases follow the generic
perturbation of :mod:`direct.crossings`: a vertex where the polyline turns
back on itself (exterior angle ``+-pi``) turns to the side given by the
perturbation ``phi + eps v_c + eps^2 x u`` (towards ``u``); zero-length deformed
segments are skipped.  :func:`direct.penalty` does not rely on that rule for a
deformed circle: the crossings at the base of such a spike can be decided
otherwise, and a rotation of the scene changed ``J`` from 0 to 14.5 (an
adversarial review), so it raises :class:`direct.DegenerateError` there
(:func:`exact_reversals` finds the tips).  A winding number around a point *on* the polyline is
not defined: :func:`winding_number` raises :class:`direct.DegenerateError`.
"""

from __future__ import annotations

import numpy as np

from .crossings import _U as _CROSSINGS_U
from .errors import DegenerateError, SceneError

__all__ = ["turning_number", "winding_number", "exact_reversals"]

#: direction ``u`` of the parameter-proportional term of the generic perturbation (see :mod:`direct.crossings`)
_U = np.array(_CROSSINGS_U)


def turning_number(vertices: np.ndarray, label: str = "the closed polyline") -> int:
    """Turning number of a closed polyline: total signed exterior angle over ``2 pi`` (Remark 10).

    Parameters
    ----------
    vertices : (n, 2) array_like of float
        The vertices of the closed polyline, each once (the last is joined to the first).
    label : str, optional
        What the polyline is, for error messages (``"the deformed polyline of component 'A'"``).

    Returns
    -------
    int
        ``+1`` for a counterclockwise simple loop, ``-1`` clockwise, ``2`` for a
        doubly covered circle, ``0`` for a figure eight.

    Examples
    --------
    >>> turning_number([[0, 0], [1, 0], [1, 1], [0, 1]])
    1
    >>> turning_number([[0, 0], [0, 1], [1, 1], [1, 0]])
    -1
    """
    _, e, cross, dot = _turns(vertices)
    if len(e) < 2:
        raise DegenerateError(
            f"{label} has fewer than two segments of positive length: no turning number; give it at least two "
            "distinct vertices"
        )
    ang = np.arctan2(cross, dot)
    back = (cross == 0) & (dot < 0)  # exact reversal: +-pi decided by the perturbation
    if back.any():
        side = np.sign(e[back, 0] * _U[1] - e[back, 1] * _U[0])
        side[side == 0] = 1.0
        ang[back] = np.pi * side
    total = ang.sum() / (2 * np.pi)
    k = int(np.rint(total))
    if abs(total - k) > 1e-6:  # pragma: no cover - the exterior angles of a closed polyline add up to 2 pi k
        raise SceneError(f"turning number is not an integer ({total}); the polyline is not closed")
    return k


def exact_reversals(vertices: np.ndarray) -> np.ndarray:
    """Vertices where a closed polyline turns exactly back on itself (exterior angle ``+-pi``): a spike.

    Zero-length segments are skipped, as in :func:`turning_number`.

    Parameters
    ----------
    vertices : (n, 2) array_like of float
        The vertices of the closed polyline, each once.

    Returns
    -------
    ndarray of int
        The indices (into ``vertices``) of the tips, in order.
    """
    keep, e, cross, dot = _turns(vertices)
    if len(e) < 2:
        return np.empty(0, dtype=int)
    tips = np.roll(keep, -1)[(cross == 0) & (dot < 0)]  # the vertex that starts the next kept segment
    return np.sort(tips)


def _turns(vertices: np.ndarray):
    """The segments of positive length of a closed polyline and the turn from each to the next.

    Returns ``(keep, e, cross, dot)``: the indices of the segments kept
    (segment ``k`` runs from vertex ``k`` to ``k + 1``), their vectors, and
    the cross and dot products of each with the next kept one.
    """
    v = np.asarray(vertices, dtype=float)
    e = np.roll(v, -1, axis=0) - v
    keep = np.flatnonzero(np.hypot(e[:, 0], e[:, 1]) > 0)
    e = e[keep]
    e_next = np.roll(e, -1, axis=0)
    return keep, e, e[:, 0] * e_next[:, 1] - e[:, 1] * e_next[:, 0], (e * e_next).sum(axis=1)


def winding_number(vertices: np.ndarray, point: np.ndarray, label: str = "the closed polyline") -> int:
    """Winding number of a closed polyline around a point.

    Parameters
    ----------
    vertices : (n, 2) array_like of float
        The closed polyline (last vertex joined to the first).
    point : (2,) array_like of float
        A point not on the polyline.
    label : str, optional
        What the polyline is, for error messages.

    Returns
    -------
    int

    Raises
    ------
    DegenerateError
        If the point lies on the polyline.

    Examples
    --------
    >>> winding_number([[0, 0], [1, 0], [1, 1], [0, 1]], [0.5, 0.5])
    1
    >>> winding_number([[0, 0], [1, 0], [1, 1], [0, 1]], [2.0, 0.5])
    0
    """
    v = np.asarray(vertices, dtype=float) - np.asarray(point, dtype=float)
    w = np.roll(v, -1, axis=0)
    cross = v[:, 0] * w[:, 1] - v[:, 1] * w[:, 0]
    dot = (v * w).sum(axis=1)
    on = (cross == 0) & (dot <= 0)
    if on.any():
        k = int(np.flatnonzero(on)[0])
        raise DegenerateError(
            f"the point {np.asarray(point).tolist()} lies on segment {k} (vertices {k} and {(k + 1) % len(v)}) of "
            f"{label}: its winding number is not defined; the curves overlap there: move a vertex off the other "
            "curve"
        )
    total = np.arctan2(cross, dot).sum() / (2 * np.pi)
    return int(np.rint(total))
