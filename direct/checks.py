"""All checks of user input, in one place.

Each check raises :class:`direct.SceneError` (or :class:`direct.SceneFileError`
for the file format) with a message that names the component and the vertex at
fault and says what to do.
"""

from __future__ import annotations

import inspect
import numbers
from typing import Any

import numpy as np

from .errors import SceneError, SceneFileError

_KEYS = {"name", "closed", "reference", "deformed"}


def _label(name: str) -> str:
    return f"component {name!r}" if name else "component"


def is_real_number(x: Any) -> bool:
    """A real number (int, float, Fraction, numpy scalar, 0-d array), not a bool or a string.

    Used for vertex coordinates, and for ``power`` and ``resolution`` (:mod:`direct.metric`,
    :mod:`direct.penalty`).
    """
    if isinstance(x, (bool, np.bool_, str, bytes)):
        return False
    return isinstance(x, numbers.Real) or (isinstance(x, np.ndarray) and x.ndim == 0 and x.dtype.kind in "iuf")


def _check_vertex_list(a: Any, what: str, label: str) -> None:
    """Each vertex a pair of numbers (strings and booleans, which numpy would convert, refused), by index."""
    if not isinstance(a, (list, tuple, np.ndarray)):
        raise SceneError(f"{label}: {what} vertices must be a list of [x, y] pairs, got {type(a).__name__}")
    if not isinstance(a, np.ndarray):
        arr = np.asarray(a, dtype=object) if len(a) else np.empty((0, 2))
        if arr.ndim == 2 and arr.shape[1] == 2:  # a regular list: one pass over its entries, in C where it can
            flat = arr.ravel()
            if set(map(type, flat.tolist())) <= {float, int}:  # type(True) is bool: booleans fall through
                return
    sizes = set()
    for k, v in enumerate(a):
        if isinstance(v, np.ndarray) and v.dtype.kind in "iuf" and v.ndim == 1:
            sizes.add(len(v))
            continue
        if not (isinstance(v, (list, tuple, np.ndarray)) and all(is_real_number(x) for x in v)):
            raise SceneError(f"{label}: {what} vertex {k} is {v!r}; each vertex must be a pair [x, y] of numbers")
        sizes.add(len(v))
    if len(sizes) > 1:  # ragged: name the first vertex that is not a pair
        k = next(k for k, v in enumerate(a) if len(v) != 2)
        raise SceneError(f"{label}: {what} vertex {k} is {a[k]!r}; each vertex must be a pair [x, y] of numbers")


def _as_vertices(a: Any, what: str, label: str) -> np.ndarray:
    if isinstance(a, np.ndarray) and a.dtype.kind not in "iuf" and a.dtype != object:
        raise SceneError(f"{label}: {what} vertices must be numbers, got an array of {a.dtype}")
    if not isinstance(a, np.ndarray) or a.dtype == object:
        _check_vertex_list(a, what, label)
    try:
        arr = np.asarray(a, dtype=float)
    except (TypeError, ValueError) as err:
        raise SceneError(f"{label}: {what} vertices must be a list of [x, y] numbers ({err})") from err
    except OverflowError as err:  # an integer beyond the floats (a JSON file's 10**400): no finite coordinate
        k = next((k for k, row in enumerate(a) if any(_overflows(x) for x in row)), None)
        which = f"vertex {k}" if k is not None else "vertices"
        raise SceneError(f"{label}: {what} {which} holds an integer too large for a floating-point number "
                         f"({err}); coordinates must be finite: rescale the scene") from err
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise SceneError(f"{label}: {what} vertices must have shape (n, 2), got shape {arr.shape}")
    bad = np.flatnonzero(~np.isfinite(arr).all(axis=1))
    if bad.size:
        k = int(bad[0])
        raise SceneError(
            f"{label}: {what} vertex {k} is {arr[k].tolist()}; coordinates must be finite (no NaN or infinity)"
        )
    return arr


