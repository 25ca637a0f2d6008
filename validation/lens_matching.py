"""A thin lens with ``g``: the grid's overestimate of each curve, and the matching at ``tol=1e-5`` and ``1e-6``.

Run ``python validation/lens_matching.py`` (a few seconds).  The scene is ``tests/data/lens_four_crossings_g.json``
(two open polylines crossing four times, close together in between; an adversarial review at stop 39), with
``g`` (``p = 2``).  For every solve of the refinement's choice (``direct.penalty._settle``, both grids, and
the second solve after the chosen curves are refined again with the value's absolute tolerance) it prints each
entry refined: its grid length, its refined length and their ratio; then each run's value, estimate,
``upper_bound`` and curves.  Until stop 39 the second solve brought back the curve between the two middle
crossing points at its grid lower bound, 17.7 and 66 times its length, and the value at ``tol=1e-5`` was the
other matching, 7.4e-5 (relative) above ``J`` (docs/record.md).  Writes ``lens_matching.csv`` beside this file.
"""

from __future__ import annotations

import os
import sys
import warnings

import direct

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from study import write_csv  # noqa: E402

P = sys.modules["direct.penalty"]


def main() -> None:
    scene = direct.load_scene(os.path.join(os.path.dirname(HERE), "tests", "data", "lens_four_crossings_g.json"))
    rows: list = []
    settle = P._settle
    state = {"tol": None, "solve": 0}

    def traced(grid_costs, *args, **kwargs):
        value, chosen, cache = settle(grid_costs, *args, **kwargs)
        state["solve"] += 1
        for key, rp in cache.items():
            if grid_costs.get(key, 0.0) > 0.0:
                rows.append(dict(tol=state["tol"], solve=state["solve"], entry=str(key), chosen=key in dict(chosen),
                                 grid=grid_costs[key], refined=rp.length, ratio=grid_costs[key] / rp.length))
                print(rows[-1], flush=True)
        return value, chosen, cache

    P._settle = traced
    try:
        for tol in (1e-5, 1e-6):
            state["tol"], state["solve"] = tol, 0
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", direct.ToleranceWarning)
                res = direct.penalty(scene, metric="g", power=2, tol=tol)
            print(f"tol={tol:g}: value {res.value!r}, estimate {res.error_estimate:.2e}, upper_bound "
                  f"{res.upper_bound!r}; curves " + ", ".join(f"{p.start}->{p.end} {p.polyline_length:.6e}"
                                                           for p in res.pairs), flush=True)
    finally:
        P._settle = settle
    write_csv(rows, os.path.join(HERE, "lens_matching.csv"))


if __name__ == "__main__":
    main()
