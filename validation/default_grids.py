"""The default ``tol`` on other grids and in other positions: do the estimates still cover the errors?

Run ``python validation/default_grids.py`` (about six minutes).  The 175 random interval scenes of
``default_tol.py`` (seeds 100 to 299) and the closed polygons of ``random_closed.py`` (``hairpin`` and the
random ones with crossings), each turned and shifted (``J`` does not change under rigid motions) and solved
at the default ``tol`` on grids of 96, 160 and 192 cells (one angle each), against the ``tol=1e-6``
references those studies wrote to ``default_tol.csv`` and ``random_closed.csv`` (computed by ``direct`` on
the default grid of the scene as given: a check of consistency across grids and positions, not against an
independent value; ``straight_crossings.py`` and ``crease_motions.py`` do that).  A row is ``over`` when
the error exceeds the sum of its ``error_estimate`` and the reference's, ``warned`` when a
``ToleranceWarning`` said so.  Writes ``default_grids.csv`` beside this file and prints a count per family
and grid.
"""

from __future__ import annotations

import csv
import os
import sys

import direct

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))
from conftest import rigid, study_scenes  # noqa: E402

sys.path.insert(0, HERE)
from default_tol import _solve as solve_recording_warnings  # noqa: E402
from random_closed import random_closed  # noqa: E402
from study import write_csv  # noqa: E402

#: (resolution, angle) of the runs of each scene, and the shift
CASES = ((96, 0.4), (160, 1.3), (192, 2.2))
SHIFT = (0.3, -0.1)


def _references(name: str, key: str) -> dict:
    """``{scene key: (reference, its absolute estimate)}`` from a study's CSV (one row per scene and ``tol``)."""
    with open(os.path.join(HERE, name)) as fh:
        return {r[key]: (float(r["reference"]), float(r["reference_relative_estimate"]) * float(r["reference"]))
                for r in csv.DictReader(fh)}


def _scenes():
    """``(family, name, scene, reference, its estimate)`` of every scene with a reference."""
    intervals = _references("default_tol.csv", "seed")
    for seed, scene in study_scenes(range(100, 300)):
        if str(seed) in intervals:  # J = 0 has no row: no crossing that costs anything
            yield ("intervals", str(seed), scene, *intervals[str(seed)])
    for name, ref in _references("random_closed.csv", "scene").items():
        scene = direct.scenes.get("hairpin") if name == "hairpin" else random_closed(int(name.split()[-1]))
        yield ("closed", name, scene, *ref)


def main() -> list[dict]:
    rows = []
    for family, name, scene, exact, exact_estimate in _scenes():
        for resolution, angle in CASES:
            res, warned, seconds = solve_recording_warnings(rigid(scene, angle, SHIFT), 1e-3, resolution=resolution)
            error = res.value - exact
            rows.append(dict(family=family, scene=name, resolution=resolution, angle=angle, value=res.value,
                             reference=exact,
                             relative_error=error / exact, relative_estimate=res.error_estimate / exact,
                             reference_relative_estimate=exact_estimate / exact,
                             over=abs(error) > res.error_estimate + exact_estimate, warned=warned, seconds=seconds))
    write_csv(rows, os.path.join(HERE, "default_grids.csv"))
    for family, resolution in [(f, n) for f in ("intervals", "closed") for n, _ in CASES]:
        sel = [r for r in rows if (r["family"], r["resolution"]) == (family, resolution)]
        print(f"{family}, {resolution} cells: {len(sel)} runs, {sum(r['over'] for r in sel)} off by more than "
              f"both estimates "
              f"({sum(r['over'] and not r['warned'] for r in sel)} without a warning), "
              f"{sum(r['warned'] for r in sel)} warned; largest error "
              f"{max(abs(r['relative_error']) for r in sel):.1e} relative, "
              f"{sum(abs(r['relative_error']) > 1e-3 for r in sel)} beyond tol")
    return rows


if __name__ == "__main__":
    main()
