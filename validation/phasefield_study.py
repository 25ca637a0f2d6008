r"""Validation of the phase-field solver (:mod:`phasefield`) against the oracle :func:`direct.penalty`.

Issue 5, item 2: the phase-field value ``J_eps / beta`` and its curves
``gamma_eps`` against the direct method's ``J`` (tol ``1e-6``) and geodesics,
as functions of ``eps`` and of the grid step ``h``, on the paper's scenes and
on two generated families; observed rates by least squares.

What is measured
----------------
* ``cross`` (``J = 1/12`` exactly) on an ``(eps, n)`` grid: the error
  ``J_eps/beta - J`` is fitted by the vortex model

  .. math::  e(\varepsilon, h) = \varepsilon \big(A \log(1/h) + B \log(1/\varepsilon) + C\big)

  on the runs with ``n <= 128`` and checked on the held-out ``n = 256`` runs
  (and on ``eps = 0.025``).  ``A`` is compared with its predicted value
  ``N 2 pi / beta`` (``N`` signed crossing points over ``M x M``: the Dirichlet
  energy ``2 pi eps log(1/h)`` of one vortex of ``w``).
* the paper's scenes and the generated families (seeded: random
  ``direct.scenes.cross``, random polylines, a circle with a segment or a
  second circle moved across it -- cylinder and torus pieces) at several ``(eps, n)``: relative error, log-log slope
  of the error in ``eps``, and the Hausdorff distances between the recovered
  curves and the direct method's ``pairs[k].path`` in ``(x1, x2)`` (periodic
  on circles), both ways.
* a *vortex-corrected* estimator, clearly separate from the phase-field value:
  ``J_eps/beta - eps N (A1 log(1/h) + B1 log(1/eps) + C1)`` with the per-point
  coefficients fitted on ``cross`` only, then applied unchanged to every other
  scene (held out).

Usage::

    python validation/phasefield_study.py [--quick]

writes ``validation/phasefield_*.csv`` and ``validation/phasefield_*.png`` and
prints the markdown section returned by :func:`report` (full: about 2 minutes
on the 2-core test machine, ``--quick``: about 25 s).  Besides ``J_eps / beta``
it reports the exact metric length of the recovered curves
(``PhaseFieldResult.curve_value``), a second estimator.
"""

from __future__ import annotations

import argparse
import csv
import os
import sys
import time

import numpy as np
from scipy.spatial import cKDTree

import direct

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import phasefield as pf  # noqa: E402

__all__ = ["report", "hausdorff", "run_case", "fit_vortex_model"]

PER_POINT = 2 * np.pi / pf.BETA  # predicted log(1/h) coefficient of one vortex, in units of J


# ----------------------------------------------------------------------------- curves against geodesics


def _densify(path, step):
    path = np.asarray(path, dtype=float)
    if len(path) < 2:
        return path
    seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
    k = np.maximum(np.ceil(seg / step).astype(int), 1)
    out = [path[:1]]
    for a, b, m in zip(path[:-1], path[1:], k):
        t = (np.arange(1, m + 1) / m)[:, None]
        out.append(a + t * (b - a))
    return np.vstack(out)


def hausdorff(curves_a, curves_b, lengths, periodic, step):
    """Hausdorff distances between two families of polylines in ``(x1, x2)``.

    Parameters
    ----------
    curves_a, curves_b : list of (k, 2) ndarray
    lengths : (2,) floats
        Parameter lengths; an axis flagged periodic is read modulo its length.
    periodic : (2,) bools
    step : float
        Densification step of the polylines.

    Returns
    -------
    (sym, a_to_b, b_to_a) : floats
        Symmetric distance and the two one-sided ones (``max over a of dist to b``).
        ``nan`` when exactly one family is empty, 0 when both are.
    """
    A = [_densify(c, step) for c in curves_a if len(c)]
    B = [_densify(c, step) for c in curves_b if len(c)]
    if not A and not B:
        return 0.0, 0.0, 0.0
    if not A or not B:
        return float("nan"), float("nan"), float("nan")
    A, B = np.vstack(A), np.vstack(B)
    box = np.array([lengths[k] if periodic[k] else 1e6 for k in (0, 1)])
    shift = np.array([0.0 if periodic[k] else 1e5 for k in (0, 1)])

    def prep(P):
        P = P + shift
        for k in (0, 1):
            if periodic[k]:
                P[:, k] = np.mod(P[:, k], lengths[k])
        return np.minimum(P, box * (1 - 1e-15))

    A, B = prep(A), prep(B)
    ab = cKDTree(B, boxsize=box).query(A)[0].max()
    ba = cKDTree(A, boxsize=box).query(B)[0].max()
    return float(max(ab, ba)), float(ab), float(ba)


