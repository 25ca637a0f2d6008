"""Scenes: the body M, its reference embedding j and its deformation phi.

A :class:`Scene` is a tuple of :class:`Component`.  Each component is a
polyline, open (an interval of M) or closed (a circle of M), given twice with
the same vertices (material points): its reference embedding ``j`` and its
deformation ``phi`` (section 2 of the paper).  Between vertices both maps are
affine.

The parameter of a component is the arclength of its *reference* polyline:
vertex ``k`` sits at ``params[k]``, ``params[0] = 0`` and the component is
the interval ``[0, length]`` (the circle ``R / length Z`` when closed).  This
matters for the non-degenerate metric ``g`` of section 3.4.2 only; ``G`` is
invariant under reparametrization (Prop. 18).

Scene files are JSON::

    {"components": [{"name": "A", "closed": false,
                     "reference": [[x, y], ...],
                     "deformed":  [[x, y], ...]}, ...]}
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from functools import cached_property
from typing import Any, Iterable

import numpy as np

from .errors import SceneError, SceneFileError

__all__ = ["Component", "Scene", "load_scene"]


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Component:
    """One component of M: a polyline with its reference and deformed vertices.

    Parameters
    ----------
    reference : (n, 2) array_like of float
        Vertices of the reference embedding ``j`` (length units).
    deformed : (n, 2) array_like of float
        The same material points after the deformation ``phi``.
    closed : bool, default False
        True for a circle of M: the last vertex is joined to the first.  A
        repeated closing vertex (first == last in both arrays, or in the one
        array that has a vertex more) is dropped.
    name : str, optional
        Used in messages and figures; defaults to ``"C<index>"`` in a scene.

    Notes
    -----
    Construction validates the input (see :mod:`direct.checks`) and raises
    :class:`direct.SceneError` naming the vertex at fault.
    """

    reference: np.ndarray
    deformed: np.ndarray
    closed: bool = False
    name: str = ""

    def __post_init__(self) -> None:
        from .checks import check_component

        ref, dfm = check_component(self.reference, self.deformed, self.closed, self.name)
        object.__setattr__(self, "reference", _frozen(ref))
        object.__setattr__(self, "deformed", _frozen(dfm))
        object.__setattr__(self, "closed", bool(self.closed))

    # -- derived geometry -------------------------------------------------------
    @property
    def n_vertices(self) -> int:
        """Number of distinct vertices (material points)."""
        return len(self.reference)

    @property
    def n_segments(self) -> int:
        """Number of segments: ``n - 1`` when open, ``n`` when closed."""
        return self.n_vertices if self.closed else self.n_vertices - 1

    def _ring(self, a: np.ndarray) -> np.ndarray:
        return np.vstack([a, a[:1]]) if self.closed else a

    @cached_property
    def reference_ring(self) -> np.ndarray:
        """(n_segments + 1, 2) reference vertices, first vertex repeated when closed."""
        return _frozen(self._ring(self.reference))

    @cached_property
    def deformed_ring(self) -> np.ndarray:
        """(n_segments + 1, 2) deformed vertices, first vertex repeated when closed."""
        return _frozen(self._ring(self.deformed))

    @cached_property
    def segment_lengths(self) -> np.ndarray:
        """(n_segments,) reference lengths of the segments (length units)."""
        return _frozen(np.linalg.norm(np.diff(self.reference_ring, axis=0), axis=1))

    @cached_property
    def params(self) -> np.ndarray:
        """(n_segments + 1,) reference arclength of each vertex; the last is :attr:`length`."""
        return _frozen(np.concatenate([[0.0], np.cumsum(self.segment_lengths)]))

    @property
    def length(self) -> float:
        """Reference length of the component (length units)."""
        return float(self.params[-1])

    @cached_property
    def velocities(self) -> np.ndarray:
        """(n_segments, 2) derivative ``phi'`` on each segment, per unit reference arclength."""
        d = np.diff(self.deformed_ring, axis=0)
        return _frozen(d / self.segment_lengths[:, None])

    def segment_index(self, s: np.ndarray) -> np.ndarray:
        """Index of the segment that contains each parameter ``s`` (clipped to the ends).

        A parameter on a vertex belongs to the segment that starts there,
        except the last vertex of an open component.

        Parameters
        ----------
        s : (...,) array_like of float
            Reference arclength parameters (length units).

        Returns
        -------
        (...,) ndarray of int
            Segment indices in ``[0, n_segments - 1]``.
        """
        k = np.searchsorted(self.params, np.asarray(s, dtype=float), side="right") - 1
        return np.clip(k, 0, self.n_segments - 1)

    def phi(self, s: np.ndarray) -> np.ndarray:
        """Evaluate the deformation at reference arclength ``s``.

        Parameters
        ----------
        s : (...,) array_like of float
            Parameters in ``[0, length]`` (taken modulo ``length`` when closed).

        Returns
        -------
        (..., 2) ndarray of float
            Deformed positions.
        """
        return self._along(self.deformed_ring, self.velocities, s)

    def j(self, s: np.ndarray) -> np.ndarray:
        """Evaluate the reference embedding at reference arclength ``s``.

        Parameters
        ----------
        s : (...,) array_like of float
            Parameters in ``[0, length]`` (taken modulo ``length`` when closed).

        Returns
        -------
        (..., 2) ndarray of float
            Reference positions.
        """
        return self._along(self.reference_ring, np.diff(self.reference_ring, axis=0) / self.segment_lengths[:, None], s)

    def _along(self, ring: np.ndarray, speeds: np.ndarray, s) -> np.ndarray:
        """The polyline ``ring`` (closing vertex included) at reference arclength ``s``, with per-segment ``speeds``."""
        s = np.asarray(s, dtype=float)
        if self.closed:
            s = np.mod(s, self.length)
        k = self.segment_index(s)
        return ring[k] + (s - self.params[k])[..., None] * speeds[k]

    def reference_arclength(self, s) -> np.ndarray:
        """The reference arclength of parameters ``s`` (the identity here; see :meth:`reparametrized`).

        Parameters
        ----------
        s : (...,) array_like of float
            Parameters of this component (unwrapped when closed).

        Returns
        -------
        (...,) ndarray of float
            The same material points in reference arclength (length units).
        """
        return np.asarray(s, dtype=float)

    def reparametrized(self, widths) -> "Component":
        """The same component with segment ``k`` spanning ``widths[k]`` of parameter instead of its reference length.

        ``J^G`` does not depend on the parametrization (Prop. 18), and its
        length element is isotropic in the deformed arclength:
        :func:`direct.penalty.penalty` computes an interval whose speeds
        ``|phi'|`` span more than 16, and a closed component whose speeds
        differ at all, in its deformed arclength and maps the curves back
        with :meth:`reference_arclength`.

        Parameters
        ----------
        widths : (n_segments,) array_like of float
            Positive parameter length of each segment.

        Returns
        -------
        Component
            The same polylines and name; :attr:`params`, :meth:`phi` and
            :meth:`j` in the new parameter, :meth:`reference_arclength` back.

        Raises
        ------
        SceneError
            If ``widths`` is not one positive finite number per segment.
        """
        w = np.asarray(widths, dtype=float)
        if w.shape != (self.n_segments,) or not (np.isfinite(w).all() and (w > 0).all()):
            raise SceneError(f"component {self.name!r}: widths must be {self.n_segments} positive finite numbers (one "
                             f"per segment), got shape {w.shape}")
        return _Reparametrized(self.reference, self.deformed, self.closed, self.name, w, self)

    def reversed(self) -> "Component":
        """The same component with its orientation reversed (reference and deformation)."""
        if self.closed:
            ref = np.vstack([self.reference[:1], self.reference[:0:-1]])
            dfm = np.vstack([self.deformed[:1], self.deformed[:0:-1]])
        else:
            ref, dfm = self.reference[::-1], self.deformed[::-1]
        return Component(ref, dfm, self.closed, self.name)

    def to_dict(self) -> dict[str, Any]:
        """The JSON form of the component."""
        return {
            "name": self.name,
            "closed": self.closed,
            "reference": self.reference.tolist(),
            "deformed": self.deformed.tolist(),
        }

    def __repr__(self) -> str:
        kind = "closed" if self.closed else "open"
        return f"Component({self.name!r}, {kind}, {self.n_vertices} vertices, length={self.length:.6g})"


