"""Symmetric closed polygons at 8 and 16 neighbours: do the two stencils agree?

Run ``python validation/symmetric.py`` (about a minute).  A closed polygon sampled evenly from a formula
symmetric about an axis through its crossing has a straight local geodesic from the crossing point to the
diagonal along ``(-1, 1)``, which every stencil weighs exactly while the shortest curves beside it cost up
to the stencil's bias more (8.2 % with 8 moves): docs/record.md, *Known limitations*, symmetric polygons.  The
scenes: the figure eights ``(sin t, sin t cos t)`` at 10 to 32 vertices and the limaçons ``r = a + cos t``,
``a`` = 0.3, 0.5, 0.6 and 0.8, at 12 to 32 vertices (reference: the unit polygon, the same ``t``), each at
``neighbours=8`` and ``16``, the default ``tol``.  A pair agrees when each value, less its estimate, is at
most the other's ``upper_bound`` (the exact length of its curves); ``SILENT`` marks a disagreement without
a ``ToleranceWarning``.  Writes ``symmetric.csv`` beside this file.
"""

from __future__ import annotations

import os
import time
import warnings

import numpy as np
from study import write_csv

import direct

HERE = os.path.dirname(os.path.abspath(__file__))


def _closed(points: np.ndarray, t: np.ndarray, name: str) -> direct.Scene:
    ref = np.column_stack([np.cos(t), np.sin(t)])
    return direct.Scene((direct.Component(ref, points, closed=True, name=name),))


def figure_eight(n: int) -> direct.Scene:
    """The figure eight ``(sin t, sin t cos t)`` at ``n`` vertices evenly in ``t``."""
    t = 2 * np.pi * np.arange(n) / n
    return _closed(np.column_stack([np.sin(t), np.sin(t) * np.cos(t)]), t, f"figure eight n={n}")


def limacon(a: float, n: int) -> direct.Scene:
    """The limaçon ``r = a + cos t`` at ``n`` vertices evenly in ``t``."""
    t = 2 * np.pi * np.arange(n) / n
    r = a + np.cos(t)
    return _closed(np.column_stack([r * np.cos(t), r * np.sin(t)]), t, f"limacon a={a} n={n}")


def main() -> None:
    scenes = [figure_eight(n) for n in (10, 12, 14, 16, 18, 20, 24, 28, 32)]
    scenes += [limacon(a, n) for a in (0.3, 0.5, 0.6, 0.8) for n in (12, 16, 20, 24, 32)]
    rows, silent = [], 0
    for sc in scenes:
        runs = {}
        for nb in (8, 16):
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", direct.ToleranceWarning)
                t0 = time.perf_counter()
                res = direct.penalty(sc, neighbours=nb)
                seconds = time.perf_counter() - t0
            runs[nb] = (res, any(issubclass(w.category, direct.ToleranceWarning) for w in caught), seconds)
        (a, wa, ta), (b, wb, tb) = runs[8], runs[16]
        agree = a.value - a.error_estimate <= b.upper_bound and b.value - b.error_estimate <= a.upper_bound
        verdict = "agree" if agree else ("warned" if wa or wb else "SILENT")
        silent += verdict == "SILENT"
        name = sc.components[0].name
        rows.append({"scene": name, "value_8": a.value, "estimate_8": a.error_estimate, "upper_8": a.upper_bound,
                     "warned_8": wa, "seconds_8": ta, "value_16": b.value, "estimate_16": b.error_estimate,
                     "upper_16": b.upper_bound, "warned_16": wb, "seconds_16": tb, "verdict": verdict})
        print(f"{name:24s} 8: {a.value:.9f} ({a.error_estimate:.1e}{', warned' if wa else ''})  "
              f"16: {b.value:.9f} ({b.error_estimate:.1e}{', warned' if wb else ''})  {verdict}", flush=True)
    write_csv(rows, os.path.join(HERE, "symmetric.csv"))
    print(f"{silent} of {len(rows)} SILENT; wrote validation/symmetric.csv")


if __name__ == "__main__":
    main()