def _direct_paths(ref, dom):
    """The direct method's curves that lie in the piece ``dom`` (pieces ``i <= j`` only)."""
    names = tuple(c.name for c in dom.comps)
    out = []
    for p in ref.pairs:
        if tuple(p.components) != names:
            continue
        if dom.kind == "triangle" and np.mean(p.path[:, 1] - p.path[:, 0]) <= 0:
            continue
        out.append(np.asarray(p.path))
    return out


def curve_distances(res, ref):
    """Worst Hausdorff distances over the pieces: (sym, direct_to_pf, pf_to_direct)."""
    worst = np.zeros(3)
    for f in res.fields:
        mine = [c for c, k in zip(res.curves, res.curve_domains) if res.fields[k] is f]
        theirs = _direct_paths(ref, f.domain)
        d = hausdorff(theirs, mine, f.domain.lengths, f.periodic, float(min(f.h)) / 4)
        worst = np.fmax(worst, d) if np.all(np.isfinite(d)) else np.array([np.nan] * 3)
        if np.isnan(worst[0]):
            break
    return tuple(float(x) for x in worst)


# ----------------------------------------------------------------------------- runs


def n_points(ref):
    """Signed crossing points over all of ``M x M`` (two per geometric crossing)."""
    return 2 * len(ref.crossings)


def run_case(group, name, scene, metric, eps, n, ref):
    """One phase-field run compared with the oracle ``ref``; a CSV row (dict)."""
    res = pf.solve(scene, metric, eps=eps, n=n)
    _LAST[(name, metric)] = res
    h = float(np.mean([np.sqrt(f.h[0] * f.h[1]) for f in res.fields]))
    sym, d2p, p2d = curve_distances(res, ref)
    J = ref.value
    return dict(group=group, scene=name, metric=metric, eps=eps, n=n, h=h, nodes=res.n_nodes,
                points=n_points(ref), resolution=resolution(res, ref), direct=J, value=res.value,
                abs_err=res.value - J, rel_err=(res.value - J) / J if J else float("nan"),
                curve_value=res.curve_value,
                curve_rel_err=(res.curve_value - J) / J if J else float("nan"),
                hausdorff=sym, hd_direct_to_pf=d2p, hd_pf_to_direct=p2d, n_curves=len(res.curves),
                n_direct_curves=len(ref.pairs), seconds=res.seconds, iterations=res.iterations,
                escapes=res.escapes, direct_seconds=ref.seconds)


_LAST: dict = {}  # the last phase-field result of each (scene, metric), for the figures


def resolution(res, ref):
    """Interface width over grid step along the direct method's curves (smallest over the curves).

    A 1-D transition of ``w`` has width about ``eps / rho`` in units of the
    metric ``B``, i.e. ``eps / (rho |phi'|)`` in parameters.  Below about one
    grid cell the discrete interface is pinned between nodes and costs
    ``eps (2 pi)^2 / h`` per unit length whatever ``rho``, so the phase-field
    value falls *below* ``beta J`` there.  ``inf`` without curves.
    """
    out = np.inf
    for f in res.fields:
        ci, cj = f.domain.comps
        for path in _direct_paths(ref, f.domain):
            x1, x2 = path[:, 0], path[:, 1]
            r = ci.phi(x1) - cj.phi(x2)
            if res.metric == "G":
                rho = (r * r).sum(1)
                sp_ = np.maximum(np.linalg.norm(ci.velocities[ci.segment_index(np.mod(x1, ci.length))], axis=1),
                                 np.linalg.norm(cj.velocities[cj.segment_index(np.mod(x2, cj.length))], axis=1))
            else:
                rho = (r * r).sum(1) ** 2
                sp_ = np.ones(len(path))
            m = float((rho * sp_).max())
            if m > 0:
                out = min(out, res.eps / (m * max(f.h)))
    return float(out)


def fit_vortex_model(rows):
    """Least-squares fit of ``err / (eps N) = A1 log(1/h) + B1 log(1/eps) + C1`` (per signed point).

    Returns
    -------
    (3,) ndarray
        ``(A1, B1, C1)``.
    """
    X = np.array([[np.log(1 / r["h"]), np.log(1 / r["eps"]), 1.0] for r in rows])
    y = np.array([r["abs_err"] / (r["eps"] * r["points"]) for r in rows])
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    return coef


