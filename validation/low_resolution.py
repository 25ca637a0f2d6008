"""Grids coarser than the default: does a value stay within its estimate of the default's?

Run ``python validation/low_resolution.py`` (about a minute).  The grid
decides which points the curves join and which local geodesic each curve
settles in, and the estimate measures only the refinement of that geodesic.
Below the default resolution (128 cells) ``direct`` therefore also runs the
default computation, route check included, and keeps the better family
(``second_resolution`` in ``direct/penalty.py``).  For the scenes on which a
review found silent errors at coarse grids (interval seeds 100, 104, 105 and
138 of ``tests/conftest.py``'s ``study_scenes``, closed polygons 0, 7, 13 and
18 of ``random_closed.py``), at 4 to 96 cells and the default ``tol=1e-3``,
this compares each value with the default's:

* *off*: ``|J(N) - J(128)|`` above the sum of the two estimates;
* *provably high*: ``J(N) - estimate(N)`` above the default's
  ``upper_bound`` (the exact length of real curves, so above ``J``).

Writes ``low_resolution.csv`` beside this file and prints a summary.
"""

from __future__ import annotations

import os
import sys
import time
import warnings

from study import write_csv

import direct

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "..", "tests"))
from conftest import study_scenes  # noqa: E402
from random_closed import random_closed  # noqa: E402

RESOLUTIONS = (4, 8, 16, 24, 32, 48, 64, 96)


def main() -> list[dict]:
    scenes = {f"interval {seed}": sc for seed, sc in study_scenes([100, 104, 105, 138])}
    scenes.update({f"closed {seed}": random_closed(seed) for seed in (0, 7, 13, 18)})
    rows = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", direct.ToleranceWarning)
        for name, sc in scenes.items():
            default = direct.penalty(sc)
            for res in RESOLUTIONS:
                caught.clear()
                t0 = time.perf_counter()
                r = direct.penalty(sc, resolution=res)
                seconds = time.perf_counter() - t0
                diff = r.value - default.value
                rows.append(dict(scene=name, resolution=res, value=r.value, default=default.value,
                                 relative_difference=diff / default.value,
                                 relative_estimates=(r.error_estimate + default.error_estimate) / default.value,
                                 off=abs(diff) > r.error_estimate + default.error_estimate,
                                 provably_high=r.value - r.error_estimate > default.upper_bound,
                                 warned=any(issubclass(w.category, direct.ToleranceWarning) for w in caught),
                                 seconds=seconds))
                r_ = rows[-1]
                flags = [k for k in ("off", "provably_high", "warned") if r_[k]]
                print(f"{name} at {res} cells: {diff / default.value:+.1e} (estimates {r_['relative_estimates']:.1e})"
                      f" {seconds:.2f} s {' '.join(flags)}", flush=True)
    write_csv(rows, os.path.join(HERE, "low_resolution.csv"))
    print(f"{len(rows)} runs on {len(scenes)} scenes at {RESOLUTIONS[0]} to {RESOLUTIONS[-1]} cells: "
          f"{sum(r['off'] for r in rows)} off from the default by more than the two estimates "
          f"({sum(r['off'] and not r['warned'] for r in rows)} without a warning), "
          f"{sum(r['provably_high'] for r in rows)} provably high; largest |difference| "
          f"{max(abs(r['relative_difference']) for r in rows):.1e} relative")
    return rows


if __name__ == "__main__":
    main()
