"""The ``direct`` command line: ``direct penalty``, ``direct plot`` and ``direct scenes``.

Usage::

    direct penalty SCENE [--metric {G,g,euclid}] [--power P] [--tol TOL] [--resolution N] [--coarsen C]
                         [--neighbours {8,16,32}] [--backend {scipy,networkx}] [--no-refine]
                         [--second-pass {auto,on,off}] [--json]
    direct plot SCENE -o FIG.png [same options as penalty, without --json]
    direct scenes
    direct --version

``SCENE`` is a JSON scene file (format in :mod:`direct.scene`) or the name of
a built-in scene (``direct scenes`` lists them).  ``python -m direct`` is the
same program.

Every error that `direct` raises on purpose (:class:`direct.DirectError`) is
reported as one line ``direct: error: <message>`` on standard error with exit
status 2, as are command-line usage errors.  Warnings (a
:class:`direct.ToleranceWarning` when the estimate exceeds the tolerance) are
printed as one line ``direct: warning (<category>): <message>`` on standard
error; the result is still printed, with exit status 0.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import sys
import warnings
from typing import Any, NoReturn, Sequence

__all__ = ["main", "build_parser"]


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line, in the same form as the other errors."""

    def error(self, message: str) -> NoReturn:
        """Report a usage error on one line of standard error and exit with status 2."""
        self.exit(2, f"direct: error: {message} (see '{self.prog} --help')\n")


def _add_method_options(p: argparse.ArgumentParser) -> None:
    """Options shared by ``penalty`` and ``plot``: the arguments of :func:`direct.penalty`."""
    p.add_argument("scene", metavar="SCENE", help="a JSON scene file or a built-in scene name (see 'direct scenes')")
    p.add_argument(
        "--metric",
        choices=["G", "g", "euclid"],
        default="G",
        help="'G': |y1 - y2|^(2q) Id (Example 14, default); 'g': g(s) = s^p (section 3.4.2); "
        "'euclid': the heuristic metric of section 3.1 (degenerate: its values are not certified; every positive "
        "value warns)",
    )
    p.add_argument("--power", type=float, default=None, metavar="P",
                   help="q of G or p of g (default 2; a real number in (0, 64])")
    p.add_argument("--tol", type=float, default=1e-3, help="relative tolerance of each refined geodesic (default 1e-3)")
    p.add_argument(
        "--resolution", type=int, default=128, metavar="N",
        help="grid cells along the longer side of a domain (128; below it the default grid is solved too; at most 8192)"
    )
    p.add_argument(
        "--coarsen", type=int, default=4, metavar="C",
        help="grid C times coarser away from the crossing points (default 4; 1: uniform grid; at most N / 2)",
    )
    p.add_argument("--neighbours", type=int, choices=[8, 16, 32], default=16, help="grid stencil (default 16)")
    p.add_argument("--backend", choices=["scipy", "networkx"], default="scipy", help="shortest-path backend")
    p.add_argument(
        "--no-refine", dest="refine", action="store_false", help="report the grid (Dijkstra) value without refinement"
    )
    p.add_argument(
        "--workers", type=int, default=1, metavar="N",
        help="processes that refine the curves (default 1; -1: one per CPU); the same value as with one (bit for "
        "bit with G, q = 2; within the estimates with the other metrics)",
    )
    p.add_argument(
        "--second-pass", choices=["auto", "on", "off"], default="auto",
        help="solve again from a second grid's routes and add the spread to the error estimate "
        "(auto: when tol <= 1e-4, when the resolution is below 128, always with euclid, and on every domain with a "
        "grazing crossing; otherwise only the chosen curves are checked against the second grid's routes; "
        "off: neither)",
    )


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser of the ``direct`` command.

    Returns
    -------
    argparse.ArgumentParser
    """
    from . import __version__

    parser = _Parser(
        prog="direct",
        description="The direct method for the topological self-contact penalty J(phi) of plane curves.",
    )
    parser.add_argument("--version", action="version", version=f"direct {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    p = sub.add_parser(
        "penalty",
        help="compute the penalty J(phi) of a scene",
        description="Compute the penalty J(phi) of a scene by the direct method (section 5.1.1).",
    )
    _add_method_options(p)
    p.add_argument("--json", action="store_true",
                   help='print one JSON object instead of the summary (its "warnings" list names each warning)')

    p = sub.add_parser(
        "plot",
        help="draw a scene, its crossings and the optimal curves gamma",
        description="Compute the penalty and draw the scene beside the pair domains that carry crossings.",
    )
    _add_method_options(p)
    p.add_argument("-o", "--output", required=True, metavar="FIG", help="figure file to write (.png, .pdf, .svg)")

    sub.add_parser("scenes", help="list the built-in scenes", description="List the built-in scenes.")
    return parser


# -- helpers -------------------------------------------------------------------------------------------------------


def _compute(args: argparse.Namespace):
    """Resolve the scene and run :func:`direct.penalty` with the command-line options."""
    from .penalty import penalty
    from .scenes import resolve

    scene = resolve(args.scene)
    result = penalty(
        scene,
        args.metric,
        power=args.power,
        tol=args.tol,
        resolution=args.resolution,
        neighbours=args.neighbours,
        coarsen=args.coarsen,
        backend=args.backend,
        refine=args.refine,
        second_pass={"auto": None, "on": True, "off": False}[args.second_pass],
        workers=args.workers,
    )
    return scene, result


def _finite(obj: Any) -> Any:
    """Replace non-finite floats by None so that the output is strict JSON."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    return obj


