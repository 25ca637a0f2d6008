"""``nested``: does refining the chosen closed curve again, from its own polyline, find a shorter one?

Run ``python validation/restarts.py`` (about half a minute).  ``nested`` (two concentric regular
128-gons, section 3.3.4) needs a closed curve on each of the tori ``M1 x M2`` and ``M2 x M1``; rotating
it along the circles nearly preserves its length, so the refinement faces a family of nearly tied
geodesics and keeps the shortest of three starts (docs/record.md, *Known limitations*).  This computes
``J`` at ``tol=1e-5`` and, for each chosen closed curve, refines it again (``refine_many`` with the same
tolerance) from its own polyline and from copies shifted along both circles by 0.25, 0.5, 0.75 and 1
edge (a whole edge maps the scene onto itself).  Prints the lengths; a restart shorter than the chosen
curve shows how far the value sits above ``J``.
"""

from __future__ import annotations

import sys
import warnings

import numpy as np

import direct
from direct.refinement import GeodesicJob, refine_many

P = sys.modules["direct.penalty"]
S = sys.modules["direct.starts"]  # the other starts: _more_starts refines and picks there


def main(tol: float = 1e-5) -> list[tuple[float, list[float]]]:
    found: list[tuple[float, list[float]]] = []
    refine = P.refine_many
    context = {}

    def spy(domain, metric, jobs, *args, **kwargs):
        context["args"] = (domain, metric, kwargs)
        return refine(domain, metric, jobs, *args, **kwargs)

    choose = P._best_of_starts

    def restart(starts, family=0.01, by_bound=False):
        if not by_bound:  # not the closed curves of a torus (the mirror pairs, the shifted starts): as it was
            return choose(starts, family, by_bound)
        best = min(starts, key=lambda rp: rp.length)
        domain, metric, kwargs = context["args"]
        edges = np.array([c.length / c.n_segments for c in domain.comps])
        jobs = [GeodesicJob(best.points + f * edges, closed=True) for f in (0.0, 0.25, 0.5, 0.75, 1.0)]
        again = [rp.length for rp in refine_many(domain, metric, jobs, **kwargs)]
        found.append((best.length, again))
        print(f"chosen closed curve {best.length:.10f} (estimate {best.error_estimate:.1e}); refined again from it "
              f"and shifted by 0.25, 0.5, 0.75, 1 edge: " + ", ".join(f"{v:.10f}" for v in again), flush=True)
        return choose(starts, family, by_bound)

    P.refine_many, P._best_of_starts = spy, restart
    S.refine_many, S._best_of_starts = spy, restart
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", direct.ToleranceWarning)
            res = direct.penalty("nested", tol=tol)
    finally:
        P.refine_many, P._best_of_starts = refine, choose
        S.refine_many, S._best_of_starts = refine, choose
    low = sum(min([b] + a) for b, a in found)
    print(f"J(nested) at tol={tol:g}: {res.value:.10f}, estimate {res.error_estimate:.2e} "
          f"({res.error_estimate / res.value:.1e} relative); the shortest curves found, summed: {low:.10f} "
          f"({(res.value - low) / res.value:.1e} relative below the value)")
    return found


if __name__ == "__main__":
    main()
