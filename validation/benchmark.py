"""Side-by-side benchmark of ways to compute J, in one process.

Run ``python validation/benchmark.py`` (about four minutes).  It writes, beside
this file, ``benchmark.csv`` (one row per run), ``benchmark.png`` (relative
error against wall time, log-log) and ``benchmark.md`` (a summary with
ratios).  Times are wall times on a shared machine: read the ratios, and the
``calibration`` row (a fixed numpy workload timed in the same run) to compare
runs made on different days.

Methods, on the 60-degree crossing (``J^G`` known from shared/NUMERICS.md):

* ``direct``: the pipeline (grid Dijkstra, then refined geodesics) at several tolerances;
* ``dijkstra-8``, ``dijkstra-16``: grid Dijkstra alone at several resolutions (uniform grids);
* ``networkx``: the same grid with networkx's Dijkstra (the straightforward implementation:
  a networkx graph, a full search from every terminal, program (34), no refinement);
* ``skfmm-1``, ``skfmm-2``: scikit-fmm fast marching (orders 1 and 2) on the same
  metric, which is isotropic here (``|r|^2 |dx|`` with unit speeds).

Plus the assignment program (34) solved by ``linear_sum_assignment`` against
the paper's enumeration, the growth of the pipeline's time with the number
of crossings and with ``1 / tol``, and the networkx pipeline (a networkx graph,
a full Dijkstra search from every terminal, no refinement) against this whole
pipeline (a grid refined locally around crossing points, bounded scipy
searches, then the refinement) at the same finest step (128 cells) on zigzags of
3, 10, 30 and 100 crossings: the networkx pipeline on the uniform grid of that
step (the straightforward implementation) and on the same locally refined
graph; also the networkx grid stage followed by this refinement, and this
pipeline on the uniform grid.  Last, the ratio of the straightforward networkx
pipeline to this one against the finest step (64 to 256 cells, 384 on the
10-crossing zigzag), on zigzags of 3, 10 and 30 crossings: networkx's cost
grows with the number of grid nodes, this pipeline's refinement does not.
"""

from __future__ import annotations

import csv
import os
import time

import numpy as np

import direct
from direct.matching import brute_force, solve

HERE = os.path.dirname(os.path.abspath(__file__))
EXACT = 2 * 0.2581226580725618  # J^G of cross60 (shared/NUMERICS.md)
#: zigzags and finest steps (cells) of the sweep of the networkx ratio against the resolution
SWEEP_CROSSINGS = (3, 10, 30)
SWEEP_RESOLUTIONS = (64, 128, 192, 256)


def calibration() -> float:
    """Seconds of a fixed numpy workload (sorting and a matrix product)."""
    rng = np.random.default_rng(0)
    a = rng.random(2_000_000)
    m = rng.random((300, 300))
    t0 = time.perf_counter()
    for _ in range(3):
        np.sort(a)
        m @ m
    return (time.perf_counter() - t0) / 3


def timed(fn, *args, repeat: int = 1, **kwargs):
    """The result of ``fn(*args, **kwargs)`` and the best wall time of ``repeat`` calls."""
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn(*args, **kwargs)
        best = min(best, time.perf_counter() - t0)
    return out, best


def fmm_value(n: int, order: int) -> float:
    """Twice the travel time from the boundary of [-1, 1]^2 to the crossing at 0, speed 1 / |r|^2."""
    import skfmm

    x = np.linspace(-1, 1, n)
    X1, X2 = np.meshgrid(x, x, indexing="ij")
    c = np.cos(np.pi / 3)
    rho = X1**2 + X2**2 - 2 * X1 * X2 * c
    rho = np.maximum(rho, 1e-6 * rho.max())
    h = x[1] - x[0]
    phi = np.minimum(np.minimum(X1 + 1, 1 - X1), np.minimum(X2 + 1, 1 - X2)) - 0.5 * h  # boundary just inside
    t = skfmm.travel_time(phi, 1.0 / rho, dx=[float(h), float(h)], order=order)
    mid = n // 2
    return 2 * float(t[mid, mid])


def zigzag(n_cross: int, seed: int = 0) -> direct.Scene:
    """A straight line crossed ``n_cross`` times by a zigzag (alternating signs)."""
    rng = np.random.default_rng(seed)
    x = np.linspace(0, n_cross, n_cross + 1)
    x[0], x[-1] = -0.5, n_cross + 0.5
    y = np.where(np.arange(n_cross + 1) % 2 == 0, 1.0, -1.0) * rng.uniform(0.5, 1.0, n_cross + 1)
    ref = np.column_stack([np.linspace(-0.5, n_cross + 0.5, n_cross + 1), np.full(n_cross + 1, 5.0)])
    line = direct.Component([[-1, 0], [n_cross + 1, 0]], [[-1, 0], [n_cross + 1, 0]], name="line")
    return direct.Scene((line, direct.Component(ref, np.column_stack([x, y]), name="zigzag")))