@dataclass(frozen=True, eq=False, repr=False)
class _Reparametrized(Component):
    """A component whose parameter is not its reference arclength (:meth:`Component.reparametrized`)."""

    widths: np.ndarray = None
    source: Component = None

    @cached_property
    def segment_lengths(self) -> np.ndarray:
        """(n_segments,) parameter lengths of the segments."""
        return _frozen(self.widths)

    def reference_arclength(self, s) -> np.ndarray:
        """The reference arclength of parameters ``s``: affine on each segment, periodic when closed."""
        s = np.asarray(s, dtype=float)
        turns = np.floor(s / self.length) if self.closed else 0.0
        r = s - turns * self.length
        k = self.segment_index(r)
        src = self.source
        out = src.params[k] + (r - self.params[k]) * (src.segment_lengths[k] / self.segment_lengths[k])
        return out + turns * src.length


@dataclass(frozen=True, eq=False)
class Scene:
    """A body M (disjoint intervals and circles) with reference embedding and deformation.

    Parameters
    ----------
    components : iterable of Component
        The components of M.  Unnamed components are named ``C0, C1, ...``.
    name : str, optional
        A label for messages and figures.

    Raises
    ------
    SceneError
        If there is no component, if names repeat, or if the reference
        embedding is not an embedding (two reference segments meet).

    Examples
    --------
    >>> import direct
    >>> s = direct.Scene([direct.Component([[0, 0], [1, 0]], [[0, 0], [1, 0]])])
    >>> s.components[0].name
    'C0'
    """

    components: tuple[Component, ...]
    name: str = ""

    def __post_init__(self) -> None:
        from .checks import check_scene, free_name

        if isinstance(self.components, (Component, str, bytes)) or not hasattr(self.components, "__iter__"):
            raise SceneError(f"a Scene takes a sequence of direct.Component, got a {type(self.components).__name__}: "
                             "write Scene((A,)) or Scene([A, B])")
        comps = []
        taken = {getattr(c, "name", "") for c in self.components}
        for k, c in enumerate(self.components):
            if not isinstance(c, Component):
                raise SceneError(f"component {k} is a {type(c).__name__}, not a direct.Component")
            if not c.name:  # "C<k>", or with a suffix when the user gave another component that name
                name = free_name(f"C{k}", taken)
                taken.add(name)
                c = Component(c.reference, c.deformed, c.closed, name)
            comps.append(c)
        object.__setattr__(self, "components", tuple(comps))
        check_scene(self)

    @classmethod
    def from_dict(cls, data: Any, name: str = "") -> "Scene":
        """Build a scene from its JSON form (see the module docstring).

        Parameters
        ----------
        data : dict
            ``{"components": [{"name": ..., "closed": ..., "reference": ..., "deformed": ...}, ...]}``.
        name : str, default ""
            The scene's name.

        Returns
        -------
        Scene

        Raises
        ------
        SceneError
            For a malformed description or an invalid scene; the message
            names the component and vertex at fault.
        """
        from .checks import parse_scene_dict

        return cls(tuple(Component(**kw) for kw in parse_scene_dict(data)), name=name)

    def to_dict(self) -> dict[str, Any]:
        """The JSON form of the scene."""
        return {"components": [c.to_dict() for c in self.components]}

    def to_json(self, path: str | os.PathLike | None = None, indent: int | None = 1) -> str:
        """Serialize to JSON; also write it to ``path`` when given.

        Parameters
        ----------
        path : str or path-like, optional
            File to write (UTF-8, with a final newline).
        indent : int or None, default 1
            Indentation of :func:`json.dumps` (``None``: one line).

        Returns
        -------
        str
            The JSON text (what :func:`load_scene` reads back).
        """
        text = json.dumps(self.to_dict(), indent=indent)
        if path is not None:
            with open(path, "w", encoding="utf-8") as fh:
                fh.write(text + "\n")
        return text

    def index(self, name: str) -> int:
        """Index of the component called ``name``.

        Parameters
        ----------
        name : str
            A component's name.

        Returns
        -------
        int

        Raises
        ------
        SceneError
            When no component has that name (the message lists the names).
        """
        for k, c in enumerate(self.components):
            if c.name == name:
                return k
        raise SceneError(f"no component named {name!r}; the scene has {[c.name for c in self.components]}")

    def with_deformed(self, deformed: Iterable[np.ndarray]) -> "Scene":
        """The same reference with new deformed vertices, component by component.

        Parameters
        ----------
        deformed : iterable of (n_i, 2) array_like of float
            One array of deformed vertices per component, in order, each
            with as many vertices as that component's reference.

        Returns
        -------
        Scene
            A new scene with the same names, references and closedness.

        Raises
        ------
        SceneError
            When the number of arrays differs from the number of components,
            or for an invalid deformed polyline.
        """
        deformed = list(deformed)
        if len(deformed) != len(self.components):
            raise SceneError(
                f"with_deformed got {len(deformed)} deformed polylines for the {len(self.components)} components "
                f"{[c.name for c in self.components]}: give one per component, in order."
            )
        comps = [Component(c.reference, d, c.closed, c.name) for c, d in zip(self.components, deformed)]
        return Scene(tuple(comps), name=self.name)

    def __repr__(self) -> str:
        inner = ", ".join(repr(c) for c in self.components)
        return f"Scene({self.name!r}: {inner})"


