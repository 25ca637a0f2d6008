"""Are the values at the loose tolerances within their estimates of a tight one?

Run ``python validation/default_tol.py`` (about seven minutes).  For the random
interval scenes of the family of ``validation/multistart.py`` (which runs seeds
100 to 139) and ``route_check.py`` (2 or 3 polylines of 7 vertices, 1 to 10
crossings), seeds 100 to 299, it computes ``J`` at ``tol=1e-3`` (the default:
one start and the route check of the chosen curves; a domain with a grazing
crossing gets the second pass at every tolerance), at ``tol=1e-4`` (the full second pass, the default from there
down) and at ``tol=1e-6`` (the second pass too), the reference.  The reference
is computed by ``direct`` too: this is a check of self-consistency across
tolerances, not of the method against an independent value
(``crossings_sweep.py`` and ``convergence.py`` do that on straight crossings).

Unlike ``route_check.py``, which compares the chosen curves with and without
their check, this measures the whole value: a curve that the assignment did
not choose, refined in a worse local geodesic, would show here as a value
above the reference.  Two measures: a row is *over its estimate* when the
value differs from the reference by more than its own ``error_estimate``, and
*silently off* when it differs by more than the sum of both estimates (the
reference's own estimate included: it warns when its second pass saw a spread
above ``1e-6``) with no ``ToleranceWarning``.
Writes ``default_tol.csv`` and ``default_tol.png`` beside this file and prints
a summary per tolerance.
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

TOLS = (1e-3, 1e-4)
REFERENCE_TOL = 1e-6


def _solve(scene, tol, **kwargs):
    """``(result, warned, seconds)`` of ``direct.penalty(scene, tol=tol, **kwargs)``, ToleranceWarnings recorded."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", direct.ToleranceWarning)
        t0 = time.perf_counter()
        res = direct.penalty(scene, tol=tol, **kwargs)
        seconds = time.perf_counter() - t0
    warned = any(issubclass(w.category, direct.ToleranceWarning) for w in caught)
    return res, warned, seconds


def status(error: float, estimate: float, warned: bool, tol: float) -> str:
    """``"SILENT"`` (off by more than the estimate, without a warning), ``"over tol"`` or ``"ok"``; relative values."""
    if error > estimate and not warned:
        return "SILENT"
    return "over tol" if error > tol else "ok"


def main(seeds=range(100, 300)) -> list[dict]:
    rows = []
    for seed, sc in study_scenes(seeds):
        ref, ref_warned, ref_seconds = _solve(sc, REFERENCE_TOL)
        if ref.value == 0.0:
            continue
        for tol in TOLS:
            res, warned, seconds = _solve(sc, tol)
            error = res.value - ref.value
            allowed = res.error_estimate + ref.error_estimate  # both absolute
            rows.append(dict(seed=seed, crossings=len(res.crossings), tol=tol, value=res.value, reference=ref.value,
                             relative_error=error / ref.value, relative_estimate=res.error_estimate / res.value,
                             reference_relative_estimate=ref.error_estimate / ref.value, warned=warned,
                             reference_warned=ref_warned, over_estimate=abs(error) > res.error_estimate,
                             silently_off=abs(error) > allowed and not warned,
                             beyond_tol=abs(error) > tol * ref.value, seconds=seconds,
                             reference_seconds=ref_seconds))
            r = rows[-1]
            if r["over_estimate"] or r["beyond_tol"]:
                print(f"seed {seed} tol {tol:g}: {r['relative_error']:+.1e} relative, estimate "
                      f"{r['relative_estimate']:.1e}{' (warned)' if warned else ''}, reference estimate "
                      f"{r['reference_relative_estimate']:.1e}{' (warned)' if ref_warned else ''}", flush=True)
    write_csv(rows, os.path.join(HERE, "default_tol.csv"))
    for tol in TOLS:
        rs = [r for r in rows if r["tol"] == tol]
        err = np.array([abs(r["relative_error"]) for r in rs])
        est = np.array([(r["relative_estimate"] * r["value"] + r["reference_relative_estimate"] * r["reference"])
                        / r["reference"] for r in rs])
        t = sum(r["seconds"] for r in rs)
        t_ref = sum(r["reference_seconds"] for r in rs)
        print(f"tol={tol:g}: {len(rs)} scenes; {sum(r['over_estimate'] for r in rs)} over their own estimate, "
              f"{sum(r['silently_off'] for r in rs)} silently off, "
              f"{sum(r['beyond_tol'] for r in rs)} beyond tol, {sum(r['warned'] for r in rs)} warned; "
              f"largest error {err.max():.1e} relative, largest error / (both estimates) {np.max(err / est):.2f}; "
              f"{sum(r['reference_warned'] for r in rs)} references warned; "
              f"time against tol={REFERENCE_TOL:g}: {t / t_ref:.2f} ({t:.0f} s / {t_ref:.0f} s)")
    _chart(rows)
    return rows


def _chart(rows):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.5))
    floor = 1e-12
    for k, tol in enumerate(TOLS):
        rs = [r for r in rows if r["tol"] == tol]
        est = np.array([r["relative_estimate"] + r["reference_relative_estimate"] for r in rs])
        err = np.maximum(np.array([abs(r["relative_error"]) for r in rs]), floor)
        ax.loglog(est, err, "o^"[k], ms=4, alpha=0.7, color=f"C{k}", label=f"tol={tol:g}")
    lim = [1e-8, 1e-2]
    ax.loglog(lim, lim, "k--", lw=0.8, label="error = estimate")
    ax.set_xlabel(f"error_estimate / J (plus that of the tol={REFERENCE_TOL:g} reference)")
    ax.set_ylabel(f"|J - J(tol={REFERENCE_TOL:g})| / J  (1e-12 when equal)")
    ax.set_title(f"loose tolerances against tol={REFERENCE_TOL:g}, {len(rows) // len(TOLS)} random scenes")
    ax.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    fig.savefig(os.path.join(HERE, "default_tol.png"), dpi=120)


if __name__ == "__main__":
    main()