def main() -> list[dict]:
    rows: list[dict] = []
    cal = calibration()
    rows.append(dict(method="calibration", setting="numpy workload", value="", rel_error="", seconds=cal))
    scene = direct.scenes.get("cross60")
    direct.penalty(scene)  # warm up

    for tol in [1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7]:
        res, dt = timed(direct.penalty, scene, tol=tol, repeat=3)
        rows.append(dict(method="direct", setting=f"tol={tol:g}", value=res.value,
                         rel_error=abs(res.value - EXACT) / EXACT, seconds=dt))
    for nb in (8, 16):
        for resolution in (24, 48, 96, 192, 384):
            res, dt = timed(direct.penalty, scene, refine=False, neighbours=nb, resolution=resolution, coarsen=1,
                            repeat=2)
            rows.append(dict(method=f"dijkstra-{nb}", setting=f"N={resolution}", value=res.value,
                             rel_error=abs(res.value - EXACT) / EXACT, seconds=dt))
    for resolution in (24, 48, 96):
        res, dt = timed(direct.penalty, scene, refine=False, backend="networkx", resolution=resolution, coarsen=1)
        rows.append(dict(method="networkx", setting=f"N={resolution}", value=res.value,
                         rel_error=abs(res.value - EXACT) / EXACT, seconds=dt))
    try:
        for order in (1, 2):
            for n in (51, 101, 201, 401):
                val, dt = timed(fmm_value, n, order, repeat=2)
                rows.append(dict(method=f"skfmm-{order}", setting=f"N={n}", value=val,
                                 rel_error=abs(val - EXACT) / EXACT, seconds=dt))
    except ImportError:
        print("scikit-fmm is not installed (pip install scikit-fmm): fast marching left out")

    rng = np.random.default_rng(1)
    for n in (2, 4, 6, 8):
        A, a0, b0 = rng.random((n, n)), rng.random(n), rng.random(n)
        (v1, _), t1 = timed(solve, A, a0, b0, repeat=5)
        v2, t2 = timed(brute_force, A, a0, b0)
        assert abs(v1 - v2) <= 1e-12
        rows.append(dict(method="assignment (34)", setting=f"n+=n-={n}", value=v1, rel_error=0.0, seconds=t1))
        rows.append(dict(method="enumeration (34)", setting=f"n+=n-={n}", value=v2, rel_error=0.0, seconds=t2))

    for n in (10, 30, 100):
        sc = zigzag(n)
        res, dt = timed(direct.penalty, sc, repeat=3 if n <= 30 else 1)
        rows.append(dict(method="direct, zigzag", setting=f"crossings={len(res.crossings)}", value=res.value,
                         rel_error=res.error_estimate / res.value, seconds=dt))
    # the cost against 1/tol on the 10-crossing zigzag (relative errors against tol 1e-8)
    sc = zigzag(10)
    ref = direct.penalty(sc, tol=1e-8).value
    for tol in (1e-2, 1e-3, 1e-4, 1e-5, 1e-6):
        res, dt = timed(direct.penalty, sc, tol=tol, repeat=3)
        rows.append(dict(method="direct, zigzag tol", setting=f"tol={tol:g}", value=res.value,
                         rel_error=abs(res.value - ref) / ref, seconds=dt))
    # networkx (full searches from every terminal) against scipy (bounded searches) at equal resolution: the finest
    # step (128 cells) everywhere for the straightforward pipeline; the same locally refined graph for the others
    for n in (3, 10, 30, 100):
        sc = zigzag(n)
        for backend in ("scipy", "networkx"):
            res, dt = timed(direct.penalty, sc, refine=False, backend=backend, repeat=2 if backend == "scipy" else 1)
            rows.append(dict(method=f"grid stage, {backend}", setting=f"crossings={n}", value=res.value,
                             rel_error="", seconds=dt))
            res, dt = timed(direct.penalty, sc, backend=backend, repeat=2 if backend == "scipy" else 1)
            rows.append(dict(method=f"pipeline, {backend}", setting=f"crossings={n}", value=res.value,
                             rel_error="", seconds=dt))
            res, dt = timed(direct.penalty, sc, refine=False, backend=backend, coarsen=1,
                            repeat=2 if backend == "scipy" else 1)
            rows.append(dict(method=f"uniform grid stage, {backend}", setting=f"crossings={n}", value=res.value,
                             rel_error="", seconds=dt))
        res, dt = timed(direct.penalty, sc, coarsen=1, repeat=2)
        rows.append(dict(method="pipeline, scipy, uniform grid", setting=f"crossings={n}", value=res.value,
                         rel_error="", seconds=dt))

    # the same ratio against the resolution: the straightforward networkx pipeline (uniform grid, full searches)
    # against this whole pipeline at finest steps of 64 to 256 cells (384 on the 10-crossing zigzag); the
    # networkx value's relative error is measured against this pipeline's value at the same step
    for n in SWEEP_CROSSINGS:
        sc = zigzag(n)
        for resolution in SWEEP_RESOLUTIONS + ((384,) if n == 10 else ()):
            ours, dt = timed(direct.penalty, sc, resolution=resolution, repeat=2)
            rows.append(dict(method=f"sweep, direct, {n} crossings", setting=f"N={resolution}", value=ours.value,
                             rel_error=ours.error_estimate / ours.value, seconds=dt))
            res, dt = timed(direct.penalty, sc, refine=False, backend="networkx", resolution=resolution, coarsen=1)
            rows.append(dict(method=f"sweep, networkx, {n} crossings", setting=f"N={resolution}", value=res.value,
                             rel_error=abs(res.value - ours.value) / ours.value, seconds=dt))

    with open(os.path.join(HERE, "benchmark.csv"), "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=["method", "setting", "value", "rel_error", "seconds"])
        w.writeheader()
        w.writerows(rows)
    _chart(rows)
    _summary(rows, cal)
    return rows


def _chart(rows):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, ax2, ax3) = plt.subplots(1, 3, figsize=(17, 4.6))

    def lines(axis, series, x, y):
        """One log-log line per ``(method, style, label)`` of ``series``, points sorted by ``x``."""
        for method, style, label in series:
            pts = sorted((x(r), y(r)) for r in rows if r["method"] == method)
            if pts:
                axis.loglog(*zip(*pts), style, label=label)

    lines(ax, [(m, st, m) for m, st in (("direct", "o-"), ("dijkstra-8", "s--"), ("dijkstra-16", "d--"),
                                        ("networkx", "v:"), ("skfmm-1", "^-."), ("skfmm-2", "<-."))],
          lambda r: r["seconds"], lambda r: max(r["rel_error"], 1e-16))
    ax.set_xlabel("wall time per call (s)")
    ax.set_ylabel("relative error of J^G (60-degree crossing)")
    ax.set_title("error against time: lower left is better")
    ax.legend(fontsize=8)
    # the cost against the number of crossings, at equal resolution (128)
    lines(ax2, [("pipeline, scipy", "o-", "direct (locally refined grid + refinement)"),
                ("pipeline, scipy, uniform grid", "o:", "direct on the uniform grid"),
                ("uniform grid stage, networkx", "v:", "networkx, uniform grid only (straightforward)"),
                ("grid stage, networkx", "^:", "networkx, locally refined grid only"),
                ("pipeline, networkx", "s--", "networkx grid + this refinement"),
                ("grid stage, scipy", "d-.", "direct, grid stage only")],
          lambda r: int(r["setting"].split("=")[1]), lambda r: r["seconds"])
    ax2.set_xlabel("crossings (zigzag through a line)")
    ax2.set_ylabel("wall time per call (s)")
    ax2.set_title("cost against crossings, equal finest step (128 cells)")
    ax2.legend(fontsize=8)
    # the networkx ratio against the resolution
    for n, style in zip(SWEEP_CROSSINGS, ("o-", "s-", "d-")):
        ratio = _sweep_ratios(rows, n)
        if ratio:
            ax3.loglog(list(ratio), list(ratio.values()), style, label=f"zigzag, {n} crossings")
    ax3.axhline(50, color="k", ls="--", lw=0.8, label="issue 4 target (50 x)")
    steps = sorted({int(r["setting"].split("=")[1]) for r in rows if r["method"].startswith("sweep, direct")})
    ax3.set_xticks(steps, [str(k) for k in steps])
    ax3.minorticks_off()
    ax3.set_xlabel("finest grid step (cells along the longer side)")
    ax3.set_ylabel("networkx pipeline time / this pipeline's time")
    ax3.set_title("straightforward networkx pipeline against this one")
    ax3.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(HERE, "benchmark.png"), dpi=120)


