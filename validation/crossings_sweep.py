"""Straight crossings against the independent eikonal reference, dressed up as a user would send them.

Run ``python validation/crossings_sweep.py`` (about four minutes).  Each scene
is two straight arms crossing at a random angle, with a known ``J``
(``tests/references.py``: the eikonal ODE of a straight crossing, not
computed with ``direct``), solved at ``tol=1e-5``.  Two families:

* ``reparametrized`` (metric ``G``): extra collinear vertices at random
  places, a random reference polyline (``G`` does not see the reference,
  Example 14), a random rigid motion of the deformation;
* ``extreme`` (``G`` and ``g``, unit speed): arms from 0.02 to 2 long, and a
  vertex next to the crossing point (1e-7 to 1e-3 of its arm away) or exactly
  on it.

A row passes when the relative error is at most ``1e-5`` and at most the
``error_estimate``.

A third family, ``near a corner`` (``G`` and ``g``, ``tol=1e-5``), has arms
from 0.01 to 2 on the plain two-segment crossing, so that the point is often
a few cells from two sides of a thin domain.

A fourth family, ``corner, tol 1e-3``, measures what the default tolerance
gives near corners (arms 0.015 to 2, a vertex on the crossing on one arm, the
other or both), at 64, 96, 128 and 160 cells and ``tol=1e-3``, without the
second pass: a row passes when the error is at most ``1e-3`` and at most
the estimate.  Writes ``crossings_sweep.csv`` beside this file and prints a
summary per family.
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
from references import crossing_reference  # noqa: E402

TOL = 1e-5


def _arm(ts: np.ndarray, theta: float) -> np.ndarray:
    return ts[:, None] * np.array([np.cos(theta), np.sin(theta)])[None, :]


def reparametrized(rng: np.random.Generator, case: int):
    """G: collinear vertices, a random reference polyline and a rigid motion; the reference value is unchanged."""
    alpha = rng.uniform(0.05, np.pi - 0.05)
    a, b, c, d = rng.uniform(0.3, 1.5, 4)
    comps = []
    for k, (name, (lo, hi), theta) in enumerate((("A", (a, b), 0.0), ("B", (c, d), alpha))):
        ts = np.sort(np.concatenate([[-lo, hi], rng.uniform(-lo, hi, rng.integers(0, 4))]))
        steps = rng.uniform(0.2, 2.0, len(ts) - 1)
        turn = rng.uniform(-0.6, 0.6, len(ts) - 1).cumsum()
        reference = np.vstack([[0.0, 0.0], np.cumsum(steps[:, None] * np.column_stack([np.cos(turn), np.sin(turn)]),
                                                     axis=0)]) + [20.0 * k, 0.0]
        comps.append((name, reference, _arm(ts, theta)))
    rot = 1.0 + case
    R = np.array([[np.cos(rot), -np.sin(rot)], [np.sin(rot), np.cos(rot)]])
    shift = rng.uniform(-3, 3, 2)
    scene = direct.Scene(tuple(direct.Component(r, x @ R.T + shift, name=n) for n, r, x in comps))
    return scene, "G", crossing_reference(alpha, a, b, c, d, k=2), f"alpha={alpha:.4f}"


def extreme(rng: np.random.Generator, case: int):
    """Unit speed, arms 0.02 to 2, a vertex near or at the crossing point; G and g alternately."""
    alpha = rng.uniform(0.1, np.pi - 0.1)
    a, b, c, d = np.exp(rng.uniform(np.log(0.02), np.log(2.0), 4))
    metric = ("G", "g")[case % 2]
    comps = []
    for k, (name, (lo, hi), theta) in enumerate((("A", (a, b), 0.0), ("B", (c, d), alpha))):
        mode = rng.integers(0, 3)
        extra = {0: [], 1: [rng.choice([-1, 1]) * 10 ** rng.uniform(-7, -3) * min(lo, hi)], 2: [0.0]}[int(mode)]
        ts = np.sort(np.concatenate([[-lo, hi], extra]))
        reference = np.column_stack([ts - ts[0], np.full_like(ts, 10.0 * (1 + k))])
        comps.append(direct.Component(reference, _arm(ts, theta), name=name))
    ref = crossing_reference(alpha, a, b, c, d, k=2 if metric == "G" else 4)
    return direct.Scene(tuple(comps)), metric, ref, f"alpha={alpha:.4f} arms={a:.3g},{b:.3g},{c:.3g},{d:.3g}"


def corner(rng: np.random.Generator, case: int):
    """Near a corner: arms 0.015 to 2, a vertex on the crossing (first arm, second arm, both); G and G-then-g."""
    alpha = rng.uniform(0.2, np.pi - 0.2)
    a, b, c, d = np.exp(rng.uniform(np.log(0.015), np.log(2.0), 4))
    which = case % 3
    comps = []
    for k, ((lo, hi), theta) in enumerate((((a, b), 0.0), ((c, d), alpha))):
        ts = np.array([-lo, 0.0, hi]) if which in (k, 2) else np.array([-lo, hi])
        reference = np.column_stack([ts - ts[0], np.full_like(ts, 5.0 * (k + 1))])
        comps.append(direct.Component(reference, _arm(ts, theta), name="AB"[k]))
    what = f"alpha={alpha:.4f} arms={a:.3g},{b:.3g},{c:.3g},{d:.3g} vertex on {('A', 'B', 'A and B')[which]}"
    return direct.Scene(tuple(comps)), alpha, (a, b, c, d), what


def _run(rows, family, case, scene, metric, ref, what, tol, **kw):
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        t0 = time.perf_counter()
        res = direct.penalty(scene, metric, tol=tol, **kw)
        dt = time.perf_counter() - t0
    err = abs(res.value - ref)
    ok = err <= tol * ref and err <= max(res.error_estimate, 1e-14 * ref)
    rows.append(dict(family=family, case=case, metric=metric, scene=what, settings=f"tol={tol:g} {kw}",
                     reference=ref, value=res.value, rel_error=err / ref, rel_estimate=res.error_estimate / ref,
                     warned=len(w) > 0, passed=ok, seconds=dt))
    print(f"{family} {case:2d} {metric} {what} {kw}: error {err / ref:.1e}, estimate {res.error_estimate / ref:.1e}"
          f" {'ok' if ok else 'FAILED'}", flush=True)


def main(n: int = 40) -> list[dict]:
    rows: list[dict] = []
    for family, make, seed in (("reparametrized", reparametrized, 1), ("extreme", extreme, 5)):
        rng = np.random.default_rng(seed)
        for case in range(n):
            scene, metric, ref, what = make(rng, case)
            _run(rows, family, case, scene, metric, ref, what, TOL)
    rng = np.random.default_rng(11)
    for case in range(60):
        alpha = rng.uniform(0.1, np.pi - 0.1)
        arms = np.exp(rng.uniform(np.log(0.01), np.log(2.0), 4))
        scene = direct.scenes.cross(*arms, angle=alpha)
        what = f"alpha={alpha:.4f} arms=" + ",".join(f"{x:.3g}" for x in arms)
        for metric, k in (("G", 2), ("g", 4)):
            _run(rows, "near a corner", case, scene, metric, crossing_reference(alpha, *arms, k=k), what, TOL)
    rng = np.random.default_rng(0)
    for case in range(24):
        scene, alpha, arms, what = corner(rng, case)
        for metric, k in (("G", 2), ("g", 4)):
            ref = crossing_reference(alpha, *arms, k=k)
            for resolution in (64, 96, 128, 160):
                _run(rows, "corner, tol 1e-3", case, scene, metric, ref, what, 1e-3, resolution=resolution,
                     second_pass=False)
    write_csv(rows, os.path.join(HERE, "crossings_sweep.csv"))
    for family in dict.fromkeys(r["family"] for r in rows):
        rs = [r for r in rows if r["family"] == family]
        failed = [r for r in rs if not r["passed"]]
        worst = max(rs, key=lambda r: r["rel_error"])
        print(f"{family}: {len(rs)} runs, {len(failed)} failed; largest relative error {worst['rel_error']:.1e} "
              f"(case {worst['case']}, estimate {worst['rel_estimate']:.1e}); {sum(r['warned'] for r in rs)} "
              f"warnings; at most {max(r['seconds'] for r in rs):.2f} s a run")
        for r in failed:
            print(f"  FAILED {r['case']} {r['metric']} {r['scene']} {r['settings']}: error {r['rel_error']:.1e}, "
                  f"estimate {r['rel_estimate']:.1e}")
    return rows


if __name__ == "__main__":
    main()