def load_scene(path: str | os.PathLike) -> Scene:
    """Read a scene from a JSON file.

    Parameters
    ----------
    path : str or path-like
        A JSON file in the format of the :mod:`direct.scene` module docstring.

    Returns
    -------
    Scene

    Raises
    ------
    SceneFileError
        If the file cannot be read, is not JSON, or misses keys.
    SceneError
        If the geometry is invalid.
    """
    try:
        with open(path, encoding="utf-8-sig") as fh:  # a byte-order mark, which some editors write, is skipped
            text = fh.read()
    except OSError as err:
        raise SceneFileError(f"cannot read scene file {os.fspath(path)!r}: {err.strerror}") from err
    except UnicodeDecodeError as err:
        raise SceneFileError(
            f"scene file {os.fspath(path)!r} is not UTF-8 text (byte {err.start}: {err.reason}); save it as UTF-8 JSON"
        ) from err
    try:
        data = json.loads(text)
    except json.JSONDecodeError as err:
        raise SceneFileError(
            f"scene file {os.fspath(path)!r} is not valid JSON (line {err.lineno}, column {err.colno}: {err.msg})"
        ) from err
    except RecursionError as err:
        raise SceneFileError(f"scene file {os.fspath(path)!r} nests its JSON too deeply to be a scene") from err
    return Scene.from_dict(data, name=os.path.splitext(os.path.basename(os.fspath(path)))[0])
