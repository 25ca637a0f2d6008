"""Random closed polygons at the default tolerance, against a tight run of each.

Run ``python validation/random_closed.py`` (about two minutes).  Each scene
is one closed polygon of 6 to 11 vertices: a regular polygon on the unit
circle (the reference) whose vertices are moved to random radii and angles
(the deformation), which folds it into loops, some thin.  Where two
segments of the deformed curve are nearly parallel (a hairpin) the metric
has a valley far narrower than a grid cell, and the grid's value
overestimates ``J`` many times over: the built-in scene ``hairpin`` (the
first row, 6.2 times at 128 cells, 61 times at 96).  For it and seeds 0 to 59 it computes
``J`` at ``tol=1e-3`` (the default) and at ``tol=1e-6`` (the reference,
computed by ``direct`` too: a check of self-consistency across tolerances,
like ``default_tol.py``).

A row is *over its estimate* when the value differs from the reference by
more than its own ``error_estimate``, and *silently off* when it differs by
more than the sum of both estimates with no ``ToleranceWarning``.  The
column ``refined_again`` says whether the chosen curves were refined a
second time because the absolute tolerance taken from the grid's value was
too loose (see ``settings["refined_again"]`` of :class:`direct.Penalty`).
Writes ``random_closed.csv`` beside this file and prints a summary.
"""

from __future__ import annotations

import os
import sys

import numpy as np
from study import write_csv

import direct

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from default_tol import _solve as solve_recording_warnings  # noqa: E402

TOL = 1e-3
REFERENCE_TOL = 1e-6


def random_closed(seed: int) -> direct.Scene:
    """A regular polygon of 6 to 11 vertices whose deformation moves each vertex to a random radius and angle."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(6, 12))
    t = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    ref = np.column_stack([np.cos(t), np.sin(t)])
    radius = 1.0 + 0.3 * rng.standard_normal(n)
    angle = t + rng.uniform(-1.2, 1.2, n)
    dfm = np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])
    return direct.Scene((direct.Component(ref, dfm, closed=True, name="c"),), name=f"random closed {seed}")


def main(seeds=range(60)) -> list[dict]:
    rows = []
    for seed in [None, *seeds]:
        sc = direct.scenes.get("hairpin") if seed is None else random_closed(seed)
        try:
            res, warned, sec = solve_recording_warnings(sc, TOL)
        except direct.DegenerateError as exc:  # a contact the generic-perturbation rule cannot decide
            print(f"{sc.name}: {exc}")
            continue
        if res.value == 0.0:
            continue
        ref, ref_warned, ref_sec = solve_recording_warnings(sc, REFERENCE_TOL)
        err = res.value - ref.value
        rows.append(dict(
            scene=sc.name, vertices=sc.components[0].n_vertices, crossings=len(res.crossings), value=res.value,
            reference=ref.value, relative_error=err / ref.value, relative_estimate=res.error_estimate / res.value,
            reference_relative_estimate=ref.error_estimate / ref.value, grid_over_value=res.grid_value / res.value,
            refined_again=bool(res.settings.get("refined_again")), warned=warned, reference_warned=ref_warned,
            over_estimate=abs(err) > res.error_estimate,
            silently_off=abs(err) > res.error_estimate + ref.error_estimate and not warned,
            beyond_tol=abs(err) > TOL * ref.value, seconds=sec, reference_seconds=ref_sec))
        r = rows[-1]
        print(f"{sc.name}: {r['crossings']} crossings, J = {res.value:.7g} (reference {ref.value:.7g}), "
              f"error {r['relative_error']:+.1e}, estimate {r['relative_estimate']:.1e}, grid/J "
              f"{r['grid_over_value']:.1f}{', refined again' if r['refined_again'] else ''}"
              f"{', warned' if warned else ''}, {sec:.2f} s", flush=True)
    write_csv(rows, os.path.join(HERE, "random_closed.csv"))
    n = len(rows)
    print(f"\n{n} scenes with crossings at tol={TOL:g} (hairpin and {n - 1} random): "
          f"{sum(r['over_estimate'] for r in rows)} over their estimate, "
          f"{sum(r['silently_off'] for r in rows)} silently off, {sum(r['beyond_tol'] for r in rows)} beyond tol, "
          f"{sum(r['warned'] for r in rows)} warned, {sum(r['refined_again'] for r in rows)} refined again; "
          f"largest |error| {max(abs(r['relative_error']) for r in rows):.1e}; "
          f"grid/J up to {max(r['grid_over_value'] for r in rows):.1f}; "
          f"{sum(r['reference_warned'] for r in rows)} references warned; "
          f"median time {np.median([r['seconds'] for r in rows]):.2f} s")
    return rows


if __name__ == "__main__":
    main()