def _g(x: float, digits: int = 7) -> str:
    return f"{x:.{digits}g}"


def _point(p: Sequence[float] | None) -> str:
    return "boundary" if p is None else f"({_g(p[0], 6)}, {_g(p[1], 6)})"


def _symbol(settings: dict) -> str:
    """``J^G``, ``J^g`` or ``J^euclid``."""
    return f"J^{settings.get('metric', '?')}"


def _in_half(pair, scene) -> bool:
    """Tell whether a curve lies in the half ``i <= j`` of ``M x M`` (``x1 < x2`` when ``i == j``)."""
    a, b = (scene.index(n) for n in pair.components)
    if a != b:
        return a < b
    if scene.components[a].closed:
        return True  # a circle with itself is one piece, its own mirror image
    return bool((pair.path[:, 0] - pair.path[:, 1]).mean() < 0)


def _table(rows: list[list[str]], indent: str = "  ") -> list[str]:
    widths = [max(len(r[k]) for r in rows) for k in range(len(rows[0]))]
    return [indent + "  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in rows]


def summary(scene, result) -> str:
    """Write a readable summary of a :class:`direct.Penalty` (what ``direct penalty`` prints).

    Parameters
    ----------
    scene : Scene
        The scene the result was computed for.
    result : Penalty
        The result of :func:`direct.penalty`.

    Returns
    -------
    str
        The value is printed in full and every error estimate rounded up
        (:func:`direct.penalty.rounded_up`), so the printed pair keeps
        ``|value - J| <= error_estimate``.
    """
    from .penalty import rounded_up

    names = [c.name for c in scene.components]
    lines = [f"scene: {scene.name or '(unnamed)'} ({len(names)} component{'s' if len(names) != 1 else ''})"]
    rows = [
        [c.name, "closed" if c.closed else "open", f"{c.n_vertices} vertices", f"length {_g(c.length, 6)}"]
        for c in scene.components
    ]
    lines += _table(rows)
    s = result.settings
    metric = ", ".join(
        f"{k}={v}" for k, v in s.items()
        if k not in ("metric", "tol", "resolution", "neighbours", "coarsen", "backend", "refine", "second_pass",
                     "grazing_second_pass", "route_check", "refined_again")
    )
    grazing = s.get("grazing_second_pass")
    again = s.get("refined_again")
    lines.append(
        f"metric: {s.get('metric')}{f' ({metric})' if metric else ''}; tol={s.get('tol')}, "
        f"resolution={s.get('resolution')} (coarsen {s.get('coarsen')}), neighbours={s.get('neighbours')}, "
        f"backend={s.get('backend')}, "
        f"refine={s.get('refine')}, second pass={s.get('second_pass')}"
        + (" (route check of the chosen curves)" if s.get("route_check") else "")
        + (f" (grazing crossings: second pass on {grazing} domain{'s' if grazing > 1 else ''})" if grazing else "")
        + (f" (short curves refined again: {again} domain solve{'s' if again > 1 else ''})" if again else "")
    )
    lines.append("")
    n = len(result.crossings)
    lines.append(f"crossings: {n}" + (" (each gives the points (x1, x2) and (x2, x1) of M x M)" if n else ""))
    if n:
        rows = [["#", "components", "x1", "x2", "point phi(x1) = phi(x2)", "sign"]]
        for k, c in enumerate(result.crossings):
            i, j = c.components
            rows.append(
                [
                    str(k),
                    f"{names[i]} x {names[j]}",
                    _g(c.params[0], 6),
                    _g(c.params[1], 6),
                    _point(c.point),
                    "+" if c.sign > 0 else "-",
                ]
            )
        lines += _table(rows)
    lines.append("")
    lines.append(
        f"{_symbol(s)} = {result.value!r} \u00b1 {rounded_up(result.error_estimate)} "
        f"(grid Dijkstra alone: {_g(result.grid_value)})"
        if math.isfinite(result.error_estimate)
        else f"{_symbol(s)} = {_g(result.value)} (grid Dijkstra alone, no error estimate: its bias is a few per "
        "cent on most scenes, more in narrow valleys)"
    )
    if math.isfinite(result.error_estimate) and result.pairs:
        lines.append(f"upper bound (the exact length of the curves below): {rounded_up(result.upper_bound, 10)}")
    half = [p for p in result.pairs if _in_half(p, scene)]
    if half:
        lines.append(
            f"optimal curves gamma: {len(half)} on the pieces i <= j of M x M; the other pieces are their mirror "
            "images (x1 <-> x2), with curves of the same lengths, all counted in J"
        )
        rows = [["domain", "from (negative point)", "to (positive point)", "length", "error"]]
        for p in half:
            start = "boundary" if p.start is None else f"#{p.start_crossing} {_point(p.start)}"
            end = "boundary" if p.end is None else f"#{p.end_crossing} {_point(p.end)}"
            if p.closed:
                start, end = "closed curve", "-"
            rows.append([f"{p.components[0]} x {p.components[1]}", start, end, repr(p.length),
                         rounded_up(p.error_estimate)])
        lines += _table(rows)
    else:
        lines.append("no curve gamma is needed: J = 0")
    lines.append("")
    lines.append(f"time: {result.seconds:.3g} s")
    return "\n".join(lines)


def _scene_descriptions() -> dict[str, str]:
    """One-line descriptions of the built-in scenes, read from the table of the :mod:`direct.scenes` docstring."""
    from . import scenes

    desc: dict[str, str] = {}
    rules = 0
    current = None
    for line in (scenes.__doc__ or "").splitlines():
        if line.startswith("=="):
            rules += 1
            continue
        if rules != 2 or not line.strip():
            continue  # only the body of the table, between the second and third rules
        if not line[0].isspace():
            current, _, text = line.partition(" ")
            desc[current] = text.strip()
        elif current is not None:
            desc[current] += " " + line.strip()
    return desc


# -- commands ------------------------------------------------------------------------------------------------------


def _cmd_penalty(args: argparse.Namespace) -> int:
    with warnings.catch_warnings(record=True) as caught:  # the filters as they are (python -W ...)
        scene, result = _compute(args)
    for w in caught:  # still one line each on standard error, as any other warning
        _show_warning(w.message, w.category, w.filename, w.lineno)
    if args.json:
        out = {"scene": scene.name, "components": [c.name for c in scene.components], **result.to_dict(scene),
               "warnings": [{"category": w.category.__name__, "message": " ".join(str(w.message).split())}
                            for w in caught]}
        print(json.dumps(_finite(out), allow_nan=False))
    else:
        print(summary(scene, result))
    return 0


def _cmd_plot(args: argparse.Namespace) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .errors import DirectError
    from .plot import plot_penalty

    folder = os.path.dirname(os.path.abspath(args.output))
    if not os.path.isdir(folder):  # fail before the computation, not after
        raise DirectError(f"cannot write the figure to {args.output!r}: no folder {folder!r}")
    if os.path.isdir(args.output):
        raise DirectError(f"cannot write the figure to {args.output!r}: it is a folder; give a file name such as "
                          f"{os.path.join(args.output, 'figure.png')!r}")
    # matplotlib adds its default format's extension to a name without one: print the file actually written
    written = args.output
    if not os.path.splitext(args.output)[1][1:]:  # as matplotlib does: "fig" and "fig." both give fig.png
        written = args.output.rstrip(".") + "." + plt.rcParams["savefig.format"]
    scene, result = _compute(args)
    fig = plot_penalty(result, scene)
    try:
        fig.savefig(args.output, dpi=150, bbox_inches="tight")
    except (OSError, ValueError) as err:
        raise DirectError(f"cannot write the figure to {args.output!r}: {err}") from err
    finally:
        plt.close(fig)
    print(written)
    return 0


def _cmd_scenes(args: argparse.Namespace) -> int:
    from . import scenes

    desc = _scene_descriptions()
    names = scenes.names()
    width = max(len(n) for n in names)
    for n in names:
        print(f"{n.ljust(width)}  {desc.get(n, '').replace('``', '')}".rstrip())
    return 0


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Print a warning as one line ``direct: warning (Category): <message>`` on standard error."""
    text = " ".join(str(message).split())
    print(f"direct: warning ({category.__name__}): {text}", file=sys.stderr if file is None else file)


#: a negative number, in scientific notation too (argparse takes "-1e-3" for an option, so that "--tol -1e-3"
#: failed as "expected one argument" rather than with the range of tol)
_NEGATIVE = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^-(inf|infinity|nan)$", re.IGNORECASE)


def _numeric_options() -> set[str]:
    """The options of :func:`_add_method_options` whose value is a number (``--tol``, ``--power``, ...)."""
    p = argparse.ArgumentParser(add_help=False)
    _add_method_options(p)
    return {s for a in p._actions if a.type in (int, float) for s in a.option_strings}


def _joined_numbers(argv: list[str]) -> list[str]:
    """``--tol -1e-3`` as ``--tol=-1e-3``: a negative value reaches the option's own check."""
    numeric = _numeric_options()
    out: list[str] = []
    for a in argv:
        if out and out[-1] in numeric and _NEGATIVE.match(a):
            out[-1] = f"{out[-1]}={a}"
        else:
            out.append(a)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``direct`` command.

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments, without the program name (default ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit status: 0 on success, 2 for a usage error or a
        :class:`direct.DirectError` (reported on one line of standard error).
    """
    from .errors import DirectError

    parser = build_parser()
    try:
        args = parser.parse_args(_joined_numbers(sys.argv[1:] if argv is None else list(argv)))
    except SystemExit as exc:  # --help, --version and usage errors
        return int(exc.code or 0) if not isinstance(exc.code, str) else 2
    command = {"penalty": _cmd_penalty, "plot": _cmd_plot, "scenes": _cmd_scenes}[args.command]
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _show_warning
            return command(args)
    except DirectError as err:
        message = " ".join(str(err).split()) or type(err).__name__
        print(f"direct: error: {message}", file=sys.stderr)
        return 2
