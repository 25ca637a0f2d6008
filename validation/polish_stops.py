"""Could the L-BFGS-B polish stop earlier?  Its progress, evaluation by evaluation, on the star and ellipse.

Run ``python validation/polish_stops.py`` (about two and a half minutes alone).  The star crossing an
ellipse of ``star_ellipse.py`` (20 crossings, ``G``, the default ``tol=1e-3``), listed as built, spends
about half its time in the L-BFGS-B polish (:func:`direct.refinement._lbfgs_polish`), where Newton did
not converge.  This records every polish (its evaluations' objective, the length over the starting
length) and replays stopping rules on those records: stop once the last ``K`` evaluations gained less
than ``c * tol``.  For each rule it gives the evaluations it would use (against the polish as it is,
100 iterations at most) and what it would leave: the largest loss and how many polishes would stop
more than ``1e-3 * tol`` above where the polish ends.  Writes ``polish_stops.csv`` beside this file
(docs/record.md, *The test suite on another processor*).
"""

from __future__ import annotations

import os
import sys
import time
import warnings

import numpy as np

import direct
from direct import refinement

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from star_ellipse import star_and_ellipse  # noqa: E402
from study import write_csv  # noqa: E402

TOL = 1e-3


def record_polishes() -> tuple[list[np.ndarray], float, float, direct.Penalty]:
    """Run the scene once, keeping each polish's objective at every evaluation.

    Returns ``(histories, seconds in the polish, seconds in all, result)``.
    """
    histories: list[np.ndarray] = []
    seconds = [0.0]
    inner = refinement.minimize

    def spy(fun, z, **kwargs):
        seen: list[float] = []

        def f(zz):
            v = fun(zz)
            seen.append(v[0])
            return v

        t = time.perf_counter()
        res = inner(f, z, **kwargs)
        seconds[0] += time.perf_counter() - t
        histories.append(np.array(seen))
        return res

    refinement.minimize = spy
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", direct.ToleranceWarning)
            t = time.perf_counter()
            res = direct.penalty(star_and_ellipse(0), tol=TOL)
            total = time.perf_counter() - t
    finally:
        refinement.minimize = inner
    return histories, seconds[0], total, res


def replay(histories: list[np.ndarray], window: int, c: float) -> dict:
    """Stop each polish at the first evaluation whose last ``window`` evaluations gained less than ``c * TOL``."""
    used, losses = 0, []
    for h in histories:
        best = np.minimum.accumulate(h)
        gained = best[:-window] - best[window:]  # gained[i]: over evaluations i .. i + window
        small = np.flatnonzero(gained < c * TOL)
        stop = int(small[0]) + window + 1 if small.size else len(h)
        used += stop
        losses.append(best[stop - 1] - best[-1])
    losses = np.array(losses)
    return dict(window=window, c=c, evaluations=used, share=used / sum(len(h) for h in histories),
                largest_loss=float(losses.max()), polishes_over_1e_3_tol=int((losses > 1e-3 * TOL).sum()))


def main() -> None:
    histories, polish, total, res = record_polishes()
    n_eval = sum(len(h) for h in histories)
    print(f"J = {res.value:.10g} (estimate {res.error_estimate:.2g}) in {total:.1f} s; {len(histories)} polishes, "
          f"{n_eval} evaluations, {polish:.1f} s ({polish / total:.0%})")
    for eps in (1e-4, 1e-6, 1e-8):
        best = [np.minimum.accumulate(h) for h in histories]
        need = sum(int(np.argmax(b <= b[-1] + eps)) + 1 for b in best)
        print(f"  evaluations to come within {eps:g} of each polish's end: {need} ({need / n_eval:.0%})")
    rows = [replay(histories, w, c) for w in (10, 20, 30) for c in (1e-3, 1e-4)]
    for r in rows:
        print(f"  stop after {r['window']} evaluations gaining < {r['c']:g} tol: {r['share']:.0%} of the evaluations, "
              f"largest loss {r['largest_loss']:.2g}, {r['polishes_over_1e_3_tol']} polishes over 1e-3 tol")
    write_csv(rows, os.path.join(HERE, "polish_stops.csv"))


if __name__ == "__main__":
    main()
