"""Straight crossings in any position and parametrization, against the independent eikonal reference.

Run ``python validation/reparametrized.py`` (about one and a half minutes).  Each scene
is two straight segments crossing at a random angle (0.05 to pi - 0.05
radians), with arms of random lengths from 0.01 to 2 on each side of the
crossing (log-uniform: crossings next to an end, and next to a corner of the
domain, are common), turned by a random rotation and scaled by a random
factor.  Each segment is cut into 1 to 3 pieces at random points of the
deformed curve while the reference vertices stay equally spaced, so the
deformation's speed jumps from piece to piece (up to tens of times); each
component may be reversed, and their order swapped.  ``J^G`` does not see the
parametrization, so the reference is that of the unit-speed crossing in
``tests/references.py`` (the eikonal ODE, not computed with ``direct``) times
the scale cubed.  These are the scenes a user's property test is likely to
draw: non-axis-aligned, arbitrarily parametrized, known to many digits.

Every scene runs at ``tol=1e-3`` (one start and the route check) and
``tol=1e-5`` (the second pass).  A row is ``SILENT`` when the error exceeds
the ``error_estimate`` without a ``ToleranceWarning``, ``over tol`` when it
exceeds ``tol``.  Writes ``reparametrized.csv`` beside this file and prints
a count per tolerance.

``python validation/reparametrized.py --uneven`` (about two minutes) draws
each piece's reference length instead, log-uniform in ``10^-2.5`` to
``10^1.5`` (2 or 3 pieces a segment: speeds spanning up to 10^4), and writes
``reparametrized_uneven.csv``.  ``--rev REV`` runs the ``direct`` of a git
revision instead (a temporary worktree), to compare with an older version.
"""

from __future__ import annotations

import csv
import os
import sys

import numpy as np

import direct

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))
from references import crossing_reference  # noqa: E402

sys.path.insert(0, HERE)
from default_tol import _solve as solve_recording_warnings  # noqa: E402
from default_tol import status  # noqa: E402

TOLS = (1e-3, 1e-5)


def scene(seed: int, uneven: bool = False) -> tuple[direct.Scene, float, dict]:
    """A randomly placed and parametrized straight crossing: ``(scene, J^G, its parameters)``."""
    rng = np.random.default_rng(seed)
    a, b, c, d = np.exp(rng.uniform(np.log(0.01), np.log(2.0), 4))
    alpha = rng.uniform(0.05, np.pi - 0.05)
    turn = rng.uniform(0.0, 2 * np.pi)
    scale = rng.uniform(0.3, 3.0)
    R = scale * np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])
    shift = rng.uniform(-5.0, 5.0, 2)
    e = np.array([np.cos(alpha), np.sin(alpha)])
    comps = []
    for k, (start, end) in enumerate(((np.array([-a, 0.0]), np.array([b, 0.0])), (-c * e, d * e))):
        n = int(rng.integers(2, 4)) if uneven else int(rng.integers(1, 4))
        t = np.concatenate([[0.0], np.sort(rng.uniform(0.0, 1.0, n - 1)), [1.0]])
        deformed = (start + t[:, None] * (end - start)) @ R.T + shift
        if uneven:
            x = np.concatenate([[0.0], np.cumsum(10.0 ** rng.uniform(-2.5, 1.5, n))])
        else:
            x = np.linspace(0.0, rng.uniform(0.5, 3.0), n + 1)
        reference = np.column_stack([x, np.full(n + 1, 10.0 * k)])
        if rng.random() < 0.5:
            deformed, reference = deformed[::-1], reference[::-1]
        comps.append(direct.Component(reference, deformed, name="AB"[k]))
    if rng.random() < 0.5:
        comps.reverse()
    exact = crossing_reference(alpha, a, b, c, d) * scale**3
    return direct.Scene(tuple(comps), name=f"seed {seed}"), exact, dict(a=a, b=b, c=c, d=d, angle=alpha,
                                                                      scale=scale)


def main(seeds=range(1000, 1200), uneven: bool = False, out: str = "reparametrized.csv") -> list[dict]:
    rows = []
    for seed in seeds:
        sc, exact, params = scene(seed, uneven)
        for tol in TOLS:
            res, warned, seconds = solve_recording_warnings(sc, tol)
            err = abs(res.value - exact)
            verdict = status(err / exact, res.error_estimate / exact, warned, tol)
            rows.append(dict(seed=seed, **params, tol=tol, value=res.value, reference=exact,
                             relative_error=err / exact, relative_estimate=res.error_estimate / exact,
                             over_estimate=err > res.error_estimate, warned=warned,
                             above_upper_bound=exact > res.upper_bound * (1 + 1e-10), seconds=seconds, status=verdict))
            if verdict != "ok" or err > res.error_estimate:
                print(f"seed {seed} tol {tol:g}: error {err / exact:.2e}, estimate {res.error_estimate / exact:.2e}, "
                      f"warned {warned}: {verdict}", flush=True)
    with open(os.path.join(HERE, out), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    for tol in TOLS:
        sub = [r for r in rows if r["tol"] == tol]
        err = np.array([r["relative_error"] for r in sub])
        est = np.array([r["relative_estimate"] for r in sub])
        print(f"tol={tol:g}: {len(sub)} scenes; largest error {err.max():.1e} relative; "
              f"{sum(r['over_estimate'] for r in sub)} over their estimate "
              f"({sum(r['status'] == 'SILENT' for r in sub)} without a warning); "
              f"{sum(r['status'] == 'over tol' for r in sub)} over tol; {sum(r['warned'] for r in sub)} warned; "
              f"estimates above 10 tol: {int((est > 10 * tol).sum())}; J above upper_bound: "
              f"{sum(r['above_upper_bound'] for r in sub)}; median time {np.median([r['seconds'] for r in sub]):.3f} s")
    return rows


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--uneven", action="store_true", help="reference pieces of lengths 10^-2.5 to 10^1.5")
    ap.add_argument("--rev", help="run the direct of this git revision (a temporary worktree)")
    args = ap.parse_args()
    name = "reparametrized_uneven" if args.uneven else "reparametrized"
    if args.rev:
        from ab import at_revision

        # the same script, importing that revision's direct
        at_revision(args.rev, f"import reparametrized as r; r.main(uneven={args.uneven}, "
                              f"out={name + '_' + args.rev + '.csv'!r})")
    else:
        main(uneven=args.uneven, out=name + ".csv")
