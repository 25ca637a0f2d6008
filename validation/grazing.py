"""Grazing crossings against the independent eikonal reference, at every tolerance.

Run ``python validation/grazing.py`` (about half a minute).  A straight
crossing of two arms of length 1 (``direct.scenes.cross(0.5, 0.5, 0.5, 0.5,
angle)``) at angles from 0.1 down to 1e-4 radians, metric ``G``, at ``tol``
from 1e-2 to 1e-7, against ``tests/references.py`` (the eikonal ODE of a
straight crossing, not computed with ``direct``).

At a small angle the geodesic from the crossing point runs down a valley of
width ~ angle into a corner of the domain and turns onto a side just before
it; the refinement's rounds creep towards that turn with gains that shrink
slowly, which is what the remaining-gain estimate of
``direct.refinement._remaining_gain`` must cover.

A row is ``SILENT`` when the error exceeds the ``error_estimate`` without a
``ToleranceWarning``, ``over tol`` when it exceeds ``tol`` (with or without a
warning).  Writes ``grazing.csv`` beside this file and prints a markdown
table and a count.
"""

from __future__ import annotations

import csv
import os
import sys

import direct

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))
from references import crossing_reference  # noqa: E402

sys.path.insert(0, HERE)
from default_tol import _solve as solve_recording_warnings  # noqa: E402
from default_tol import status  # noqa: E402

ANGLES = (0.1, 0.03, 0.01, 3e-3, 1e-3, 1e-4)
TOLS = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7)


def main() -> None:
    rows = []
    for alpha in ANGLES:
        exact = crossing_reference(alpha, 0.5, 0.5, 0.5, 0.5)
        scene = direct.scenes.cross(0.5, 0.5, 0.5, 0.5, angle=alpha)
        for tol in TOLS:
            res, warned, seconds = solve_recording_warnings(scene, tol)
            err = abs(res.value - exact) / exact
            est = res.error_estimate / exact
            rows.append(dict(angle=alpha, tol=tol, value=res.value, reference=exact, relative_error=err,
                             estimate=est, warned=warned, seconds=seconds, status=status(err, est, warned, tol)))
    with open(os.path.join(HERE, "grazing.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print("| angle (rad) | tol | relative error | error_estimate / J | warning | seconds | status |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['angle']:g} | {r['tol']:.0e} | {r['relative_error']:.1e} | {r['estimate']:.1e} | "
              f"{'yes' if r['warned'] else ''} | {r['seconds']:.2f} | {r['status']} |")
    n_silent = sum(r["status"] == "SILENT" for r in rows)
    n_over = sum(r["status"] == "over tol" for r in rows)
    print(f"\n{len(rows)} runs: {n_silent} silently off (error above the estimate, no warning), "
          f"{n_over} above tol")


if __name__ == "__main__":
    main()
