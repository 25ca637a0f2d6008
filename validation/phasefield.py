r"""A phase-field solver for the penalty (section 5.1.2), the first client of the oracle.

Status: a prototype for issue 5, not the finished study.  It handles the
pieces of ``M x M`` made of intervals (rectangles ``I_i x I_j`` and triangles
``x1 < x2`` of ``I_i x I_i``) with the metrics ``G`` and ``g`` of
:mod:`direct.metric`; circles, the recovery of the curves gamma_eps, the
validation study and the report are still to be written.  First finding:
with the degenerate metrics the transition width of the phase, about
``eps / rho`` in parameter units, blows up near the crossing points where
``rho -> 0``, so ``J_eps / beta`` approaches ``J`` slowly (see the issue note).

The functional (section 5.1.2, Prop. 31).  With ``w = u - (theta_phi -
theta_j)`` (defined mod ``2 pi``) and the metric ``dl = rho ||dx||_B``
(``B = diag(|phi'(x1)|^2, |phi'(x2)|^2)`` for ``G``, ``B = Id`` for ``g``),
``A = rho^2 B`` and

.. math::

    L_\varepsilon(u) = \int \Big(\varepsilon\, (\Phi_\varphi - \nabla u)^T A^{-1}
        (\Phi_\varphi - \nabla u) + \varepsilon^{-1} R(w)\Big) \sqrt{\det A}\, dx
    = \int \Big(\varepsilon\, |\nabla w|^2_{B^{-1}} + \varepsilon^{-1} \rho^2 R(w)\Big)
        \sqrt{\det B}\, dx,

with the 2 pi-periodic well ``R(t) = 1 - cos t``.  A 1-D transition of ``w``
by ``2 pi`` across a curve costs ``beta rho ||.||`` per unit length with
``beta = int_0^{2 pi} 2 sqrt(R) = 8 sqrt 2``, so ``J_eps / beta -> J``.

Discretization: nodal values of ``u`` on a uniform grid; on each grid edge
(4 neighbours) the increment of ``u`` minus the exact increment of
``theta_phi - theta_j`` along the edge (the angle swept by the affine pieces
of ``r_phi`` and ``r_j``), squared, weighted by ``B^{-1} sqrt(det B)`` at the
edge midpoint; the well at the nodes weighted by ``rho^2 sqrt(det B)`` and the
cell area.  Minimized by a trust-region Newton-Krylov method (exact gradient and
Hessian-vector products: a weighted graph Laplacian plus a diagonal), with
continuation in ``eps`` from a large value (where the minimizer is smooth and no jump set is
imposed by the initialization ``u = 0``) down to the target.

Usage::

    python validation/phasefield.py cross --eps 0.05 --n 128
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

import direct
from direct.metric import get_metric
from direct.penalty import domains

BETA = 8 * np.sqrt(2)  # int_0^{2 pi} 2 sqrt(1 - cos t) dt


@dataclass
class PhaseFieldResult:
    """``value`` = J_eps / beta over all of M x M; per-domain fields for plots; work counters."""

    value: float
    eps: float
    n: int
    fields: list
    iterations: int
    seconds: float


def _angle(r):
    return np.arctan2(r[..., 1], r[..., 0])


def _sweep(comps, P, Q, jref: bool):
    """Exact angle swept by r (r_phi, or r_j if jref) along straight segments P -> Q of parameters."""
    ci, cj = comps
    f1 = ci.j if jref else ci.phi
    f2 = cj.j if jref else cj.phi
    # r is affine between vertex parameters: split at every vertex line crossed (a few at most per edge)
    ts = [np.zeros(len(P)), np.ones(len(P))]
    for axis, comp in enumerate(comps):
        vp = comp.params[1:-1]
        u0, u1 = P[:, axis], Q[:, axis]
        lo, hi = np.minimum(u0, u1), np.maximum(u0, u1)
        for v in vp:
            inside = (lo < v) & (v < hi)
            t = np.full(len(P), np.nan)
            t[inside] = (v - u0[inside]) / (u1[inside] - u0[inside])
            ts.append(t)
    T = np.sort(np.column_stack(ts), axis=1)  # NaNs go last
    total = np.zeros(len(P))
    prev = None
    for k in range(T.shape[1]):
        t = T[:, k]
        ok = np.isfinite(t)
        X = P + np.where(ok, t, 1.0)[:, None] * (Q - P)
        r = f1(X[:, 0]) - f2(X[:, 1])
        a = _angle(r)
        if prev is not None:
            d = np.mod(a - prev + np.pi, 2 * np.pi) - np.pi
            total += np.where(ok, d, 0.0)
        prev = np.where(ok, a, prev if prev is not None else a)
    return total


def _setup(dom, metric, n: int):
    L1, L2 = dom.lengths
    h = max(L1, L2) / n
    n1, n2 = max(int(round(L1 / h)), 2), max(int(round(L2 / h)), 2)
    x1 = np.linspace(0, L1, n1 + 1)
    x2 = np.linspace(0, L2, n2 + 1)
    h1, h2 = x1[1] - x1[0], x2[1] - x2[0]
    X1, X2 = np.meshgrid(x1, x2, indexing="ij")
    keep = np.ones_like(X1, dtype=bool)
    if dom.is_triangle:
        keep = X2 > X1 + 1e-12 * L1
    ci, cj = dom.comps
    idx = -np.ones(X1.shape, dtype=int)
    idx[keep] = np.arange(keep.sum())
    pts = np.column_stack([X1[keep], X2[keep]])
    r = ci.phi(pts[:, 0]) - cj.phi(pts[:, 1])
    rj = ci.j(pts[:, 0]) - cj.j(pts[:, 1])
    theta = _angle(r) - _angle(rj)
    a = ci.velocities[ci.segment_index(pts[:, 0])]
    b = cj.velocities[cj.segment_index(pts[:, 1])]
    if metric.name == "G":
        Bd = np.column_stack([(a * a).sum(1), (b * b).sum(1)])
    else:
        Bd = np.ones((len(pts), 2))
    rho = metric.weight((r * r).sum(1))
    # nodes near the crossing points of each cell get the right weight through rho: nothing special
    node_w = rho**2 * np.sqrt(Bd.prod(1)) * h1 * h2
    edges, ew, phi_e = [], [], []
    for axis, (di, dj), hh in ((0, (1, 0), h1), (1, (0, 1), h2)):
        A = idx[: idx.shape[0] - di, : idx.shape[1] - dj]
        B_ = idx[di:, dj:]
        ok = (A >= 0) & (B_ >= 0)
        ia, ib = A[ok], B_[ok]
        P, Q = pts[ia], pts[ib]
        mid = 0.5 * (P + Q)
        am = ci.velocities[ci.segment_index(mid[:, 0])]
        bm = cj.velocities[cj.segment_index(mid[:, 1])]
        if metric.name == "G":
            Bm = np.column_stack([(am * am).sum(1), (bm * bm).sum(1)])
        else:
            Bm = np.ones((len(mid), 2))
        w = np.sqrt(Bm.prod(1)) / Bm[:, axis] * h1 * h2 / hh**2
        sweep = _sweep(dom.comps, P, Q, False) - _sweep(dom.comps, P, Q, True)
        edges.append(np.column_stack([ia, ib]))
        ew.append(w)
        phi_e.append(sweep)
    return dict(pts=pts, theta=theta, node_w=node_w, edges=np.vstack(edges), ew=np.concatenate(ew),
                phi_e=np.concatenate(phi_e), shape=X1.shape, idx=idx)


def _laplacian(S):
    """The weighted graph Laplacian of the edge term (sparse): energy = eps (du - Phi)^T W (du - Phi)."""
    import scipy.sparse as sp

    i, j = S["edges"][:, 0], S["edges"][:, 1]
    n = len(S["pts"])
    W = sp.coo_matrix((S["ew"], (i, j)), shape=(n, n))
    W = (W + W.T).tocsr()
    return (sp.diags(np.asarray(W.sum(axis=1)).ravel()) - W).tocsr()


def _energy(u, S, eps):
    i, j = S["edges"][:, 0], S["edges"][:, 1]
    d = u[j] - u[i] - S["phi_e"]
    g_edges = eps * S["ew"] * d
    E = eps * np.dot(S["ew"], d * d) + np.dot(S["node_w"], 1 - np.cos(u - S["theta"])) / eps
    grad = np.zeros_like(u)
    np.add.at(grad, j, 2 * g_edges)
    np.add.at(grad, i, -2 * g_edges)
    grad += S["node_w"] * np.sin(u - S["theta"]) / eps
    return E, grad


def solve(scene, metric="G", eps: float = 0.05, n: int = 128, eps_start: float | None = None,
          steps: int = 6, maxiter: int = 3000) -> PhaseFieldResult:
    """J_eps / beta by the phase field on every piece of M x M (intervals only).

    Parameters
    ----------
    scene : direct.Scene or str
        The scene (built-in names accepted).
    metric : {"G", "g"}
    eps : float
        Target interface width (parameter units).
    n : int
        Grid cells along the longer side of each piece.
    eps_start : float, optional
        First value of the continuation (default: a quarter of the longest side).
    steps : int
        Geometric continuation steps from ``eps_start`` to ``eps``.
    """
    t0 = time.perf_counter()
    scene = direct.scenes.resolve(scene)
    met = get_metric(metric)
    if any(c.closed for c in scene.components):
        raise direct.NotSupportedError("the phase-field prototype handles intervals only")
    total, fields, its = 0.0, [], 0
    for dom in domains(scene, direct.find_crossings(scene)):
        S = _setup(dom, met, n)
        start = eps_start or max(dom.lengths) / 4
        u = np.zeros(len(S["pts"]))
        lap = _laplacian(S)
        for e in np.geomspace(start, eps, steps) if start > eps else [eps]:
            def hessp(x, v, S_, e_, lap=lap):
                return 2 * e_ * (lap @ v) + S_["node_w"] * np.cos(x - S_["theta"]) / e_ * v

            res = minimize(_energy, u, args=(S, e), jac=True, hessp=hessp, method="trust-krylov",
                           options={"maxiter": maxiter, "gtol": 1e-9})
            u, its = res.x, its + res.nit
        E, _ = _energy(u, S, eps)
        total += dom.multiplicity * E / BETA
        fields.append((dom, S, u))
    return PhaseFieldResult(total, eps, n, fields, its, time.perf_counter() - t0)


def main(argv=None):
    p = argparse.ArgumentParser(description="phase-field estimate of J (section 5.1.2) against direct")
    p.add_argument("scene")
    p.add_argument("--metric", default="G", choices=["G", "g"])
    p.add_argument("--eps", type=float, default=0.05)
    p.add_argument("--n", type=int, default=128)
    a = p.parse_args(argv)
    ref = direct.penalty(a.scene, a.metric, tol=1e-6)
    pf = solve(a.scene, a.metric, a.eps, a.n)
    print(f"direct: J = {ref.value:.6g} (+- {ref.error_estimate:.1g})")
    print(f"phase field: J_eps / beta = {pf.value:.6g} (eps={a.eps}, n={a.n}, {pf.iterations} Newton iterations, "
          f"{pf.seconds:.2f} s); relative difference {(pf.value - ref.value) / ref.value:+.3e}")


if __name__ == "__main__":
    main()
