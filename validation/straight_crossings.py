"""Several crossings of straight runs against an exact reference, at ``tol=1e-5`` and ``1e-7``.

Run ``python validation/straight_crossings.py`` (about four minutes).  The scenes of
``tests/conftest.py``'s ``straight_crossings_scene``: combs (a spine crossed by 2 to 4 sticks), hooks (a
spine crossed twice, with opposite signs, in one piece of ``M x M``: the program could pair the two points)
and loops (one polyline crossing itself), with extra collinear vertices, uneven references, turned, moved
and scaled; 20 seeds each.  Also ``cylinder_scene``: an interval crossing a square once, whose curve must
reach the end whose winding number changed (``cylinder_reference``: a closed component, where the
topological condition decides), with its reference interval on either side of the square (``cylinder``,
the farther end; ``cylinder, flipped``, the nearer), and ``polygon_cylinder_scene``: an interval across a
random star-shaped polygon, convex or not, either orientation (``cylinder, random polygon``).  Their ``J``
comes from ``tests/references.py`` (not computed with ``direct``): ``straight_crossings_reference``, each
crossing's rectangle of straight runs, its nearest side a component end, nearer than any bend, the
rectangles disjoint, and ``cylinder_reference``; the distance to each side from the eikonal profile of
``crossing_reference``.  Metrics: ``G`` (``q = 2``, and ``q = 1`` and ``3``
on the first five seeds) and ``g`` with ``p = 2`` on isometric deformations (``k = 4``); every case at
``tol=1e-5``, the ``G`` cases of the first five seeds also at ``1e-7``.  A row is ``SILENT`` when the error
exceeds the ``error_estimate`` without a ``ToleranceWarning``, ``over tol`` when it exceeds ``tol``.
Writes ``straight_crossings.csv`` beside this file and prints a summary per family and setting.
"""

from __future__ import annotations

import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))
from conftest import cylinder_scene, polygon_cylinder_scene, straight_crossings_scene  # noqa: E402
from references import cylinder_reference, straight_crossings_reference  # noqa: E402

sys.path.insert(0, HERE)
from default_tol import _solve as solve_recording_warnings  # noqa: E402
from default_tol import status  # noqa: E402
from study import write_csv  # noqa: E402

#: each family's scene builder (seed, isometric, k) and reference (scene, k)
FAMILIES = {kind: (lambda seed, iso, k, kind=kind: straight_crossings_scene(seed, kind, isometric=iso),
                   straight_crossings_reference) for kind in ("comb", "hook", "loop")}
FAMILIES["cylinder"] = (lambda seed, iso, k: cylinder_scene(seed, iso), cylinder_reference)
FAMILIES["cylinder, flipped"] = (lambda seed, iso, k: cylinder_scene(seed, iso, flip=True), cylinder_reference)
FAMILIES["cylinder, random polygon"] = (polygon_cylinder_scene, cylinder_reference)
KINDS = tuple(FAMILIES)
SEEDS = range(20)
#: (metric, power, k of the reference, isometric deformations, tolerances, seeds)
SETTINGS = (("G", 2.0, 2, False, (1e-5, 1e-7), SEEDS),
            ("G", 1.0, 1, False, (1e-5,), range(5)),
            ("G", 3.0, 3, False, (1e-5,), range(5)),
            ("g", 2.0, 4, True, (1e-5,), SEEDS))


def main() -> list[dict]:
    rows = []
    for kind in KINDS:
        for metric, power, k, isometric, tols, seeds in SETTINGS:
            for seed in seeds:
                build, reference = FAMILIES[kind]
                scene = build(seed, isometric, k)
                exact = reference(scene, k=k)
                for tol in tols if seed < 5 else tols[:1]:
                    res, warned, seconds = solve_recording_warnings(scene, tol, metric=metric, power=power)
                    err, est = abs(res.value - exact) / exact, res.error_estimate / exact
                    rows.append(dict(kind=kind, seed=seed, metric=metric, power=power, tol=tol,
                                     crossings=len(res.crossings), value=res.value, reference=exact,
                                     relative_error=err, relative_estimate=est, warned=warned, seconds=seconds,
                                     status=status(err, est, warned, tol)))
    write_csv(rows, os.path.join(HERE, "straight_crossings.csv"))
    print("| family | metric | tol | runs | largest relative error | largest error / estimate | warnings | "
          "silent | over tol | seconds (median) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for kind in KINDS:
        for metric, power, _, _, tols, _ in SETTINGS:
            for tol in tols:
                sel = [r for r in rows if (r["kind"], r["metric"], r["power"], r["tol"]) == (kind, metric, power, tol)]
                ratio = max(r["relative_error"] / r["relative_estimate"] if r["relative_estimate"] > 0 else
                            (0.0 if r["relative_error"] == 0 else float("inf")) for r in sel)
                times = sorted(r["seconds"] for r in sel)
                print(f"| {kind} | {metric} {power:g} | {tol:.0e} | {len(sel)} | "
                      f"{max(r['relative_error'] for r in sel):.1e} | {ratio:.3f} | {sum(r['warned'] for r in sel)} | "
                      f"{sum(r['status'] == 'SILENT' for r in sel)} | {sum(r['status'] == 'over tol' for r in sel)} | "
                      f"{times[len(times) // 2]:.2f} |")
    print(f"\n{len(rows)} runs: {sum(r['status'] == 'SILENT' for r in rows)} silently off (error above the "
          f"estimate, no warning), {sum(r['status'] == 'over tol' for r in rows)} above tol, "
          f"{sum(r['warned'] for r in rows)} warnings")
    return rows


if __name__ == "__main__":
    main()
