r"""Figures: a scene with its signed crossings, and the pair domains of ``M x M`` with the curves ``gamma``.

``import direct`` does not load this module, and this module loads
matplotlib only inside its functions.  Each function draws on ``ax`` (the
current axes when None) and returns what it drew, in the manner of
``shapely.plotting``:

* :func:`plot_scene` -- the reference embedding ``j`` (dashed) and the
  deformation ``phi`` (solid) with the signed crossings, in the spirit of the
  paper's Figure 2;
* :func:`plot_domain` -- one pair domain ``M_i x M_j`` in parameters
  ``(x1, x2)``: its boundary (and the diagonal when ``i == j``), the signed
  crossing points and the optimal curves ``gamma`` of a :class:`direct.Penalty`,
  in the spirit of Figure 4;
* :func:`plot_penalty` -- a whole figure: the scene beside every domain that
  carries crossings.

Sign convention (as in :mod:`direct.penalty`): a point ``(x1, x2)`` of
``I_i x I_j`` has sign ``s = sign det(phi'(x1), phi'(x2))``; a curve ``gamma``
runs from a negative point (``gamma(0)``) to a positive one (``gamma(1)``) or
ends freely on the boundary.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from .errors import SceneError
from .penalty import rounded_up

__all__ = ["plot_scene", "plot_domain", "plot_penalty"]

#: colours of the positive and negative points
_POS, _NEG = "#d62728", "#1f77b4"
#: a filled horizontal bar: the marker of negative points
_MINUS = [(-1.0, -0.28), (1.0, -0.28), (1.0, 0.28), (-1.0, 0.28), (-1.0, -0.28)]


def _unit(v: np.ndarray) -> np.ndarray:
    n = float(np.hypot(*v))
    return v / n if n > 0 else np.zeros(2)


def _align(direction: np.ndarray) -> dict[str, str]:
    """Text alignment for a label offset from its anchor in ``direction`` (a unit vector)."""
    x, y = direction
    return {
        "ha": "left" if x > 0.38 else "right" if x < -0.38 else "center",
        "va": "bottom" if y > 0.38 else "top" if y < -0.38 else "center",
    }


def _axes(ax):
    if ax is None:
        import matplotlib.pyplot as plt

        ax = plt.gca()
    return ax


def _resolve(scene):
    from .scenes import resolve

    return resolve(scene)


def _sign_markers(ax, pts: np.ndarray, signs: np.ndarray, size: float = 110, alpha: float = 1.0, label: bool = True):
    """Scatter positive points as red pluses and negative ones as blue bars; return the artists."""
    out = []
    pts = np.asarray(pts, dtype=float).reshape(-1, 2)
    signs = np.asarray(signs).reshape(-1)
    for s, colour, marker, text in ((1, _POS, "P", "positive point"), (-1, _NEG, _MINUS, "negative point")):
        sel = signs == s
        if not sel.any():
            continue
        out.append(
            ax.scatter(
                pts[sel, 0],
                pts[sel, 1],
                s=size,
                c=colour,
                marker=marker,
                edgecolors="white",
                linewidths=0.8,
                alpha=alpha,
                zorder=5,
                label=text if label else None,
            )
        )
    return out


def _legend_below(ax, handles):
    """A legend under the axis label, a fixed distance below the axes whatever their height."""
    from matplotlib.transforms import offset_copy

    below = offset_copy(ax.transAxes, fig=ax.figure, y=-36, units="points")
    return ax.legend(
        handles=handles, loc="upper left", bbox_to_anchor=(0.0, 0.0), bbox_transform=below,
        fontsize=8, ncol=2, frameon=False,
    )


def plot_scene(scene, crossings=None, ax=None) -> list[Any]:
    """Draw a scene: reference (light, dashed), deformation (solid) and the signed crossings.

    Parameters
    ----------
    scene : Scene or str
        The scene (a JSON path or built-in name is resolved).
    crossings : list of Crossing, optional
        The crossings to mark; found with :func:`direct.find_crossings` when None.
    ax : matplotlib.axes.Axes, optional
        Where to draw; the current axes when None.

    Returns
    -------
    list of matplotlib.artist.Artist
        The lines, markers and labels drawn.

    Notes
    -----
    Each component is drawn in its own colour, with an arrow at the end of
    its deformed polyline (the orientation that defines the signs) and its
    name at the arrow.  A crossing ``phi(x1) = phi(x2)`` of components
    ``(i, j)`` is marked by its sign ``sign det(phi'(x1), phi'(x2))``: a red
    plus for ``+1``, a blue bar for ``-1``, and its index ``#k`` (the order of
    :attr:`direct.Penalty.crossings`).
    """
    from matplotlib.lines import Line2D

    scene = _resolve(scene)
    ax = _axes(ax)
    if crossings is None:
        from .crossings import find_crossings

        crossings = find_crossings(scene)
    # component colours avoid blue and red, the colours of the signs
    colours = [("C2", "C4", "C1", "C5", "C6", "C8", "C9", "C7")[k % 8] for k in range(len(scene.components))]
    artists: list[Any] = []
    for comp, colour in zip(scene.components, colours, strict=True):
        ref, dfm = comp.reference_ring, comp.deformed_ring
        artists += ax.plot(ref[:, 0], ref[:, 1], ls="--", lw=1.2, color=colour, alpha=0.45, zorder=1)
        artists += ax.plot(
            dfm[:, 0],
            dfm[:, 1],
            ls="-",
            lw=2.2,
            color=colour,
            marker="o",
            ms=3,
            zorder=2,
            label=f"{comp.name} (deformed)",
        )
        tail, head = dfm[-2], dfm[-1]
        artists.append(
            ax.annotate(
                "",
                xy=head,
                xytext=tail + 0.75 * (head - tail),
                arrowprops=dict(arrowstyle="-|>", color=colour, lw=2.2, mutation_scale=18),
                zorder=3,
            )
        )
        artists.append(
            ax.annotate(
                comp.name,
                xy=head,
                xytext=(6, 4),
                textcoords="offset points",
                color=colour,
                fontsize=11,
                fontweight="bold",
            )
        )
        artists.append(
            ax.annotate(
                f"{comp.name} (ref.)",
                xy=ref[-1],
                xytext=(6, -10),
                textcoords="offset points",
                color=colour,
                alpha=0.7,
                fontsize=9,
            )
        )
    if crossings:
        pts = np.array([c.point for c in crossings], dtype=float)
        signs = np.array([c.sign for c in crossings])
        artists += _sign_markers(ax, pts, signs, label=False)
        for k, (c, p) in enumerate(zip(crossings, pts, strict=True)):
            artists.append(
                ax.annotate(
                    f"#{k}",
                    xy=p,
                    xytext=(7, -14),
                    textcoords="offset points",
                    fontsize=9,
                    color=_POS if c.sign > 0 else _NEG,
                )
            )
    handles = [Line2D([], [], color="0.4", ls="--", lw=1.2, alpha=0.6, label="reference j")]
    handles += [
        Line2D([], [], color=col, lw=2.2, label=f"{c.name}: deformation \u03c6")
        for c, col in zip(scene.components, colours, strict=True)
    ]
    present = {int(c.sign) for c in crossings}
    if 1 in present:
        handles.append(Line2D([], [], ls="", marker="P", ms=10, mfc=_POS, mec="white", label="crossing, sign +1"))
    if -1 in present:
        handles.append(
            Line2D([], [], ls="", marker=_MINUS, ms=10, mfc=_NEG, mec="white", label="crossing, sign \u22121")
        )
    artists.append(_legend_below(ax, handles))
    ax.set_aspect("equal", adjustable="datalim")
    ax.margins(0.08)
    ax.grid(True, color="0.92", zorder=0)
    ax.set_axisbelow(True)
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    n = len(crossings)
    ax.set_title(
        f"{scene.name or 'scene'}: {n} crossing{'s' if n != 1 else ''}"
        + (" (sign of det(\u03c6'(x1), \u03c6'(x2)))" if n else ""),
        fontsize=10,
    )
    return artists


def _index(scene, c) -> int:
    """Index of component ``c`` (an index or a name) in ``scene``."""
    if isinstance(c, str):
        return scene.index(c)
    if isinstance(c, (int, np.integer)) and not isinstance(c, bool) and 0 <= c < len(scene.components):
        return int(c)
    raise SceneError(f"no component {c!r}: give an index from 0 to {len(scene.components) - 1} or one of the names "
                     f"{[comp.name for comp in scene.components]}")


def _check_result(result, scene) -> None:
    """Refuse a result computed on another scene (its components' names not all in ``scene``)."""
    names = {c.name for c in scene.components}
    used = {name for p in result.pairs for name in p.components}
    crossing_ids = {int(v) for c in result.crossings for v in c.components}
    if not used <= names or (crossing_ids and max(crossing_ids) >= len(scene.components)):
        raise SceneError(f"this result does not belong to scene {scene.name or '(unnamed)'!r}: its curves run on "
                         f"components {sorted(used)}, the scene has {sorted(names)}; pass the scene it was computed on")


def _kind(ci, cj, same: bool) -> str:
    """Name the kind of the piece ``M_i x M_j`` (as in :mod:`direct.grid`)."""
    if same:
        return "annulus" if ci.closed else "triangle"
    if ci.closed and cj.closed:
        return "torus"
    return "cylinder" if (ci.closed or cj.closed) else "rect"


def _domain_points(result, i: int, j: int, kind: str):
    """Signed points of the piece ``M_i x M_j`` (half ``x1 < x2`` of a triangle) and of the triangle's mirror half.

    Returns the points, signs and crossing indices drawn in full, then the
    points and signs of the mirror half (empty unless ``kind == "triangle"``).
    The annulus ``S^1 x S^1`` minus the diagonal holds both points of each crossing.
    """
    pts, signs, ids, mpts, msigns = [], [], [], [], []
    for k, c in enumerate(result.crossings):
        a, b = (int(v) for v in c.components)
        if {a, b} != {i, j}:
            continue
        x1, x2 = (float(v) for v in c.params)
        s = int(c.sign)
        if (a, b) != (i, j):  # the mirror point: coordinates swapped, sign reversed
            x1, x2, s = x2, x1, -s
        if kind == "triangle" and x1 > x2:
            x1, x2, s = x2, x1, -s
        pts.append((x1, x2))
        signs.append(s)
        ids.append(k)
        if kind == "triangle":
            mpts.append((x2, x1))
            msigns.append(-s)
        elif kind == "annulus":
            pts.append((x2, x1))
            signs.append(-s)
            ids.append(k)
    return (
        np.array(pts, dtype=float).reshape(-1, 2),
        np.array(signs, dtype=int),
        np.array(ids, dtype=int),
        np.array(mpts, dtype=float).reshape(-1, 2),
        np.array(msigns, dtype=int),
    )


def _wrap(path: np.ndarray, periods: tuple[float | None, float | None]) -> list[np.ndarray]:
    """Read an unwrapped path modulo the circle lengths; split it where it jumps across a seam."""
    path = np.array(path, dtype=float)
    cut = np.zeros(len(path) - 1, dtype=bool)
    for axis, period in enumerate(periods):
        if period:
            path[:, axis] = np.mod(path[:, axis], period)
            cut |= np.abs(np.diff(path[:, axis])) > 0.5 * period
    return np.split(path, np.flatnonzero(cut) + 1)


def plot_domain(result, scene, pair=(0, 1), ax=None, background: bool = True) -> list[Any]:
    r"""Draw one pair domain of ``M x M`` with its signed points and the optimal curves ``gamma``.

    Parameters
    ----------
    result : Penalty
        The result of :func:`direct.penalty` for ``scene``.
    scene : Scene or str
        The scene.
    pair : tuple of (int or str), default (0, 1)
        Components ``(i, j)`` (indices or names): ``x1`` runs along ``i``,
        ``x2`` along ``j``.  For an interval with itself the half ``x1 < x2``
        is drawn with its curves and the mirror half ``x1 > x2`` is shaded.
    ax : matplotlib.axes.Axes, optional
        Where to draw; the current axes when None.
    background : bool, default True
        Shade the level sets of ``|r_phi(x)|^2 = |phi(x1) - phi(x2)|^2``, the
        factor that makes the metric vanish at the crossings.

    Returns
    -------
    list of matplotlib.artist.Artist
        The artists drawn.

    Notes
    -----
    Thick black lines are the boundary ``\partial(M x M)`` and, for a
    component with itself, the diagonal ``Delta(M)``: the curves may end
    there freely (eq. (9)); such ends are drawn as open squares.  Along a
    circle the two opposite sides are identified (dashed grey seams) and the
    curves are drawn modulo the circle's length.  Each curve runs from a
    negative point (blue bar, ``gamma(0)``) to a positive one (red plus,
    ``gamma(1)``); its arrow shows that direction and its label gives its
    length in the metric.
    """
    from matplotlib.lines import Line2D
    from matplotlib.patches import Polygon

    scene = _resolve(scene)
    _check_result(result, scene)
    if not isinstance(pair, (tuple, list)) or len(pair) != 2:
        raise SceneError(f"pair must name two components (i, j), got {pair!r}")
    ax = _axes(ax)
    i, j = (_index(scene, c) for c in pair)
    ci, cj = scene.components[i], scene.components[j]
    Li, Lj = ci.length, cj.length
    kind = _kind(ci, cj, i == j)
    periods = (Li if ci.closed else None, Lj if cj.closed else None)
    artists: list[Any] = []

    if background:
        n1 = max(16, int(round(160 * Li / max(Li, Lj))))
        n2 = max(16, int(round(160 * Lj / max(Li, Lj))))
        x1, x2 = np.linspace(0, Li, n1), np.linspace(0, Lj, n2)
        r = ci.phi(x1)[None, :, :] - cj.phi(x2)[:, None, :]
        r2 = np.einsum("...k,...k->...", r, r)
        levels = np.linspace(0, float(r2.max()) or 1.0, 13)
        artists.append(ax.contourf(x1, x2, r2, levels=levels, cmap="Greys_r", alpha=0.22, zorder=0))
        artists.append(ax.contour(x1, x2, r2, levels=levels[1:-1], colors="0.55", linewidths=0.5, alpha=0.6, zorder=0))

    # sides: ground (solid black) along an interval's ends, seams (dashed grey) along a circle
    seam = dict(color="0.45", lw=1.4, ls=(0, (5, 3)), zorder=2)
    ground = dict(color="k", lw=2.5, zorder=2)
    artists += ax.plot([0, 0], [0, Lj], **(seam if ci.closed else ground))
    artists += ax.plot([Li, Li], [0, Lj], **(seam if ci.closed else ground))
    artists += ax.plot([0, Li], [0, 0], **(seam if cj.closed else ground))
    artists += ax.plot([0, Li], [Lj, Lj], **(seam if cj.closed else ground))
    if i == j:
        artists += ax.plot([0, Li], [0, Li], **ground)
    if kind == "triangle":
        mirror = Polygon(
            [(0, 0), (Li, 0), (Li, Li)],
            closed=True,
            facecolor="0.93",
            edgecolor="0.72",
            linewidth=0,
            hatch="/",
            zorder=1,
        )
        artists.append(ax.add_patch(mirror))
        box = dict(boxstyle="round,pad=0.3", facecolor="white", edgecolor="none", alpha=0.85)
        artists.append(
            ax.text(
                0.62 * Li,
                0.25 * Li,
                "mirror half\nx1 > x2",
                ha="center",
                va="center",
                fontsize=8,
                color="0.3",
                bbox=box,
                zorder=3,
            )
        )

    pts, signs, ids, mpts, msigns = _domain_points(result, i, j, kind)
    artists += _sign_markers(ax, mpts, msigns, size=70, alpha=0.3, label=False)
    artists += _sign_markers(ax, pts, signs, label=False)

    names = (ci.name, cj.name)
    curves = []
    for pr in result.pairs:
        if tuple(pr.components) != names or len(pr.path) < 2:
            continue
        if kind == "triangle" and (pr.path[:, 0] - pr.path[:, 1]).mean() > 0:
            continue  # the mirror curve, in the shaded half
        curves.append(pr)
    # a family may use the same curve several times (a flux of 2 through a circle): draw it once, say how often
    copies: dict[tuple, int] = {}
    for pr in curves:
        key = (round(pr.length, 12), pr.path.shape, tuple(np.round(pr.path[[0, -1]], 9).ravel()))
        copies[key] = copies.get(key, 0) + 1
    ends = []  # (point, direction into the curve) at each end of each curve
    for pr in curves:
        key = (round(pr.length, 12), pr.path.shape, tuple(np.round(pr.path[[0, -1]], 9).ravel()))
        times = copies.pop(key, 0)
        if times == 0:
            continue  # drawn already
        path = np.asarray(pr.path, dtype=float)
        for piece in _wrap(path, periods):
            artists += ax.plot(piece[:, 0], piece[:, 1], color="#2ca02c", lw=2.2, zorder=4)
        seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        m = int(np.clip(np.searchsorted(cum, 0.5 * cum[-1]), 1, len(path) - 1))
        tangent = _unit(path[m] - path[m - 1])
        mid = _wrap(path[m : m + 1], periods)[0][0]
        artists.append(
            ax.annotate(
                "",
                xy=mid,
                xytext=mid - 1e-3 * max(Li, Lj) * tangent,
                arrowprops=dict(arrowstyle="-|>", color="#2ca02c", lw=0, mutation_scale=16),
                zorder=4,
            )
        )
        # the length label sits beside the middle of the curve, on the side that faces the middle of the domain
        towards = np.array([-tangent[1], tangent[0]])
        centre = np.array([0.5 * Li, 0.5 * Lj]) - mid
        if towards @ centre < 0:
            towards = -towards
        align = _align(towards)  # and a label level with the curve's middle extends towards the centre
        if align["ha"] == "center":
            align["ha"] = "left" if centre[0] > 0 else "right"
        if align["va"] == "center":
            align["va"] = "bottom" if centre[1] > 0 else "top"
        label = (
            f"\u2113 = {pr.length:.4g}"
            + (" (closed)" if pr.closed else "")
            + (f" (\u00d7{times})" if times > 1 else "")
        )
        artists.append(
            ax.annotate(
                label,
                xy=mid,
                xytext=tuple(12 * towards),
                textcoords="offset points",
                **align,
                fontsize=8,
                color="#1a6b1a",
                zorder=6,
            )
        )
        step = max(1, len(path) // 8)
        for end, inner, point in ((0, min(len(path) - 1, step), pr.start), (-1, -1 - step, pr.end)):
            here = _wrap(path[end:][:1], periods)[0][0]
            ends.append((here, path[inner] - path[end]))
            if point is None and not pr.closed:
                artists += ax.plot(*here, ls="", marker="s", ms=8, mfc="white", mec="k", mew=1.5, zorder=5)

    # each point's index goes on the side away from the curves that leave it
    for p, k in zip(pts, ids, strict=True):
        away = -sum((_unit(d) for q, d in ends if np.allclose(q, p, atol=1e-9 * max(Li, Lj))), np.zeros(2))
        away = _unit(away) if away.any() else np.array([0.6, 0.8])
        artists.append(
            ax.annotate(
                f"#{k}", xy=p, xytext=tuple(11 * away), textcoords="offset points", **_align(away), fontsize=9, zorder=6
            )
        )

    wall = {
        "rect": "boundary",
        "triangle": "boundary and diagonal",
        "cylinder": "end circles",
        "annulus": "diagonal",
        "torus": "",
    }[kind]
    handles = [Line2D([], [], label=f"{wall} (ground)", **ground)] if wall else []
    if ci.closed or cj.closed:
        handles.append(Line2D([], [], label="seam (sides identified)", **seam))
    present = set(signs.tolist()) | set(msigns.tolist())  # the mirror half's points are drawn faintly
    if -1 in present:
        handles.append(
            Line2D([], [], ls="", marker=_MINUS, ms=10, mfc=_NEG, mec="white", label="negative point \u03b3(0)")
        )
    if 1 in present:
        handles.append(
            Line2D([], [], ls="", marker="P", ms=10, mfc=_POS, mec="white", label="positive point \u03b3(1)")
        )
    if curves:
        handles.append(Line2D([], [], color="#2ca02c", lw=2.2, label="optimal curve \u03b3"))
    if any((p.start is None or p.end is None) and not p.closed for p in curves):
        handles.append(Line2D([], [], ls="", marker="s", ms=8, mfc="white", mec="k", mew=1.5, label="free end"))
    artists.append(_legend_below(ax, handles))
    ax.set_aspect("equal")
    pad = 0.04 * max(Li, Lj)
    ax.set_xlim(-pad, Li + pad)
    ax.set_ylim(-pad, Lj + pad)
    ax.set_xlabel(f"x1 on {ci.name}" + (" (circle)" if ci.closed else ""))
    ax.set_ylabel(f"x2 on {cj.name}" + (" (circle)" if cj.closed else ""))
    note = {
        "triangle": " (half x1 < x2)",
        "annulus": " minus the diagonal",
        "torus": " (torus)",
        "cylinder": " (cylinder)",
        "rect": "",
    }[kind]
    total = sum(p.length for p in curves)
    ax.set_title(
        f"{ci.name} \u00d7 {cj.name}{note}: {len(pts)} point{'s' if len(pts) != 1 else ''}, curves {total:.4g}"
        + ("\nbackground: level sets of " + r"$|r_\varphi(x)|^2$" if background else ""),
        fontsize=10,
    )
    return artists


def plot_penalty(result, scene, path: str | os.PathLike | None = None):
    """Draw a figure: the scene on the left, then every pair domain that carries crossings or curves.

    Parameters
    ----------
    result : Penalty
        The result of :func:`direct.penalty` for ``scene``.
    scene : Scene or str
        The scene.
    path : str or path-like, optional
        Save the figure there (format from the extension, 150 dpi).

    Returns
    -------
    matplotlib.figure.Figure
        With ``1 + n`` axes, ``n`` the number of pair domains ``i <= j`` that
        carry crossing points or curves ``gamma`` (a circle may need curves
        without any crossing, section 3.3.4).

    Notes
    -----
    Only the pieces ``i <= j`` of ``M x M`` are drawn (the half ``x1 < x2``
    of ``I_i x I_i``): the map ``(x1, x2) -> (x2, x1)`` carries them onto the
    others, reversing the signs, so the mirror curves have the same lengths.
    The value in the title counts all of ``M x M`` (eq. (34)).
    """
    import matplotlib.pyplot as plt

    scene = _resolve(scene)
    _check_result(result, scene)
    index = {c.name: k for k, c in enumerate(scene.components)}
    pairs = sorted(
        {tuple(sorted(int(v) for v in c.components)) for c in result.crossings}
        | {tuple(sorted(index[name] for name in p.components)) for p in result.pairs}
    )
    n = 1 + len(pairs)
    ncols = min(n, 4)
    nrows = -(-n // ncols)
    fig = plt.figure(figsize=(5.2 * ncols, 5.0 * nrows + 0.6), layout="constrained")
    ax0 = fig.add_subplot(nrows, ncols, 1)
    plot_scene(scene, result.crossings, ax=ax0)
    for k, (i, j) in enumerate(pairs):
        plot_domain(result, scene, (i, j), ax=fig.add_subplot(nrows, ncols, k + 2))
    s = result.settings
    extra = ", ".join(
        f"{k} = {v:g}" if isinstance(v, float) else f"{k} = {v}" for k, v in s.items() if k in ("q", "p", "h")
    )
    head = (
        f"{scene.name or 'scene'}:  $J^{{{s.get('metric', '?')}}}$ = {result.value!r} \u00b1 "
        f"{rounded_up(result.error_estimate)}   (metric {s.get('metric', '?')}{', ' + extra if extra else ''})"
    )
    if pairs:
        head += (
            "\nright: the pieces i \u2264 j of M \u00d7 M; the others are their mirror images (x1 \u2194 x2, "
            "signs reversed), with the same curves, all counted in J"
        )
    else:
        head += "\nno crossing, no curve"
    fig.suptitle(head, fontsize=11)
    if path is not None:
        fig.savefig(path, dpi=150, bbox_inches="tight")
    return fig
