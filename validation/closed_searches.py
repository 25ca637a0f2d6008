"""Closed curves of a torus searched only when program (34) picks one, against searching them up front.

Run ``python validation/closed_searches.py`` (about four minutes alone, ten on a loaded machine).  On a
torus (two closed components) the family of curves may include closed
curves (section 3.3.4), and their grid lengths come from 2 x 24 Dijkstra
searches on the 3 x 3 cover of the grid
(:func:`direct.geodesics.closed_curve_distances`): most of the time of a
torus whose curves all join crossing points.  The pipeline now enters them
in the program at lower bounds (:func:`direct.geodesics.closed_curve_bounds`,
one pass over the edges) and searches only once a solve picks one, for
the classes picked (24 searches from the seam the class crosses, ``s = 0``
for ``(+-1, b)``, ``v = 0`` for ``(0, +-1)``, each stopped at the closed
curves found so far).  Up front is emulated in the same process by
replacing the bounds with the searched lengths themselves (all eight
classes), which is what the pipeline did before.

Scenes: two regular ``n``-gons of radius 1 (``n`` = 16, 32, 64, 128) pushed
``shift`` = 1.6, 1.0, 0.6 and 0.3 apart (centre to centre), round or
wobbling; 12 random pairs (a wobbling circle and a smaller wobbling one
placed at random over it); and ``nested``.  Each scene runs
both ways at the default settings (``tol=1e-3``, 128 cells), in alternating
order.  A row records both times, whether the values, grid values and
error estimates are the same bit for bit, and how many classes the lazy run
searched from.  Writes
``closed_searches.csv`` and ``closed_searches.png`` (time up front against
time now) beside this file and prints a summary.
"""

from __future__ import annotations

import csv
import os
import sys
import time
import warnings

import numpy as np

import direct

HERE = os.path.dirname(os.path.abspath(__file__))
P = sys.modules["direct.penalty"]
sys.path.insert(0, os.path.join(HERE, "..", "tests"))
from conftest import polygon_pair  # noqa: E402


def random_pair(seed: int) -> direct.Scene:
    """A wobbling circle and a smaller wobbling one placed at random over it."""
    rng = np.random.default_rng(seed)
    n1, n2 = rng.integers(12, 40, 2)
    r2, c = rng.uniform(0.2, 1.3), rng.uniform(-1.2, 1.2, 2)
    k, amp, phase = rng.integers(2, 5), rng.uniform(0, 0.2), rng.uniform(0, 2 * np.pi)

    def circle(centre, r, n, turn, bump):
        t = turn + 2 * np.pi * np.arange(n) / n
        rr = r * (1 + bump(t))
        return np.column_stack([centre[0] + rr * np.cos(t), centre[1] + rr * np.sin(t)])

    a = circle((0, 0), 1, n1, 0.0, lambda t: amp * np.cos(k * t + phase))
    b = circle(c, r2, n2, rng.uniform(0, 2 * np.pi), lambda t: amp * np.sin((k + 1) * t))
    return direct.Scene((direct.Component(circle((0, 0), 1, n1, 0.0, lambda t: 0 * t), a, closed=True, name="A"),
                         direct.Component(circle((5, 0), r2, n2, 0.0, lambda t: 0 * t), b, closed=True, name="B")),
                        name=f"random pair {seed}")


def scenes():
    for n in (16, 32, 64, 128):
        for shift in (1.6, 1.0, 0.6, 0.3):
            yield polygon_pair(n, shift)
            yield polygon_pair(n, shift, 0.2, seed=n)
    for seed in range(12):
        yield random_pair(seed)
    yield direct.scenes.get("nested")


def run(scene, up_front: bool):
    """``(result, seconds, classes searched)``: the pipeline as it is, or with every closed curve searched up front."""
    inner_bounds, inner_search = P.closed_curve_bounds, P.closed_curve_distances
    searched = []

    def search(graph, *args, **kwargs):
        found = inner_search(graph, *args, **kwargs)
        searched.extend(c for c in found if c >= (0, 0))  # a class and its opposite are one search
        return found

    P.closed_curve_distances = search
    if up_front:  # the bounds are the searched lengths: the program sees what it saw before the change
        P.closed_curve_bounds = lambda graph: {c: f[0][0] for c, f in inner_search(graph).items()}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", direct.ToleranceWarning)
            t0 = time.perf_counter()
            res = direct.penalty(scene)
            seconds = time.perf_counter() - t0
    finally:
        P.closed_curve_bounds, P.closed_curve_distances = inner_bounds, inner_search
    return res, seconds, len(searched)


def main() -> list[dict]:
    rows = []
    for k, scene in enumerate(scenes()):
        order = (False, True) if k % 2 == 0 else (True, False)
        out = {up_front: run(scene, up_front) for up_front in order}
        (lazy, t_lazy, searched), (eager, t_eager, _) = out[False], out[True]
        rows.append(dict(scene=scene.name, crossings=len(lazy.crossings), value=lazy.value,
                         error_estimate=lazy.error_estimate, closed_picked=sum(p.closed for p in lazy.pairs),
                         searched=searched > 0, classes_searched=searched,
                         same=(lazy.value, lazy.grid_value, lazy.error_estimate)
                         == (eager.value, eager.grid_value, eager.error_estimate),
                         seconds=t_lazy, seconds_up_front=t_eager, ratio=t_eager / t_lazy))
        r = rows[-1]
        print(f"{r['scene']:34s} classes searched={searched} same={str(r['same']):5s} {t_eager:6.2f} s -> "
              f"{t_lazy:6.2f} s ({r['ratio']:.1f} x)", flush=True)
    with open(os.path.join(HERE, "closed_searches.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    _chart(rows)
    print(summary(rows))
    return rows


def summary(rows) -> str:
    quiet = [r["ratio"] for r in rows if not r["searched"]]
    lines = [f"{len(rows)} torus scenes; values, grid values and estimates the same bit for bit on "
             f"{sum(r['same'] for r in rows)}; closed curves picked on {sum(r['closed_picked'] > 0 for r in rows)}."]
    if quiet:
        lines.append(f"no search on {len(quiet)}: up front / now = {np.median(quiet):.1f} x (median), "
                     f"{min(quiet):.1f} to {max(quiet):.1f} x")
    for n in (1, 2, 3, 4):
        sel = [r["ratio"] for r in rows if r["classes_searched"] == n]
        if sel:
            lines.append(f"{n} class{'es' if n > 1 else ''} searched on {len(sel)}: {np.median(sel):.2f} x (median), "
                         f"{min(sel):.2f} to {max(sel):.2f} x")
    return "\n".join(lines)


def _chart(rows):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 5))
    for searched, style, label in ((False, "o", "no closed curve searched"),
                                   (True, "s", "searched (a solve picked one)")):
        sel = [r for r in rows if r["searched"] == searched]
        if sel:
            ax.loglog([r["seconds_up_front"] for r in sel], [r["seconds"] for r in sel], style, label=label, alpha=0.7)
    lo = min(min(r["seconds"] for r in rows), min(r["seconds_up_front"] for r in rows))
    hi = max(max(r["seconds"] for r in rows), max(r["seconds_up_front"] for r in rows))
    for f, ls in ((1, "-"), (1 / 10, ":")):
        ax.loglog([lo, hi], [f * lo, f * hi], "k" + ls, lw=0.8, label="same time" if f == 1 else "10 x faster")
    ax.set_xlabel("closed curves searched up front (s)")
    ax.set_ylabel("searched when picked (s)")
    ax.set_title("Torus scenes at tol 1e-3, 128 cells")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(HERE, "closed_searches.png"), dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