def _overflows(x: Any) -> bool:
    """Whether the number ``x`` does not fit in a float (an integer beyond about 1.8e308)."""
    try:
        float(x)
    except OverflowError:
        return True
    return False


def _without_closing(a: np.ndarray) -> np.ndarray:
    """The vertices without the last one when it repeats the first."""
    return a[:-1] if len(a) >= 2 and np.array_equal(a[0], a[-1]) else a


def check_component(reference: Any, deformed: Any, closed: bool, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Validate one component; return its reference and deformed vertices as float arrays.

    A closed component whose first vertex is repeated at the end (in both
    arrays, or in the one array that has a vertex more) has the repeated
    vertex dropped.
    """
    if name is None:
        name = ""
    if not isinstance(name, str):
        raise SceneError(f"a component's name must be a string, got {name!r}")
    label = _label(name)
    if not isinstance(closed, (bool, np.bool_)):
        raise SceneError(f"{label}: 'closed' must be true or false, got {closed!r}")
    ref = _as_vertices(reference, "reference", label)
    dfm = _as_vertices(deformed, "deformed", label)
    if closed:  # a repeated closing vertex goes from each array that has one, if the counts then agree
        ref_once, dfm_once = _without_closing(ref), _without_closing(dfm)
        if len(ref_once) == len(dfm_once):
            ref, dfm = ref_once, dfm_once
    if len(ref) != len(dfm):
        raise SceneError(
            f"{label}: {len(ref)} reference vertices but {len(dfm)} deformed vertices; "
            "give the same material points in both"
        )
    need = 3 if closed else 2
    if len(ref) < need:
        kind = "a closed" if closed else "an open"
        raise SceneError(f"{label}: {kind} component needs at least {need} vertices, got {len(ref)}")
    ring = np.vstack([ref, ref[:1]]) if closed else ref
    d = np.diff(ring, axis=0)
    zero = np.flatnonzero(np.hypot(d[:, 0], d[:, 1]) == 0)
    if zero.size:
        k = int(zero[0])
        k2 = (k + 1) % len(ref)
        raise SceneError(
            f"{label}: reference vertices {k} and {k2} coincide at {ref[k].tolist()}; "
            "remove the repeated vertex (a zero-length reference segment has no parameter)"
        )
    tiny = np.flatnonzero(np.linalg.norm(d, axis=1) == 0)  # apart, but the squared length underflows
    if tiny.size:
        k = int(tiny[0])
        raise SceneError(
            f"{label}: reference vertices {k} and {(k + 1) % len(ref)} are {float(np.hypot(*d[k])):.3g} apart, too "
            "close for floating point; rescale the reference (J^G does not depend on its scale) or merge them"
        )
    return ref, dfm


def _segments(scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All reference segments of a scene: (m, 2, 2) coordinates, component and segment indices."""
    segs, comp, idx = [], [], []
    for c, comp_ in enumerate(scene.components):
        r = comp_.reference_ring
        segs.append(np.stack([r[:-1], r[1:]], axis=1))
        comp.append(np.full(comp_.n_segments, c))
        idx.append(np.arange(comp_.n_segments))
    return np.concatenate(segs), np.concatenate(comp), np.concatenate(idx)


def check_scene(scene) -> None:
    """Validate a scene: at least one component, distinct names, an embedded reference.

    The reference embedding ``j`` must be one-to-one (section 2.1): no two
    reference segments may meet, except consecutive segments of one
    component at their shared vertex.
    """
    import shapely

    comps = scene.components
    if len(comps) == 0:
        raise SceneError("the scene has no component; give at least one")
    names = [c.name for c in comps]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise SceneError(f"component names must be distinct; repeated: {sorted(dup)}")
    segs, comp, idx = _segments(scene)
    lines = shapely.linestrings(segs)
    tree = shapely.STRtree(lines)
    a, b = tree.query(lines, predicate="intersects")
    keep = a < b
    a, b = a[keep], b[keep]
    # consecutive segments of one component share exactly one vertex: allowed
    same = comp[a] == comp[b]
    nseg = np.array([c.n_segments for c in comps])[comp[a]]
    closed = np.array([c.closed for c in comps])[comp[a]]
    gap = idx[b] - idx[a]
    adjacent = same & ((gap == 1) | (closed & (gap == nseg - 1)))
    if adjacent.any():
        # adjacent segments may only share their common vertex
        inter = shapely.intersection(lines[a[adjacent]], lines[b[adjacent]])
        only_point = shapely.get_type_id(inter) == 0
        bad_adj = np.flatnonzero(adjacent)[~only_point]
    else:
        bad_adj = np.array([], dtype=int)
    bad = np.sort(np.concatenate([np.flatnonzero(~adjacent), bad_adj]))
    if bad.size:
        k = int(bad[0])
        ca, cb = comps[comp[a[k]]], comps[comp[b[k]]]
        ia, ib = int(idx[a[k]]), int(idx[b[k]])
        where = shapely.intersection(lines[a[k]], lines[b[k]])
        pt = shapely.get_coordinates(where)[0].tolist()
        ea = (ia + 1) % ca.n_vertices if ca.closed else ia + 1
        eb = (ib + 1) % cb.n_vertices if cb.closed else ib + 1
        if ca is not cb:
            fix = "move the components apart"
        elif ca.closed:
            fix = ("make its reference a simple polygon; a closing vertex repeated only up to rounding is not "
                   "dropped: repeat the first vertex exactly, or leave it out")
        else:
            fix = "make its reference a simple polyline"
        raise SceneError(
            "the reference is not an embedding: "
            f"segment {ia} (vertices {ia}-{ea}) of component {ca.name!r} meets "
            f"segment {ib} (vertices {ib}-{eb}) of component {cb.name!r} "
            f"near {pt}; the reference configuration j must not touch itself ({fix})"
        )


def free_name(name: str, taken: set) -> str:
    """``name``, primed until it is not in ``taken``: the default name ``C<k>`` of an unnamed component."""
    while name in taken:
        name += "'"
    return name


def parse_scene_dict(data: Any) -> list[dict[str, Any]]:
    """Check the JSON structure of a scene; return the keyword arguments of each component."""
    if not isinstance(data, dict) or "components" not in data:
        raise SceneFileError('a scene is a JSON object with a "components" list: {"components": [...]}')
    from .penalty import penalty  # the options of direct.penalty, refused as top-level keys (they would be ignored)

    options = sorted(set(data) & (set(inspect.signature(penalty).parameters) - {"scene"}))
    if options:  # not read from the file: say so rather than compute with the defaults
        raise SceneFileError(
            f"a scene file holds the scene only, not the options {options}: pass them to direct.penalty "
            f"(metric=..., tol=...) or on the command line (--metric, --tol, ...); other top-level keys are ignored"
        )
    items = data["components"]
    if not isinstance(items, list):
        raise SceneFileError(f'"components" must be a list, got {type(items).__name__}')
    out = []
    for k, item in enumerate(items):
        if not isinstance(item, dict):
            raise SceneFileError(f"component {k} must be a JSON object, got {type(item).__name__}")
        missing = [key for key in ("reference", "deformed") if key not in item]
        if missing:
            raise SceneFileError(f"component {k} ({item.get('name', 'unnamed')!r}) misses the key(s) {missing}")
        unknown = set(item) - _KEYS
        if unknown:
            raise SceneFileError(
                f"component {k} ({item.get('name', 'unnamed')!r}) has unknown key(s) {sorted(unknown)}; "
                f"allowed: {sorted(_KEYS)}"
            )
        name = item["name"] if "name" in item else free_name(
            f"C{k}", {it.get("name") for it in items if isinstance(it, dict)})
        if not isinstance(name, str):
            raise SceneFileError(f"component {k}: 'name' must be a string, got {name!r}")
        out.append(
            {
                "reference": item["reference"],
                "deformed": item["deformed"],
                "closed": item.get("closed", False),
                "name": name,
            }
        )
    return out