def _model(coef, r):
    return r["eps"] * r["points"] * (coef[0] * np.log(1 / r["h"]) + coef[1] * np.log(1 / r["eps"]) + coef[2])


def _plot_wrapped(ax, c, f, *args, **kw):
    """Plot a polyline of a piece, reading circle parameters modulo their length (broken at the seams)."""
    c = np.array(c, dtype=float)
    L = np.array(f.domain.lengths, dtype=float)
    brk = np.zeros(len(c), dtype=bool)
    for a in (0, 1):
        if f.periodic[a]:
            c[:, a] = np.mod(c[:, a], L[a])
            brk[1:] |= np.abs(np.diff(c[:, a])) > L[a] / 2
    for piece in np.split(c, np.flatnonzero(brk)):
        ax.plot(piece[:, 0], piece[:, 1], *args, **kw)


def _slope(x, y):
    x, y = np.asarray(x, float), np.asarray(y, float)
    ok = np.isfinite(x) & np.isfinite(y) & (x > 0) & (y > 0)
    if ok.sum() < 2:
        return float("nan")
    return float(np.polyfit(np.log(x[ok]), np.log(y[ok]), 1)[0])


def _random_crosses(k, seed):
    rng = np.random.default_rng(seed)
    out = []
    for i in range(k):
        a, b, c, d = rng.uniform(0.3, 1.0, 4)
        ang = rng.uniform(np.pi / 6, 5 * np.pi / 6)
        sc = direct.scenes.cross(a, b, c, d, ang)
        out.append((f"rcross{i}", direct.Scene(sc.components, name=f"rcross{i}")))
    return out


def _random_polylines(k, seed):
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < k:
        comps = []
        for c in range(2):
            steps = rng.uniform(0.3, 1.0, size=3)
            x = np.concatenate([[0.0], np.cumsum(steps)])
            ref = np.column_stack([x, np.full(4, 2.0 * c)])
            dfm = rng.normal(scale=0.8, size=(4, 2))
            comps.append(direct.Component(ref, dfm, name=f"P{c}"))
        try:
            sc = direct.Scene(tuple(comps), name=f"rpoly{len(out)}")
        except direct.DirectError:
            continue
        if 1 <= len(direct.find_crossings(sc)) <= 3:
            out.append((sc.name, sc))
    return out


def _random_circles(k, seed):
    """Seeded scenes with circles: a unit circle and a segment moved across it (cylinder piece), or two circles
    moved onto each other (torus piece), with 1 to 4 crossings."""
    rng = np.random.default_rng(seed)
    t = 2 * np.pi * np.arange(64) / 64
    unit = np.column_stack([np.cos(t), np.sin(t)])
    circ = direct.Component(unit, unit, closed=True, name="C")
    out = []
    while len(out) < k:
        kind = "cyl" if len(out) % 2 == 0 else "tor"
        if kind == "cyl":
            a = rng.uniform(-0.8, 0.8, 2) + [0.0, -1.6]
            b = rng.uniform(-0.8, 0.8, 2) + [0.0, 1.6]
            other = direct.Component([[3, -1], [3, 1]], [a, b], name="S")
        else:
            c = rng.uniform(-0.6, 0.6, 2) + [1.2 * rng.choice([-1, 1]), 0.0]
            other = direct.Component(unit + [3, 0], rng.uniform(0.6, 1.2) * unit + c, closed=True, name="D")
        try:
            sc = direct.Scene((circ, other), name=f"r{kind}{len(out)}")
        except direct.DirectError:
            continue
        if 1 <= len(direct.find_crossings(sc)) <= 4:
            out.append((sc.name, sc))
    return out


# ----------------------------------------------------------------------------- report


def _write_csv(path, rows):
    if not rows:
        return
    keys = list(rows[0])
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})


def _fmt(x, spec=".3g"):
    return "nan" if x is None or not np.isfinite(x) else format(x, spec)


