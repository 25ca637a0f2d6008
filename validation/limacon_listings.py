"""The stop-37 review's limaçon with ``g``, in all 26 listings: do they agree, and is any silently too high?

Run ``python validation/limacon_listings.py`` (about two and a half minutes alone).  The scene is
``tests/data/limacon_13_jittered.json``: a limaçon of 13 vertices at jittered angles, one self-crossing on
its symmetry axis, whose curve from the crossing point to the diagonal ends on the short edge across the
axis, where the length has two nearly tied minima (docs/record.md, *Known limitations*).  Each of its 26 listings
(started from each of its 13 vertices, in both orientations; ``np.roll`` and reversal of reference and
deformed alike, which do not change ``J``) runs with ``g`` at ``p = 2``, ``3`` and ``4.5`` at ``tol=1e-5``,
and at ``p = 3`` at ``tol=1e-3``.

No reference: the proof is the least ``upper_bound`` (the exact length of a run's curves, so at least
``J``) of the 26 runs of a setting.  A run whose ``value - error_estimate`` lies above it is too high by
more than its estimate: ``SILENT`` without a ``ToleranceWarning``.  Prints, per setting, the spread of the
values, how many warned and the silent runs; writes ``limacon_listings.csv`` beside this file (one row per
run).
"""

from __future__ import annotations

import os
import sys
import time
import warnings

import numpy as np

import direct

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from study import write_csv  # noqa: E402

SCENE = os.path.join(os.path.dirname(HERE), "tests", "data", "limacon_13_jittered.json")
SETTINGS = [(2.0, 1e-5), (3.0, 1e-5), (4.5, 1e-5), (3.0, 1e-3)]


def listings() -> list[tuple[str, direct.Scene]]:
    """``(label, scene)`` for the 26 listings: ``r<k>`` rolled by ``k``, ``v<k>`` reversed then rolled."""
    (c,) = direct.load_scene(SCENE).components
    out = []
    for reverse in (False, True):
        R, D = (c.reference[::-1], c.deformed[::-1]) if reverse else (c.reference, c.deformed)
        for k in range(len(R)):
            comp = direct.Component(np.roll(R, k, axis=0), np.roll(D, k, axis=0), closed=True, name="limacon")
            out.append((f"{'v' if reverse else 'r'}{k}", direct.Scene((comp,))))
    return out


def main() -> list[dict]:
    rows = []
    for power, tol in SETTINGS:
        runs = []
        start = time.perf_counter()
        for label, scene in listings():
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", direct.ToleranceWarning)
                res = direct.penalty(scene, metric="g", power=power, tol=tol)
            runs.append(dict(power=power, tol=tol, listing=label, value=res.value, error_estimate=res.error_estimate,
                             upper_bound=res.upper_bound, warned=bool(caught)))
        least = min(r["upper_bound"] for r in runs)
        for r in runs:
            high = r["value"] - r["error_estimate"] > least
            r["status"] = ("SILENT" if not r["warned"] else "warned") if high else "ok"
        values = [r["value"] for r in runs]
        print(f"g, p = {power:g}, tol={tol:g}: values {min(values)!r} to {max(values)!r} (spread "
              f"{(max(values) - min(values)) / least:.1e} relative), least upper_bound {least!r}; "
              f"{sum(r['warned'] for r in runs)} of {len(runs)} warned; SILENT: "
              f"{[r['listing'] for r in runs if r['status'] == 'SILENT'] or 'none'} "
              f"({time.perf_counter() - start:.0f} s)", flush=True)
        rows += runs
    write_csv(rows, os.path.join(HERE, "limacon_listings.csv"))
    return rows


if __name__ == "__main__":
    main()
