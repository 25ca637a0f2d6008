"""What the route check buys at the default tolerance, and what it costs.

Run ``python validation/route_check.py`` (about two minutes).  Without the
full second pass (``tol > 1e-4``), ``direct.penalty`` checks each chosen
curve against the routes of a second grid (three quarters of the step),
straightened at the coarse scale, and refines those that come out shorter
than the refined curve (another local geodesic, across a crease of the
metric).  ``second_pass=False`` refuses every second start, so it gives the
single start the check is measured against.  For the random interval scenes
of ``validation/multistart.py`` (2 or 3 polylines of 7 vertices, 1 to 10
crossings) at seeds 100 to 299, it computes ``J`` both ways at ``tol=1e-3``
and counts the single starts that sit above the checked value by more than
their own ``error_estimate`` (silently off).  Scenes with a grazing crossing,
whose domain gets a full second pass unless ``second_pass=False``, are left
out.  Writes ``route_check.csv`` and ``route_check.png`` beside this file
and prints a summary.
"""

from __future__ import annotations

import os
import sys
import time
import warnings

import numpy as np
from study import write_csv

import direct

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))
from conftest import study_scenes  # noqa: E402


def main(seeds=range(100, 300), tol: float = 1e-3) -> list[dict]:
    rows = []
    t_on = t_off = 0.0
    for seed, sc in study_scenes(seeds):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", direct.ToleranceWarning)
            t0 = time.perf_counter()
            on = direct.penalty(sc, tol=tol)
            t1 = time.perf_counter()
            off = direct.penalty(sc, tol=tol, second_pass=False)
            t2 = time.perf_counter()
        if on.settings.get("grazing_second_pass"):
            continue
        t_on += t1 - t0
        t_off += t2 - t1
        change = (off.value - on.value) / on.value
        rows.append(dict(seed=seed, crossings=len(on.crossings), checked=on.value, single=off.value,
                         relative_change=change, relative_estimate_checked=on.error_estimate / on.value,
                         relative_estimate_single=off.error_estimate / off.value,
                         single_silently_off=off.value - on.value > off.error_estimate,
                         seconds_checked=t1 - t0, seconds_single=t2 - t1))
        if change != 0.0:
            r = rows[-1]
            print(f"seed {seed}: single start {change:+.1e} relative (its estimate "
                  f"{r['relative_estimate_single']:.1e}); checked estimate {r['relative_estimate_checked']:.1e}",
                  flush=True)
    write_csv(rows, os.path.join(HERE, "route_check.csv"))
    changed = [r for r in rows if r["relative_change"] != 0.0]
    lower = [r for r in changed if r["relative_change"] < 0]
    silent = [r for r in rows if r["single_silently_off"]]
    print(f"{len(rows)} scenes at tol={tol:g}: the check changed {len(changed)} values ({len(lower)} of them upwards); "
          f"{len(silent)} single starts above the checked value by more than their estimate"
          + (f" (largest {max(r['relative_change'] for r in silent):.1e} relative)" if silent else "")
          + f"; time with the check / without: {t_on / t_off:.2f} ({t_on:.0f} s / {t_off:.0f} s)")
    _chart(rows)
    return rows


def _chart(rows):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.5))
    est = np.array([r["relative_estimate_single"] for r in rows])
    change = np.array([r["relative_change"] for r in rows])
    moved = change != 0
    ax.loglog(est[~moved], np.full((~moved).sum(), 1e-12), ".", color="0.6",
              label="single start = checked (drawn at 1e-12)")
    ax.loglog(est[moved], np.abs(change[moved]), "o", color="C3", label="single start minus checked value")
    lim = [min(est.min(), 1e-7), 1e-2]
    ax.loglog(lim, lim, "k--", lw=0.8, label="= the single start's estimate")
    ax.set_xlabel("single start: error_estimate / J")
    ax.set_ylabel("relative change the route check made")
    ax.set_title(f"route check at tol=1e-3, {len(rows)} random scenes")
    ax.legend(fontsize=8, loc="center right")
    fig.tight_layout()
    fig.savefig(os.path.join(HERE, "route_check.png"), dpi=120)


if __name__ == "__main__":
    main()
