"""The heuristic metric of section 3.1 (``metric="euclid"``): how far its value is from the best of ten grids.

Run ``python validation/euclid.py`` (about ten minutes).  The length element
``|phi'(x1) dx1 - phi'(x2) dx2|`` is degenerate: it vanishes on the direction
where ``phi'(x1) dx1 = phi'(x2) dx2``, and its unit ball is an ellipse as
thin as the tangents of the two segments are close to parallel.  A grid
stencil overestimates lengths along such a thin ellipse by up to about 40 %
(8 neighbours) instead of the 3 % it gives the isotropic ``G``, so the grid
may route a curve into the valley of the wrong local geodesic, and no
refinement brings it back.

For 20 random scenes of two intervals (``tests/conftest.random_crossing_scene``)
and 12 random closed polygons (``random_closed.py``; the 2 whose value is 0
are skipped) it computes ``J^euclid``
with the defaults at ``tol=1e-3`` and ``tol=1e-5``, and compares it with the
smallest value of ten solves (16 and 32 neighbours, resolutions 64 to 256,
no second pass).  Every one of those values is the length of an admissible
family of curves, so the smallest is an upper bound of ``J^euclid`` and the
true value may be lower still: the comparison shows errors, it cannot prove
their absence.  A row is *over its estimate* when the value exceeds that
best by more than its ``error_estimate``, and *silently* so when no
``ToleranceWarning`` came with it.  Writes ``euclid.csv`` beside this file
and prints a summary.
"""

from __future__ import annotations

import os
import sys
import warnings

from study import write_csv

import direct

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "..", "tests"))
from conftest import random_crossing_scene  # noqa: E402
from default_tol import _solve as solve_recording_warnings  # noqa: E402
from random_closed import random_closed  # noqa: E402

GRIDS = [(nb, res) for nb in (16, 32) for res in (64, 96, 128, 192, 256)]


def _scenes(open_seeds, closed_seeds):
    for seed in open_seeds:
        yield "intervals", seed, random_crossing_scene(seed)
    for seed in closed_seeds:
        yield "closed", seed, random_closed(seed)


def main(open_seeds=range(20), closed_seeds=range(12), tols=(1e-3, 1e-5)) -> list[dict]:
    rows = []
    for kind, seed, scene in _scenes(open_seeds, closed_seeds):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", direct.ToleranceWarning)
            grid_values = [direct.penalty(scene, metric="euclid", tol=1e-5, resolution=res, neighbours=nb,
                                          second_pass=False).value for nb, res in GRIDS]
        best = min(grid_values)
        if best == 0.0:
            continue  # nothing to compare (no crossing, the turning number right)
        for tol in tols:
            res, warned, dt = solve_recording_warnings(scene, tol, metric="euclid")
            over = res.value - best > res.error_estimate + 1e-12 * best
            rows.append(dict(kind=kind, seed=seed, tol=tol, value=res.value, best_of_grids=best,
                             relative_error=(res.value - best) / best,
                             relative_estimate=res.error_estimate / best,
                             grid_spread=(max(grid_values) - best) / best,
                             over_estimate=over, warned=warned, seconds=round(dt, 3)))
            print(f"{kind:9s} {seed:3d} tol={tol:g}: {res.value:.9g} (best of grids {best:.9g}), error "
                  f"{rows[-1]['relative_error']:.1e}, estimate {rows[-1]['relative_estimate']:.1e}"
                  f"{', warned' if warned else ''}{', OVER' if over else ''}", flush=True)
    write_csv(rows, os.path.join(HERE, "euclid.csv"))
    for tol in tols:
        sub = [r for r in rows if r["tol"] == tol]
        over = [r for r in sub if r["over_estimate"]]
        silent = [r for r in over if not r["warned"]]
        worst = max((r["relative_error"] for r in silent), default=0.0)
        print(f"tol={tol:g}: {len(sub)} scenes, {sum(r['warned'] for r in sub)} warned, {len(over)} over their "
              f"estimate, {len(silent)} of them silently (largest {worst:.1e} relative)")
    return rows


if __name__ == "__main__":
    main()