def report(outdir, quick: bool = False) -> str:
    """Run the study, write ``phasefield_*.csv`` / ``phasefield_*.png`` into ``outdir``, return markdown.

    Parameters
    ----------
    outdir : str or path-like
    quick : bool
        A reduced set of scenes and ``(eps, n)`` (about a minute instead of several).

    Returns
    -------
    str
        A markdown section (tables, image links relative to ``outdir``, the measured rate claims).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(outdir, exist_ok=True)
    t_start = time.perf_counter()
    refs = {}

    def ref_of(name, scene, metric):
        key = (name, metric)
        if key not in refs:
            refs[key] = direct.penalty(scene, metric, tol=1e-6)
        return refs[key]

    rows = []
    # 1. cross on an (eps, n) grid: the error model
    if quick:
        grid_eps, grid_n = [0.2, 0.1, 0.05], [32, 64, 128]
    else:
        grid_eps, grid_n = [0.2, 0.1, 0.05, 0.025], [32, 64, 128, 256]
    cross = direct.scenes.get("cross")
    for e in grid_eps:
        for n in grid_n:
            rows.append(run_case("cross-grid", "cross", cross, "G", e, n, ref_of("cross", cross, "G")))
    train = [r for r in rows if r["n"] <= 128 and r["eps"] >= 0.05]
    test = [r for r in rows if r not in train]
    if not test:  # quick: hold out the finest grid
        train = [r for r in rows if r["n"] < max(grid_n)]
        test = [r for r in rows if r["n"] == max(grid_n)]
    coef = fit_vortex_model(train)
    for r in rows:
        r["model"] = _model(coef, r)
        r["corrected"] = r["value"] - r["model"]
    # 2. paper scenes and generated families
    if quick:
        paper = [("fig2", "G", [0.2, 0.1], [64]), ("loop", "G", [0.2, 0.1], [64]),
                 ("fig10", "G", [0.2, 0.1], [64])]
        fams = _random_crosses(3, 1) + _random_polylines(2, 7) + _random_circles(2, 3)
        fam_eps, fam_n = [0.1, 0.05], [64]
    else:
        paper = [("cross", "g", [0.2, 0.1, 0.05], [64, 128]),
                 ("cross60", "G", [0.2, 0.1, 0.05], [64, 128]),
                 ("fig2", "G", [0.2, 0.1, 0.05], [64, 128]),
                 ("waves", "G", [0.2, 0.1, 0.05], [64, 128]),
                 ("loop", "G", [0.2, 0.1, 0.05], [64, 128]),
                 ("ring", "G", [0.2, 0.1], [64]),
                 ("reversed", "G", [0.2, 0.1, 0.05], [64, 128]),
                 ("fig10", "G", [0.2, 0.1, 0.05], [64, 128]),
                 ("nested", "G", [0.2, 0.1], [64])]
        fams = _random_crosses(6, 1) + _random_polylines(4, 7) + _random_circles(4, 3)
        fam_eps, fam_n = [0.2, 0.1, 0.05], [64]
    for name, metric, es, ns in paper:
        sc = direct.scenes.get(name)
        for e in es:
            for n in ns:
                rows.append(run_case("paper", name, sc, metric, e, n, ref_of(name, sc, metric)))
    for name, sc in fams:
        for e in fam_eps:
            for n in fam_n:
                grp = ("family-cross" if name.startswith("rcross") else
                       "family-poly" if name.startswith("rpoly") else "family-circles")
                rows.append(run_case(grp, name, sc, "G", e, n, ref_of(name, sc, "G")))
    for r in rows:
        if "model" not in r:
            r["model"] = _model(coef, r) if r["metric"] == "G" else float("nan")
            r["corrected"] = r["value"] - r["model"]
        r["corr_rel_err"] = (r["corrected"] - r["direct"]) / r["direct"] if r["direct"] else float("nan")
    _write_csv(os.path.join(outdir, "phasefield_runs.csv"), rows)

    # held-out check of the model on cross
    held = [(r["eps"], r["n"], r["abs_err"], r["model"]) for r in test]
    fit_rows = [dict(coefficient=k, value=float(v)) for k, v in zip(("A1", "B1", "C1"), coef)]
    fit_rows.append(dict(coefficient="A1_predicted_2pi_over_beta", value=PER_POINT))
    for e, n, err, mod in held:
        fit_rows.append(dict(coefficient=f"heldout eps={e} n={n} err/model", value=err / mod))
    _write_csv(os.path.join(outdir, "phasefield_fit.csv"), fit_rows)

    # per-scene slopes in eps at the finest n
    slopes = []
    for (grp, name, metric) in sorted({(r["group"], r["scene"], r["metric"]) for r in rows}):
        rs = [r for r in rows if r["scene"] == name and r["metric"] == metric and r["group"] == grp]
        nmax = max(r["n"] for r in rs)
        fin = sorted([r for r in rs if r["n"] == nmax], key=lambda r: r["eps"])
        slopes.append(dict(group=grp, scene=name, metric=metric, n=nmax, direct=fin[0]["direct"],
                           eps_min=fin[0]["eps"], value=fin[0]["value"], rel_err=fin[0]["rel_err"],
                           corr_rel_err=fin[0]["corr_rel_err"],
                           slope_err_eps=_slope([r["eps"] for r in fin], [abs(r["abs_err"]) for r in fin]),
                           slope_corr_eps=_slope([r["eps"] for r in fin],
                                                 [abs(r["corrected"] - r["direct"]) for r in fin]),
                           curve_value=fin[0]["curve_value"], curve_rel_err=fin[0]["curve_rel_err"],
                           slope_curve_eps=_slope([r["eps"] for r in fin], [abs(r["curve_value"] - r["direct"])
                                                                             for r in fin]),
                           resolution=fin[0]["resolution"],
                           model_ratio=(float(np.median([r["abs_err"] / r["model"] for r in rs]))
                                        if metric == "G" and rs[0]["points"] else float("nan")),
                           hausdorff=fin[0]["hausdorff"], hd_direct_to_pf=fin[0]["hd_direct_to_pf"],
                           slope_hd_eps=_slope([r["eps"] for r in fin], [r["hd_direct_to_pf"] for r in fin]),
                           seconds=fin[0]["seconds"], direct_seconds=fin[0]["direct_seconds"]))
    _write_csv(os.path.join(outdir, "phasefield_rates.csv"), slopes)

    # figures
    cg = [r for r in rows if r["group"] == "cross-grid"]
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.3))
    for n in grid_n:
        rs = sorted([r for r in cg if r["n"] == n], key=lambda r: r["eps"])
        (line,) = ax[0].loglog([r["eps"] for r in rs], [r["abs_err"] for r in rs], "o-", label=f"n={n}")
        ax[0].loglog([r["eps"] for r in rs], [r["model"] for r in rs], "--", color=line.get_color(), alpha=0.6)
    ax[0].set_xlabel("eps")
    ax[0].set_ylabel("J_eps/beta - J")
    ax[0].set_title("cross: error (solid) and fitted vortex model (dashed)")
    ax[0].legend(fontsize=8)
    for e in grid_eps:
        rs = sorted([r for r in cg if r["eps"] == e], key=lambda r: r["h"])
        ax[1].semilogx([r["h"] for r in rs], [r["abs_err"] / e for r in rs], "o-", label=f"eps={e}")
    ax[1].set_xlabel("h")
    ax[1].set_ylabel("(J_eps/beta - J) / eps")
    ax[1].set_title("cross: error / eps grows like log(1/h)")
    ax[1].legend(fontsize=8)
    others = [r for r in rows if r["group"] != "cross-grid" and r["direct"] > 0]
    for grp, mk in (("paper", "o"), ("family-cross", "s"), ("family-poly", "^"), ("family-circles", "D")):
        rs = [r for r in others if r["group"] == grp]
        ax[2].loglog([r["eps"] * (1 + 0.03 * (r["n"] > 64)) for r in rs], [abs(r["rel_err"]) for r in rs], mk,
                     alpha=0.6, label=f"{grp}: J_eps/beta")
        ax[2].loglog([r["eps"] * (1 + 0.03 * (r["n"] > 64)) for r in rs], [abs(r["curve_rel_err"]) for r in rs], mk,
                     mfc="none", alpha=0.6, label=f"{grp}: length of gamma_eps")
    ax[2].set_xlabel("eps")
    ax[2].set_ylabel("|relative error|")
    ax[2].set_title("all scenes; filled: J_eps/beta, open: length(gamma_eps)", fontsize=10)
    ax[2].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(outdir, "phasefield_convergence.png"), dpi=110)
    plt.close(fig)

    # curves: phase field against geodesics at the finest setting of a few scenes
    show = [s for s in ("cross", "fig2", "waves", "loop", "fig10", "reversed", "nested")
            if any(r["scene"] == s for r in rows)]
    fig, axes = plt.subplots(1, len(show), figsize=(3.6 * len(show), 3.6))
    axes = np.atleast_1d(axes)
    for axx, s in zip(axes, show):
        sc = direct.scenes.get(s)
        res = _LAST[(s, "G")]
        best = dict(eps=res.eps, n=res.n)
        ref = ref_of(s, sc, "G")
        f0 = res.fields[0]
        L1, L2 = f0.domain.lengths
        for c, k in zip(res.curves, res.curve_domains):
            if k == 0:
                _plot_wrapped(axx, c, f0, "r-", lw=1.5)
        for path in _direct_paths(ref, f0.domain):
            _plot_wrapped(axx, path, f0, "k--", lw=1)
        if len(f0.domain.points):
            axx.plot(f0.domain.points[:, 0], f0.domain.points[:, 1], "bo", ms=4)
        axx.set_xlim(0, L1)
        axx.set_ylim(0, L2)
        axx.set_title(f"{s}: eps={best['eps']}, n={best['n']}", fontsize=9)
        axx.set_xlabel("x1")
        axx.set_ylabel("x2")
        axx.set_aspect("equal")
    fig.suptitle("gamma_eps (red, w = pi) against the direct geodesics (black dashed) on the first piece "
                 "of M x M; circles read modulo their length; blue: crossing points")
    fig.tight_layout()
    fig.savefig(os.path.join(outdir, "phasefield_curves.png"), dpi=100)
    plt.close(fig)

    # cost per grid size
    cost = []
    for n in ([32, 64, 128] if quick else [32, 64, 128, 256]):
        res = pf.solve(cross, "G", eps=0.1, n=n, curves=False)
        cost.append(dict(n=n, nodes=res.n_nodes, seconds=res.seconds, iterations=res.iterations,
                         seconds_per_iteration=res.seconds / max(res.iterations, 1)))
    _write_csv(os.path.join(outdir, "phasefield_cost.csv"), cost)
    cost_slope = _slope([c["nodes"] for c in cost], [c["seconds"] for c in cost])

    # ------------------------------------------------------------------ markdown
    total = time.perf_counter() - t_start
    heldout_ratio = [err / mod for _, _, err, mod in held]
    cg_fin = [r for r in cg if r["n"] == max(grid_n)]
    slope_cross = _slope([r["eps"] for r in cg_fin], [r["abs_err"] for r in cg_fin])
    # along h proportional to eps (n * eps fixed)
    diag = sorted([r for r in cg if abs(r["n"] * r["eps"] - 6.4) < 1e-9], key=lambda r: r["eps"])
    slope_diag = _slope([r["eps"] for r in diag], [r["abs_err"] for r in diag])
    fam = [s for s in slopes if s["group"].startswith("family")]
    pap = [s for s in slopes if s["group"] == "paper"]
    L = []
    L.append("## Phase-field method (section 5.1.2) against the oracle\n")
    L.append(f"Generated by `python validation/phasefield_study.py{' --quick' if quick else ''}` "
             f"in {total:.0f} s (solver: `validation/phasefield.py`; oracle: `direct.penalty(..., tol=1e-6)`). "
             "`value` is `J_eps / beta` with `R(t) = 1 - cos t`, `beta = 8 sqrt 2`, over all of `M x M`.\n")
    L.append("### Error model, fitted on `cross` (J = 1/12)\n")
    L.append("Near each signed crossing point the well weight `rho^2` vanishes while `Phi_phi ~ 1/|x - x_c|`, "
             "so `w = u - (theta_phi - theta_j)` carries a vortex whose Dirichlet energy `2 pi eps log(r_core/h)` "
             "is not part of `J` (it is infinite in the continuum).  Fit of "
             "`err = eps N (A1 log(1/h) + B1 log(1/eps) + C1)` (`N` = signed crossing points over `M x M`) "
             f"on {len(train)} runs:\n")
    L.append("| A1 (fitted) | A1 predicted `2 pi / beta` | B1 | C1 |")
    L.append("|---|---|---|---|")
    L.append(f"| {coef[0]:.4f} | {PER_POINT:.4f} | {coef[1]:.4f} | {coef[2]:.4f} |\n")
    L.append("Held-out runs (not used in the fit):\n")
    L.append("| eps | n | J_eps/beta - J | model | ratio |")
    L.append("|---|---|---|---|---|")
    for e, n, err, mod in held:
        L.append(f"| {e} | {n} | {err:.4g} | {mod:.4g} | {err / mod:.3f} |")
    L.append("")
    L.append("| cross: eps | " + " | ".join(f"n={n}" for n in grid_n) + " |")
    L.append("|---|" + "---|" * len(grid_n))
    for e in grid_eps:
        vals = [next(r for r in cg if r["eps"] == e and r["n"] == n) for n in grid_n]
        L.append(f"| {e} | " + " | ".join(f"{r['value']:.4f} ({r['seconds']:.1f} s)" for r in vals) + " |")
    L.append(f"\n(direct: J = {cg[0]['direct']:.6f}; entries `J_eps/beta (wall time)`.)\n")
    L.append("![phase-field convergence](phasefield_convergence.png)\n")
    L.append("### Paper scenes and generated families\n")
    L.append("Finest setting of each scene (smallest eps, largest n); `slope` = log-log slope of "
             "|error| against eps at that n; Hausdorff distances in `(x1, x2)` parameters between the level set "
             "`w = pi` and the direct method's curves (`direct->pf`: how far a geodesic is from the phase-field "
             "curves; `sym`: both ways, counts spurious level-set pieces).\n")
    L.append("| group | scene | metric | J (direct) | eps | n | eps/(rho h) | J_eps/beta | rel. err | slope "
             "| excess / model | length of gamma_eps | rel. err | slope | Hausdorff sym | direct->pf | pf s "
             "| direct s |")
    L.append("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for s in slopes:
        if s["group"] == "cross-grid":
            continue
        L.append(f"| {s['group']} | {s['scene']} | {s['metric']} | {s['direct']:.4g} | {s['eps_min']} | {s['n']} | "
                 f"{_fmt(s['resolution'], '.2g')} | "
                 f"{s['value']:.4g} | {_fmt(s['rel_err'], '+.2e')} | {_fmt(s['slope_err_eps'], '.2f')} | "
                 f"{_fmt(s['model_ratio'], '.2f')} | "
                 f"{_fmt(s['curve_value'], '.4g')} | {_fmt(s['curve_rel_err'], '+.2e')} | "
                 f"{_fmt(s['slope_curve_eps'], '.2f')} | {_fmt(s['hausdorff'])} | {_fmt(s['hd_direct_to_pf'])} | "
                 f"{s['seconds']:.1f} | {s['direct_seconds']:.2f} |")
    L.append("\n`excess / model`: median over the scene's runs of `(J_eps/beta - J)` over the vortex model fitted "
             "on `cross` (held out: 1 would mean the cross-fitted constants transfer).  "
             "`eps/(rho h)`: interface width over grid step at the largest well weight (below ~1 the discrete "
             "interface is pinned between nodes and costs `eps (2 pi)^2 / h` per unit length instead of "
             "`beta rho`, so `J_eps/beta` falls *below* J).  The vortex-corrected values are in "
             "`phasefield_runs.csv` (`corrected`).  `cross` is symmetric: its four shortest curves tie, so its "
             "Hausdorff distance measures which one was picked, not an error.\n")
    L.append("\n![curves](phasefield_curves.png)\n")
    L.append("### Cost\n")
    L.append("| n (cross, eps 0.1) | nodes | seconds | Newton iterations | s / iteration |")
    L.append("|---|---|---|---|---|")
    for c in cost:
        L.append(f"| {c['n']} | {c['nodes']} | {c['seconds']:.2f} | {c['iterations']} | "
                 f"{c['seconds_per_iteration']:.3f} |")
    L.append(f"\nTime grows like nodes^{cost_slope:.2f} (sparse direct solves, one or two per Newton iteration).\n")
    L.append("### Rates (measured)\n")
    med = lambda xs: float(np.nanmedian(xs)) if len(xs) else float("nan")  # noqa: E731
    L.append(f"* `J_eps/beta - J = eps N (A1 log(1/h) + B1 log(1/eps) + C1)`: fitted A1 = {coef[0]:.3f} against "
             f"the predicted vortex value 2 pi / beta = {PER_POINT:.3f}; held-out error/model ratios "
             f"{min(heldout_ratio):.2f} .. {max(heldout_ratio):.2f}.")
    L.append(f"* So the phase-field value converges like **O(eps log(1/h))**, first order in eps only when "
             f"h is tied to eps: log-log slope in eps at n = {max(grid_n)} on `cross`: {slope_cross:.2f}; "
             f"along h proportional to eps (n eps = 6.4): {slope_diag:.2f}.  At fixed eps the error *grows* "
             "as the grid is refined (the vortex energy), so refining h alone does not converge.")
    L.append(f"* Relative errors of `J_eps/beta` at the finest setting are large (median |rel. err| over paper "
             f"scenes {med([abs(s['rel_err']) for s in pap if np.isfinite(s['rel_err'])]):.2f}, "
             f"families {med([abs(s['rel_err']) for s in fam]):.2f}): "
             "the excess is the vortex energy, about (2 pi/beta) eps log(1/h) per signed crossing point, "
             "large against small J; scenes without crossing points (reversed) or under-resolved ones "
             "(`eps/(rho h)` < 1) are off the other way.")
    loop_note = ""
    if ("loop", "G") in _LAST:
        lp = _LAST[("loop", "G")]
        loop_note = (f"; loop: the phase-field curve has length {lp.curve_value / 2:.4f} against the oracle's "
                     f"{refs[('loop', 'G')].value / 2:.4f}, on another side of the triangle")
    ratios = [s["model_ratio"] for s in slopes if np.isfinite(s["model_ratio"]) and s["group"] != "cross-grid"]
    eslopes = [s["slope_err_eps"] for s in slopes if s["group"] != "cross-grid" and np.isfinite(s["model_ratio"])]
    if ratios:
        L.append(f"* On the other scenes with crossing points the excess has the same form: log-log slope in eps "
                 f"{min(eslopes):.2f} .. {max(eslopes):.2f} (median {med(eslopes):.2f}); the cross-fitted model "
                 f"predicts it within a factor {min(ratios):.2f} .. {max(ratios):.2f} (median {med(ratios):.2f}): "
                 "the log(1/h) coefficient is universal, the O(eps) constant depends on the crossing geometry.")
    L.append(f"* Vortex-corrected estimator (coefficients from `cross` only, applied unchanged; `corrected` in "
             f"the CSV): median |rel. err| "
             f"{med([abs(s['corr_rel_err']) for s in pap if np.isfinite(s['corr_rel_err'])]):.2f} (paper), "
             f"{med([abs(s['corr_rel_err']) for s in fam]):.2f} (families): its residual is O(eps) with a "
             "geometry-dependent constant (crossing angle, speeds) that the model does not capture.")
    L.append(f"* Length of the recovered curves `gamma_eps` (exact metric length, a second estimator, "
             f"not `J_eps/beta`): median |rel. err| "
             f"{med([abs(s['curve_rel_err']) for s in pap if np.isfinite(s['curve_rel_err'])]):.3f} (paper), "
             f"{med([abs(s['curve_rel_err']) for s in fam]):.3f} (families) at the finest setting; "
             f"median log-log slope in eps {med([s['slope_curve_eps'] for s in slopes]):.2f}; "
             f"it is >= J on {sum(1 for s in slopes if s['curve_value'] >= s['direct'] * (1 - 1e-9))} of "
             f"{len(slopes)} scenes (an admissible family is never shorter than J).")
    L.append(f"* Curves: median Hausdorff distance direct->pf at the finest setting "
             f"{med([s['hd_direct_to_pf'] for s in slopes]):.3f} (parameter units); median log-log slope in eps "
             f"{med([s['slope_hd_eps'] for s in slopes]):.2f}: no convergence of the curves is claimed.  Large "
             "distances with a curve length close to J are ties or near-ties between geodesics (cross, cross60, "
             f"fig10, nested: symmetric scenes{loop_note}), where the Hausdorff distance is not an error measure.")
    L.append(f"* Failure modes seen {'in the full run (not all of these scenes are in --quick)' if quick else 'here'}: "
             "the symmetric saddle (kept by the continuation on symmetric data; left "
             "along negative curvature when it is clearly negative -- on `cross` with `g` only below eps ~ 0.03); "
             "interface pinning when `eps/(rho h)` < 1 (`reversed`: `J_eps/beta` below J); longer local "
             "minimizers (the families' largest `length of gamma_eps` errors).")
    return "\n".join(L) + "\n"


def main(argv=None):
    """Command line: run :func:`report` into ``validation/`` and print the markdown."""
    p = argparse.ArgumentParser(description="phase-field solver against direct (issue 5, item 2)")
    p.add_argument("--quick", action="store_true", help="reduced study (about a minute)")
    p.add_argument("--outdir", default=os.path.dirname(os.path.abspath(__file__)))
    a = p.parse_args(argv)
    print(report(a.outdir, quick=a.quick))


if __name__ == "__main__":
    main()
