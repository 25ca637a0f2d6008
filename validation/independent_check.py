"""Curved open scenes at ``tol=1e-5`` against a solver written apart from ``direct`` (``independent.py``).

Run ``python validation/independent_check.py [CASE ...]`` (about half an hour for the 13 cases, almost all
of it the reference solver's; a case is ``family`` or ``family:key=value,...``).  The scenes are those of an
independent check at stop 49 (a review acting as the judge of issue 4): open polylines of 90 to 200
vertices, turned by irrational angles, where the curves are chosen inside a piece of ``M x M``, not by a
straight stretch near an end: a sine across a tilted line, two elliptic arcs, a nodal loop and a trochoid
loop (each crossing itself once), the nodal loop across a line, an S-curve and a spiral across a line, a
wiggle crossing a line 7 times, two nearly coincident arcs, a bump 0.012 or 0.003 from a line between two
crossings, random sines.  ``direct.penalty(scene, tol=1e-5)`` (what ``direct penalty --tol 1e-5`` calls)
against the reference ``J`` and its bound.  A row is ``SILENT`` when the difference exceeds the sum of
``error_estimate`` and the reference's bound without a ``ToleranceWarning``, ``over tol`` when it exceeds
``tol`` relative.  Writes ``independent_check.csv`` beside this file.

``--metric g --power 2`` (or any ``--metric``/``--power``: ``g`` with ``p``, ``G`` with ``q``) runs instead a subset
of the cases (:data:`UNEVEN_CASES`, or those named) with UNEVEN references (:func:`uneven`: reference arclength
1 to 3 times the deformed along each curve, a straight line cut into 24 uneven segments first), for
``direct.penalty(scene, metric=..., power=..., tol=1e-5)`` against ``independent.solve(..., refs=..., metric=...,
power=...)``, and writes ``independent_check_<metric><power>.csv`` (e.g. ``independent_check_g2.csv``).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import independent  # noqa: E402
from study import write_csv  # noqa: E402

import direct  # noqa: E402

TOL = 1e-5


def _turned(P, th, shift=(0.0, 0.0)):
    c, s = np.cos(th), np.sin(th)
    return np.asarray(P, float) @ np.array([[c, s], [-s, c]]) + np.asarray(shift)


def sine_line(n=120, amp=0.35, freq=3.7, phase=0.4, slope=0.08, th=0.7071, L=3.0):
    x = np.linspace(0, L, n)
    x2 = np.array([-0.2, L + 0.2])
    return [_turned(np.c_[x, amp * np.sin(freq * x + phase)], th), _turned(np.c_[x2, slope * (x2 - L / 2) + 0.03], th)]


def two_arcs(n=90, th=1.2345):
    t1 = np.linspace(-1.1, 1.15, n)
    t2 = np.linspace(np.pi - 1.2, np.pi + 1.05, n)
    return [_turned(np.c_[np.cos(t1), 0.8 * np.sin(t1)], th),
            _turned(np.c_[1.45 + 0.95 * np.cos(t2), 0.05 + 0.7 * np.sin(t2)], th)]


def nodal_loop(n=140, th=0.31831, a=1.6):
    t = np.linspace(-a, a * 0.93, n)
    return [_turned(np.c_[t * t - 1, 0.6 * (t**3 - t)], th)]


def nodal_loop_line(n=140, th=0.577, a=1.6):
    t = np.linspace(-a, a * 0.93, n)
    return [_turned(np.c_[t * t - 1, 0.6 * (t**3 - t)], th), _turned([[-0.3, -1.2], [0.05, 1.3]], th)]


def s_curve_line(n=150, th=2.0**0.5):
    t = np.linspace(-1, 1, n)
    return [_turned(np.c_[t, 0.5 * np.sin(np.pi * t) * (1 - 0.3 * t) + 0.07], th),
            _turned([[-1.1, -0.12], [1.1, 0.18]], th)]


def spiral_line(n=200, th=0.9, turns=2.3):
    s = np.linspace(0.3, 2 * np.pi * turns, n)
    r = 0.1 + 0.12 * s
    return [_turned(np.c_[r * np.cos(s), r * np.sin(s)], th), _turned([[-2.2, -0.53], [2.3, 0.41]], th)]


def close_wiggle(n=160, amp=0.04, freq=14.0, th=0.4142, L=1.6):
    x = np.linspace(0, L, n)
    return [_turned(np.c_[x, amp * np.sin(freq * x + 0.3)], th), _turned([[-0.1, 0.004], [L + 0.1, 0.006]], th)]


def trochoid(n=200, a=1.6, th=0.2718, w=2.4):
    t = np.linspace(2 * np.pi - w, 2 * np.pi + w * 1.1, n)
    return [_turned(np.c_[0.3 * (t - a * np.sin(t)), 0.3 * (1 - a * np.cos(t))], th)]


def ellipse_arcs_close(n=120, th=0.8):
    t1 = np.linspace(-0.9, 0.9, n)
    t2 = np.linspace(-0.85, 0.95, n)
    return [_turned(np.c_[np.cos(t1), 0.5 * np.sin(t1)], th),
            _turned(np.c_[1.02 * np.cos(t2) + 0.02, 0.45 * np.sin(t2) + 0.03 * np.sin(5 * t2)], th)]


def near_touch(n=160, th=0.6931, gap=0.012, L=2.0):
    """A curve crossing a line twice, with a bump that comes within ``gap`` of the line between the crossings."""
    x = np.linspace(0, L, n)
    y = 0.25 * np.sin(np.pi * x / L * 2.0 + 0.2) + (0.25 - gap) * np.exp(-(((x - 1.05) / 0.12) ** 2))
    return [_turned(np.c_[x, y], th), _turned([[-0.15, 0.24], [L + 0.15, 0.26]], th)]


def rand_sine(seed=0, n=120):
    r = np.random.default_rng(seed)
    return sine_line(n=n, amp=r.uniform(0.15, 0.4), freq=r.uniform(2.5, 6), phase=r.uniform(0, 6),
                     slope=r.uniform(-0.1, 0.1), th=r.uniform(0, 6.28))


FAMILIES = {f.__name__: f for f in (sine_line, two_arcs, nodal_loop, nodal_loop_line, s_curve_line, spiral_line,
                                    close_wiggle, trochoid, ellipse_arcs_close, near_touch, rand_sine)}
CASES = ["sine_line", "two_arcs", "nodal_loop", "trochoid", "nodal_loop_line", "s_curve_line", "spiral_line",
         "close_wiggle", "ellipse_arcs_close", "near_touch", "near_touch:gap=0.003", "rand_sine:seed=0",
         "rand_sine:seed=2"]


def polylines(case: str) -> list[np.ndarray]:
    """The deformed polylines of a case ``family`` or ``family:key=value,...`` (numbers)."""
    family, _, args = case.partition(":")
    kwargs = {k: float(v) if "." in v or "e" in v else int(v) for k, v in (a.split("=") for a in args.split(",") if a)}
    return FAMILIES[family](**kwargs)


def scene(case: str) -> direct.Scene:
    """The polylines as open components, each referenced on a horizontal line in its deformed arclength."""
    comps = []
    for k, P in enumerate(polylines(case)):
        s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(P, axis=0).T))])
        comps.append(direct.Component(np.c_[s, np.full_like(s, 10.0 * k)], P, name=f"C{k}"))
    return direct.Scene(tuple(comps), name=case)


UNEVEN_CASES = ["nodal_loop", "sine_line", "close_wiggle", "two_arcs", "trochoid", "s_curve_line", "near_touch"]


def uneven(P: np.ndarray, k: int, pieces: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """``(deformed, reference)`` for the ``k``-th polyline ``P``: the reference a horizontal line at height ``10 k``
    whose segments are ``f`` times the deformed ones, ``f = 2 + cos(3 pi u + 0.9 k + 0.3)`` at the segment's
    middle (``u`` the normalized deformed arclength), so between 1 and 3 along the curve. A polyline of one
    segment is first cut into ``pieces`` uneven segments (the same curve)."""
    P = np.asarray(P, float)
    if len(P) == 2:
        i = np.arange(1, pieces)
        t = np.r_[0.0, (i + 0.37 * np.sin(1.7 * i)) / pieces, 1.0]
        P = P[0] + t[:, None] * (P[1] - P[0])
    seg = np.hypot(*np.diff(P, axis=0).T)
    u = (np.cumsum(seg) - 0.5 * seg) / seg.sum()
    f = 2.0 + np.cos(3 * np.pi * u + 0.9 * k + 0.3)
    s = np.concatenate([[0.0], np.cumsum(seg * f)])
    return P, np.c_[s, np.full_like(s, 10.0 * k)]


def uneven_polylines(case: str) -> tuple[list, list]:
    """The deformed polylines of a case and their uneven references (:func:`uneven`)."""
    pairs = [uneven(P, k) for k, P in enumerate(polylines(case))]
    return [P for P, _ in pairs], [R for _, R in pairs]


def uneven_scene(case: str) -> direct.Scene:
    polys, refs = uneven_polylines(case)
    return direct.Scene(tuple(direct.Component(R, P, name=f"C{k}") for k, (P, R) in enumerate(zip(polys, refs))),
                        name=case)


def check(case: str, metric: str | None = None, power: float | None = None) -> dict:
    """One case; ``metric``/``power`` given: the uneven run (see the module docstring)."""
    if metric is not None or power is not None:
        return _check_uneven(case, metric or "G", power)
    sc = scene(case)
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = direct.penalty(sc, tol=TOL)
    t_direct = time.perf_counter() - t0
    t0 = time.perf_counter()
    ref = independent.solve(polylines(case))
    t_ref = time.perf_counter() - t0
    err = abs(res.value - ref["value"])
    warned = any(issubclass(w.category, direct.ToleranceWarning) for w in caught)
    verdict = ("SILENT" if err > res.error_estimate + ref["bound"] and not warned
               else "over tol" if err > TOL * ref["value"] else "ok")
    return {"case": case, "crossings": len(res.crossings), "reference_crossings": ref["ncross"],
            "value": res.value, "error_estimate": res.error_estimate, "upper_bound": res.upper_bound,
            "reference": ref["value"], "reference_bound": ref["bound"], "reference_upper": ref["upper"],
            "relative_error": err / ref["value"], "error_over_estimate": err / res.error_estimate,
            "warned": warned, "verdict": verdict, "seconds_direct": t_direct, "seconds_reference": t_ref}


def _check_uneven(case: str, metric: str, power: float | None) -> dict:
    polys, refs = uneven_polylines(case)
    sc = uneven_scene(case)
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = direct.penalty(sc, metric=metric, power=power, tol=TOL)
    t_direct = time.perf_counter() - t0
    t0 = time.perf_counter()
    ref = independent.solve(polys, refs=refs, metric=metric, power=power)
    t_ref = time.perf_counter() - t0
    err = abs(res.value - ref["value"])
    warned = any(issubclass(w.category, direct.ToleranceWarning) for w in caught)
    verdict = ("SILENT" if err > res.error_estimate + ref["bound"] and not warned
               else "over tol" if err > TOL * ref["value"] else "ok")
    return {"case": case, "metric": metric, "power": power, "crossings": len(res.crossings),
            "reference_crossings": ref["ncross"], "value": res.value, "error_estimate": res.error_estimate,
            "upper_bound": res.upper_bound, "reference": ref["value"], "reference_bound": ref["bound"],
            "reference_upper": ref["upper"], "relative_error": err / ref["value"],
            "error_over_estimate": err / res.error_estimate, "warned": warned,
            "warnings": "; ".join(f"{w.category.__name__}: {w.message}" for w in caught), "verdict": verdict,
            "seconds_direct": t_direct, "seconds_reference": t_ref}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cases", nargs="*")
    ap.add_argument("--csv", default=None)
    ap.add_argument("--metric", choices=("G", "g"), default=None,
                    help="run the uneven-reference subset with this metric (see the module docstring)")
    ap.add_argument("--power", type=float, default=None, help="q of G or p of g (default 2)")
    args = ap.parse_args(argv)
    uneven_run = args.metric is not None or args.power is not None
    if not args.cases:
        args.cases = UNEVEN_CASES if uneven_run else CASES
    if args.csv is None:
        name = (f"independent_check_{args.metric or 'G'}{2.0 if args.power is None else args.power:g}.csv"
                if uneven_run else "independent_check.csv")
        args.csv = os.path.join(HERE, name)
    rows = []
    for case in args.cases:
        rows.append(check(case, args.metric, args.power) if uneven_run else check(case))
        r = rows[-1]
        print(f"{case:24s} {r['verdict']:8s} error {r['relative_error']:.1e} relative, {r['error_over_estimate']:.3f} "
              f"of the estimate; direct {r['seconds_direct']:.1f} s, reference {r['seconds_reference']:.0f} s",
              flush=True)
        write_csv(rows, args.csv)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
