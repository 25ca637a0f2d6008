"""A star crossing an ellipse (a torus of ``M x M``), listed as built and from other vertices: do they agree?

Run ``python validation/star_ellipse.py`` (about four minutes alone: two calls of ``direct.penalty``
at the default ``tol``, one after the other).  The scene is the one an adversarial review found at
stop 34 (docs/record.md, *Known limitations*): a star ``r = 1 + 0.3 cos 10t`` at 30 vertices ``t = 2 pi k / 30 +
0.021`` (reference the unit circle at the same ``t``) crossing an ellipse ``(0.04 + 1.05 cos s, 0.03 +
0.95 sin s)`` at 20 vertices ``s = 2 pi k / 20 + 0.1`` (reference the circle of radius 1.05 about
``(10.04, 0.03)``; 20 crossings, ``G``).  Listed with both vertex lists rolled by 7 it came out 1.36e-3
(relative) above the ``upper_bound`` of the listing as built, with no warning, until
``_transplanted_starts``.  ``J`` is the same for both listings, so each run's ``value -
error_estimate`` must lie below the other's ``upper_bound`` (the exact length of its curves, so at
least ``J``).  Prints both runs and the verdict; writes ``star_ellipse.csv`` beside this file.
"""

from __future__ import annotations

import os
import time
import warnings

import numpy as np

import direct

HERE = os.path.dirname(os.path.abspath(__file__))


def star_and_ellipse(roll: int = 0) -> direct.Scene:
    """The review's scene, both vertex lists rolled by ``roll`` (``np.roll`` of reference and deformed alike)."""
    t = 2 * np.pi * np.arange(30) / 30 + 0.021
    r = 1 + 0.3 * np.cos(10 * t)
    star = (np.column_stack([np.cos(t), np.sin(t)]), np.column_stack([r * np.cos(t), r * np.sin(t)]))
    s = 2 * np.pi * np.arange(20) / 20 + 0.1
    ellipse = (np.column_stack([10.04 + 1.05 * np.cos(s), 0.03 + 1.05 * np.sin(s)]),
               np.column_stack([0.04 + 1.05 * np.cos(s), 0.03 + 0.95 * np.sin(s)]))
    pieces = zip(("star", "ellipse"), (star, ellipse))
    return direct.Scene(tuple(direct.Component(np.roll(R, roll, axis=0), np.roll(D, roll, axis=0), closed=True,
                                               name=name) for name, (R, D) in pieces))


def main() -> None:
    from study import write_csv

    rows = []
    for roll in (0, 7):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", direct.ToleranceWarning)
            start = time.perf_counter()
            res = direct.penalty(star_and_ellipse(roll))
            seconds = time.perf_counter() - start
        rows.append(dict(roll=roll, crossings=len(res.crossings), value=res.value, error_estimate=res.error_estimate,
                         upper_bound=res.upper_bound, warned=bool(caught), seconds=round(seconds, 1)))
        print(rows[-1], flush=True)
    a, b = rows
    silent = [(x["roll"], y["roll"]) for x, y in ((a, b), (b, a))
              if x["value"] - x["error_estimate"] > y["upper_bound"] and not x["warned"]]
    print("silent (too high, no warning):", silent or "none",
          f"; values {a['value']:.9f} and {b['value']:.9f}, relative difference "
          f"{abs(a['value'] - b['value']) / a['value']:.2e}")
    write_csv(rows, os.path.join(HERE, "star_ellipse.csv"))


if __name__ == "__main__":
    main()
