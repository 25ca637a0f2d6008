"""What the full second pass adds at ``tol=1e-4``: the route check alone against it, on the default_tol scenes.

Run ``python validation/second_pass.py`` (about seven minutes).  From ``tol=1e-4`` down
``direct.penalty`` solves every domain a second time from the routes of another grid and keeps the
better family, adding the spread to ``error_estimate``; just above (``tol=1.01e-4``) it only checks
the chosen curves against the second grid's routes.  For the random interval scenes of
``validation/default_tol.py`` (seeds 100 to 299) it computes both and counts the scenes where the
check alone lands above the second pass by more than its own ``error_estimate``.  Writes
``second_pass.csv`` beside this file and prints a summary.
"""

from __future__ import annotations

import os
import sys
import time
import warnings

from study import write_csv

import direct

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))
from conftest import study_scenes  # noqa: E402


def main(seeds=range(100, 300)) -> list[dict]:
    rows = []
    for seed, sc in study_scenes(seeds):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", direct.ToleranceWarning)
            t0 = time.perf_counter()
            checked = direct.penalty(sc, tol=1.01e-4)
            t1 = time.perf_counter()
            second = direct.penalty(sc, tol=1e-4)
            t2 = time.perf_counter()
        above = (checked.value - second.value) / second.value
        rows.append(dict(seed=seed, crossings=len(checked.crossings), checked=checked.value, second=second.value,
                         checked_above=above, relative_estimate_checked=checked.error_estimate / checked.value,
                         relative_estimate_second=second.error_estimate / second.value,
                         over_estimate=checked.value - second.value > checked.error_estimate,
                         seconds_checked=t1 - t0, seconds_second=t2 - t1))
        print(f"seed {seed}: check alone {above:+.1e} relative above the second pass, its estimate "
              f"{rows[-1]['relative_estimate_checked']:.1e}", flush=True)
    write_csv(rows, os.path.join(HERE, "second_pass.csv"))
    far = max(rows, key=lambda r: r["checked_above"] / r["relative_estimate_checked"])
    t_c = sum(r["seconds_checked"] for r in rows)
    t_s = sum(r["seconds_second"] for r in rows)
    print(f"\n{len(rows)} scenes: the check alone above the second pass by more than its estimate on "
          f"{sum(r['over_estimate'] for r in rows)}; farthest against its estimate seed {far['seed']} "
          f"({far['checked_above']:.1e} against {far['relative_estimate_checked']:.1e}); largest "
          f"{max(r['checked_above'] for r in rows):.1e}; time second pass / check {t_s / t_c:.2f} "
          f"({t_s:.0f} s / {t_c:.0f} s)")
    return rows


if __name__ == "__main__":
    main()