def _sweep_ratios(rows, n: int) -> dict[int, float]:
    """networkx pipeline time over this pipeline's, per finest step, on the ``n``-crossing zigzag."""
    def times(method):
        return {int(r["setting"].split("=")[1]): r["seconds"] for r in rows if r["method"] == method}

    ours, nx = times(f"sweep, direct, {n} crossings"), times(f"sweep, networkx, {n} crossings")
    return {res: nx[res] / ours[res] for res in sorted(ours) if res in nx}


def _summary(rows, cal):
    def pick(method, setting):
        return next(r for r in rows if r["method"] == method and r["setting"] == setting)

    lines = ["# Benchmark summary", "",
             "Generated by `python validation/benchmark.py`; times are wall times in one run.",
             f"Calibration workload: {cal:.4f} s (compare runs through it).", ""]
    lines += ["| method | setting | relative error | seconds | seconds / calibration |", "|---|---|---|---|---|"]
    for r in rows[1:]:
        err = f"{r['rel_error']:.1e}" if r["rel_error"] != "" else ""
        lines.append(f"| {r['method']} | {r['setting']} | {err} | {r['seconds']:.4f} | {r['seconds'] / cal:.2f} |")
    nx96, sc96 = pick("networkx", "N=96"), pick("dijkstra-16", "N=96")
    lines += ["", f"- networkx pipeline / scipy pipeline at equal resolution (N=96, grid only, 60-degree crossing): "
              f"{nx96['seconds'] / sc96['seconds']:.1f} x slower."]
    e8 = pick("enumeration (34)", "n+=n-=8")["seconds"] / pick("assignment (34)", "n+=n-=8")["seconds"]
    lines += [f"- enumeration of (34) / assignment at 8 + 8 points: {e8:.0f} x slower."]
    zz = [r for r in rows if r["method"] == "direct, zigzag"]
    n = np.array([int(r["setting"].split("=")[1]) for r in zz])
    t = np.array([r["seconds"] for r in zz])
    slope = np.polyfit(np.log(n), np.log(t), 1)[0]
    lines += [f"- pipeline time against the number of crossings (zigzag, 10 to 100): exponent {slope:.2f}."]
    tt = [r for r in rows if r["method"] == "direct, zigzag tol"]
    inv = np.array([1 / float(r["setting"].split("=")[1]) for r in tt])
    t = np.array([r["seconds"] for r in tt])
    slope_tol = np.polyfit(np.log(inv), np.log(t), 1)[0]
    lines += [f"- pipeline time against 1/tol (10-crossing zigzag, tol 1e-2 to 1e-6): exponent {slope_tol:.2f}."]
    z10 = pick("direct, zigzag", "crossings=10")["seconds"]
    z100 = pick("direct, zigzag", "crossings=100")["seconds"]
    lines += [f"- 10 crossings at tol 1e-3: {z10:.3f} s (target 0.2 s); 100 crossings: {z100:.2f} s (target 5 s)."]
    for n in (3, 10, 30, 100):
        key = f"crossings={n}"
        ours = pick("pipeline, scipy", key)["seconds"]
        t = {m: pick(m, key)["seconds"] for m in ("grid stage, networkx", "grid stage, scipy", "pipeline, networkx",
                                                  "uniform grid stage, networkx", "uniform grid stage, scipy",
                                                  "pipeline, scipy, uniform grid")}
        lines += [f"- zigzag with {n} crossings, finest step 128 cells: the straightforward networkx pipeline "
                  f"(uniform grid, full searches, no refinement) takes "
                  f"{t['uniform grid stage, networkx'] / ours:.1f} x "
                  f"the time of this whole pipeline (locally refined grid, bounded searches, refinement); on the same "
                  f"locally refined graph {t['grid stage, networkx'] / ours:.1f} x; grid stage against grid stage "
                  f"{t['uniform grid stage, networkx'] / t['grid stage, scipy']:.1f} x (uniform networkx against "
                  f"locally refined scipy) and {t['grid stage, networkx'] / t['grid stage, scipy']:.1f} x (same "
                  f"graph); networkx grid stage with this refinement {t['pipeline, networkx'] / ours:.1f} x; the "
                  f"local refinement makes the pipeline {t['pipeline, scipy, uniform grid'] / ours:.2f} x faster "
                  f"and the scipy grid stage {t['uniform grid stage, scipy'] / t['grid stage, scipy']:.2f} x."]
    for n in SWEEP_CROSSINGS:
        ratio = _sweep_ratios(rows, n)
        nx_err = [r["rel_error"] for r in rows if r["method"] == f"sweep, networkx, {n} crossings"]
        lines += [f"- the same ratio against the finest step, zigzag with {n} crossings: "
                  + ", ".join(f"{v:.1f} x at {k} cells" for k, v in ratio.items())
                  + f" (networkx values {min(nx_err):.1e} to {max(nx_err):.1e} relative from this pipeline's)."]
    with open(os.path.join(HERE, "benchmark.md"), "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
