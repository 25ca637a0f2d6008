"""The folded starts at their own resolution: a limaçon, an ellipse and a line at ``tol=1e-3`` and ``1e-5``.

Run ``python validation/folded_starts.py`` (about two minutes alone).  The scene,
``limacon_ellipse_line.json`` beside this file, is one an adversarial review built at stop 35: a limaçon
``r = 0.35 + cos t`` at 30 vertices, an ellipse (semi-axes 0.9 and 0.4) at 16 and a straight line at 8,
13 crossings, ``G``.  At ``tol=1e-5`` one winding curve of the limaçon and the ellipse (a torus of
``M x M``, 1,861 vertices refined) got 22 folded starts (``direct.starts._crease_starts``), each
refined from that resolution through every level: one of them reached 119,874 vertices.  The call took
1,155 s on 46eea1d (beside other jobs).  Since then a route as fine as a last level stops at its third
level (``direct.refinement.refine_many``).  Prints each call's value,
estimate, warning and time, and writes ``folded_starts.csv`` beside this file.
"""

from __future__ import annotations

import os
import time
import warnings

import direct

HERE = os.path.dirname(os.path.abspath(__file__))


def main() -> list[dict]:
    from study import write_csv

    scene = direct.load_scene(os.path.join(HERE, "limacon_ellipse_line.json"))
    rows = []
    for tol in (1e-3, 1e-5):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", direct.ToleranceWarning)
            start = time.perf_counter()
            res = direct.penalty(scene, tol=tol)
            seconds = time.perf_counter() - start
        rows.append(dict(tol=tol, crossings=len(res.crossings), value=res.value, error_estimate=res.error_estimate,
                         relative_estimate=res.error_estimate / res.value, upper_bound=res.upper_bound,
                         warned=bool(caught), seconds=round(seconds, 1)))
        print(rows[-1], flush=True)
    a, b = rows
    print(f"the two values {abs(a['value'] - b['value']) / b['value']:.1e} apart (relative), within the two "
          f"estimates: {abs(a['value'] - b['value']) <= a['error_estimate'] + b['error_estimate']}")
    write_csv(rows, os.path.join(HERE, "folded_starts.csv"))
    return rows


if __name__ == "__main__":
    main()
